//! Periodic and non-periodic logs in one `--data` directory: the periodic estimate needs every
//! experiment periodic, so all of them go through Welch, and the summary and the JSON say why,
//! naming the experiment that is not periodic.
#![allow(clippy::unwrap_used)]
mod common;

use std::path::{Path, PathBuf};

use common::ok;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sim-mixed-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A first-order plant `x' = -a x + b F`, `y = x`.
const LAG_MODEL: &str = r#"
name = "lag"
states = ["y"]
inputs = ["F"]
outputs = ["y"]

[parameters]
a = { value = 2.0, min = 0.1, max = 100, unit = "1/s" }
b = { value = 1.0, min = 0.01, max = 100, unit = "m/(N s)" }

[linear]
A = [["-a"]]
B = [["b"]]
C = [[1]]
"#;

/// Uniform numbers in [-1, 1) from a linear congruential generator.
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0
    }
}

/// One open-loop experiment of the lag plant (a = 3, b = 1.5) at 100 Hz, 2000 samples, as
/// `name` in `dir`: a 1-20 Hz multisine of period 1 s when `periodic`, else random
/// excitation; small noise from `seed`. No metadata (CSV): periods are detected.
fn experiment(dir: &Path, name: &str, periodic: bool, seed: u64) {
    let (fs, samples) = (100.0, 2000usize);
    let (a, b) = (3.0f64, 1.5f64);
    let h = 1.0 / fs;
    let phi = (-a * h).exp();
    let gamma = (1.0 - phi) * b / a;
    let mut noise = uniform(seed);
    let mut random = uniform(seed ^ 0x5eed);
    let mut csv = String::from("t,F,y,r_F\n");
    let mut x = 0.0;
    for k in 0..samples {
        let t = k as f64 * h;
        let f: f64 = if periodic {
            (1..=20)
                .map(|l| {
                    let phase = std::f64::consts::PI * (l * (l - 1)) as f64 / 20.0;
                    (2.0 * std::f64::consts::PI * l as f64 * (k % 100) as f64 * h + phase).cos()
                })
                .sum::<f64>()
                / 5.0
        } else {
            2.0 * random()
        };
        csv.push_str(&format!("{t},{f},{},{f}\n", x + 1e-4 * noise()));
        x = phi * x + gamma * f;
    }
    std::fs::write(dir.join(name), csv).unwrap();
}

#[test]
fn a_mixed_set_names_the_experiment_that_is_not_periodic() {
    let dir = scratch("names");
    let model = dir.join("lag.toml");
    std::fs::write(&model, LAG_MODEL).unwrap();
    let data = dir.join("runs");
    std::fs::create_dir_all(&data).unwrap();
    for k in 1..=3 {
        experiment(&data, &format!("exp_0{k}.csv"), true, k);
    }
    let run = |json: &Path| {
        ok(&[
            "compare",
            "--model",
            model.to_str().unwrap(),
            "--data",
            data.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ])
    };
    let read = |json: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
    };
    // The periodic experiments alone: the periodic estimate, nothing to explain.
    let json = dir.join("periodic.json");
    let stdout = run(&json);
    assert!(!stdout.contains("Welch"), "{stdout}");
    let doc = read(&json);
    assert!(doc["welch_reason"].is_null(), "{}", doc["welch_reason"]);
    assert!(!doc["estimator"].as_str().unwrap().contains("welch"));

    // One random experiment among them: Welch for all, and the summary says which one and why.
    experiment(&data, "exp_04.csv", false, 4);
    let json = dir.join("mixed.json");
    let stdout = run(&json);
    let line = stdout
        .lines()
        .find(|l| l.starts_with("Welch estimate: "))
        .unwrap_or_else(|| panic!("no reason for the Welch estimate:\n{stdout}"));
    // Experiments are named by their paths.
    let name = |k: usize| data.join(format!("exp_0{k}.csv")).display().to_string();
    assert!(
        line.contains(&format!(
            "experiment {} is not periodic (no period_samples metadata, and its logged \
             excitation does not repeat), while {}, {}, {} are",
            name(4),
            name(1),
            name(2),
            name(3)
        )),
        "{line}"
    );
    assert!(line.contains("so all 4 went through Welch"), "{line}");
    let doc = read(&json);
    assert!(doc["estimator"].as_str().unwrap().contains("welch"));
    let why = doc["welch_reason"].as_str().unwrap();
    assert_eq!(format!("Welch estimate: {why}"), line);
    std::fs::remove_dir_all(&dir).unwrap();
}
