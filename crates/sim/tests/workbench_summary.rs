//! What `compare`, `fit`, `discover` and `model check` say: the fitted parameters in the
//! summary, a verdict that claims no candidate test that was not run, `fit` without an effect
//! refused, counts in the singular, eigenvalues on the imaginary axis, the unseen combination
//! and the parameter a fit holds, bounds the wrong way round, and why periodic logs went
//! through Welch.
#![allow(clippy::unwrap_used)]
mod common;

use std::path::Path;

use common::{ok, refused, Scratch};

/// An empty directory of the test's own, removed when dropped.
fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("sim-summary-{name}-"))
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
fn fit_compare_and_discover_print_the_fitted_parameters() {
    let stdout = ok(&["fit", "--with", "momentum_drag"]);
    let line = |name: &str| {
        stdout
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{name} ")))
            .unwrap_or_else(|| panic!("no line for {name}:\n{stdout}"))
            .to_string()
    };
    assert!(
        stdout.contains("parameters (value ± standard error"),
        "{stdout}"
    );
    // An effect's parameter names where its fit started, not a documented value.
    let c = line("c_alpha1");
    assert!(
        c.contains(" ± ") && c.contains("N s/m") && c.contains("its fit started at"),
        "{c}"
    );
    // Held fixed by the structure, with the reason.
    assert!(line("mass").contains("fixed ("), "{}", line("mass"));
    let stdout = ok(&["compare"]);
    assert!(
        stdout.contains("parameters (value ± standard error"),
        "{stdout}"
    );
    // discover prints its steps, then the final model's parameters by the same function:
    // the effects it added bring theirs.
    let stdout = ok(&["discover"]);
    let steps = stdout
        .find("effect added")
        .unwrap_or_else(|| panic!("{stdout}"));
    let table = stdout
        .find("parameters (value ± standard error, unit; documented value, or where an effect's fit started) of the final model:")
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(steps < table, "{stdout}");
    let params = &stdout[table..];
    for name in ["c_alpha1", "l_alpha1"] {
        let row = params
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{name} ")))
            .unwrap_or_else(|| panic!("no row for {name}:\n{stdout}"));
        // An effect's parameter starts from a guess, not a documented value.
        assert!(
            row.contains(" ± ")
                && row.contains("its fit started at")
                && !row.contains("documented"),
            "{row}"
        );
    }
    assert!(
        params
            .lines()
            .any(|l| l.contains(" ± ") && l.contains("(documented ")),
        "no base parameter names its documented value:
{params}"
    );
    assert!(params.contains("fixed ("), "{params}");
}

#[test]
fn compare_does_not_claim_that_candidates_were_tried() {
    let stdout = ok(&["compare"]);
    assert!(stdout.contains("unexplained structured misfit"), "{stdout}");
    assert!(
        !stdout.contains("no candidate effect explains it"),
        "{stdout}"
    );
    assert!(
        stdout.contains("no candidate effect was tried") && stdout.contains("discover tries them"),
        "{stdout}"
    );
    let json: serde_json::Value = serde_json::from_str(&ok(&["compare", "--json"])).unwrap();
    assert_eq!(json["steps"][0]["candidates"], serde_json::json!([]));
    let verdict = json["verdict_text"].as_str().unwrap();
    assert!(
        verdict.contains("no candidate effect was tried"),
        "{verdict}"
    );
    // discover tries them and says so.
    let json: serde_json::Value = serde_json::from_str(&ok(&["discover", "--json"])).unwrap();
    let verdict = json["verdict_text"].as_str().unwrap();
    assert!(!verdict.contains("was tried"), "{verdict}");
    // The candidates only the effect size kept out are a list, each named in the verdict.
    for near in json["near_misses"].as_array().unwrap() {
        let name = near.as_str().unwrap().split(' ').next().unwrap();
        assert!(verdict.contains(name), "{verdict}");
    }
}

#[test]
fn the_report_json_is_named_for_any_verb() {
    let dir = scratch("report-name");
    let report = dir.join("cmp");
    ok(&["compare", "--report", report.to_str().unwrap()]);
    assert!(report.join("report.json").is_file());
    assert!(!report.join("discover.json").exists());
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("report.json")).unwrap())
            .unwrap();
    assert_eq!(doc["steps"].as_array().unwrap().len(), 1);
}

#[test]
fn fit_without_an_effect_is_refused_before_the_work() {
    let dir = scratch("fit-without");
    let report = dir.join("r");
    let stderr = refused(&["fit", "--report", report.to_str().unwrap()]);
    assert!(
        stderr.contains("fit needs --with EFFECT[,EFFECT]; to fit the model as it is, use compare"),
        "{stderr}"
    );
    let stderr = refused(&["fit", "--with", ""]);
    assert!(stderr.contains("fit needs --with"), "{stderr}");
    assert!(!report.exists());
}

#[test]
fn one_experiment_is_counted_in_the_singular() {
    let dir = scratch("one");
    let model = dir.join("lag.toml");
    std::fs::write(&model, LAG_MODEL).unwrap();
    let data = dir.join("runs");
    std::fs::create_dir_all(&data).unwrap();
    experiment(&data, "exp1.csv", true, 1);
    let report = dir.join("report");
    let stdout = ok(&[
        "compare",
        "--model",
        model.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(stdout.contains(", 1 experiment,"), "{stdout}");
    assert!(!stdout.contains("1 experiments"), "{stdout}");
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(html.contains("1 experiment.") && !html.contains("1 experiments"));
}

/// Two masses joined by a spring, free to move together: A has a double zero eigenvalue,
/// which rounding leaves at about +-1e-17.
const TWO_MASS: &str = r#"
name = "twomass"
states = ["x1", "v1", "x2", "v2"]
inputs = ["F"]
outputs = ["x1", "x2"]

[parameters]
m1 = { value = 1.0, min = 0.1, max = 10, unit = "kg" }
m2 = { value = 0.5, min = 0.05, max = 5, unit = "kg" }
k  = { value = 200.0, min = 1.0, max = 2000, unit = "N/m" }
c  = { value = 0.2, min = 0.0, max = 20, unit = "N s/m" }

[linear]
A = [[0, 1, 0, 0],
     ["-k/m1", "-c/m1", "k/m1", "c/m1"],
     [0, 0, 0, 1],
     ["k/m2", "c/m2", "-k/m2", "-c/m2"]]
B = [[0], ["1/m1"], [0], [0]]
C = [[1, 0, 0, 0], [0, 0, 1, 0]]
"#;

#[test]
fn model_check_puts_both_zero_eigenvalues_on_the_imaginary_axis() {
    let dir = scratch("eig");
    let file = dir.join("twomass.toml");
    std::fs::write(&file, TWO_MASS).unwrap();
    let f = file.to_str().unwrap();
    let stdout = ok(&["model", "check", f]);
    assert!(stdout.contains("no unstable eigenvalue"), "{stdout}");
    let axis = stdout
        .lines()
        .find(|l| l.starts_with("on the imaginary axis"))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert_eq!(axis.matches("0.00000 +0.00000i").count(), 2, "{axis}");
    let json: serde_json::Value =
        serde_json::from_str(&ok(&["model", "check", f, "--json"])).unwrap();
    assert_eq!(json["unstable"], serde_json::json!([]));
    assert_eq!(json["marginal"].as_array().unwrap().len(), 2, "{json}");
    assert_eq!(json["eigenvalues"].as_array().unwrap().len(), 4);
    assert_eq!(json["silent_outputs"], serde_json::json!([]));
    // An output row left at zero is named: the workbench refuses it.
    let silent = dir.join("silent.toml");
    std::fs::write(&silent, TWO_MASS.replace("[0, 0, 1, 0]]", "[0, 0, 0, 0]]")).unwrap();
    let stdout = ok(&["model", "check", silent.to_str().unwrap()]);
    assert!(
        stdout.contains("output x2 depends on no state and no input"),
        "{stdout}"
    );
}

/// A pendulum whose response fixes only `1/Jp` and `m g l/Jp` (`Jp = J + m l^2`).
const PENDULUM: &str = r#"
name = "pendulum"
states = ["theta", "omega"]
inputs = ["T"]
outputs = ["theta"]
[parameters]
m = { value = 0.5, min = 0.01, max = 5.0 }
l = { value = 0.4, min = 0.05, max = 2.0 }
J = { value = 0.02, min = 0.0, max = 1.0 }
g = { value = 9.81, fixed = true }
[definitions]
Jp = "J + m*l^2"
[linear]
A = [[0, 1], ["m*g*l/Jp", 0]]
B = [[0], ["1/Jp"]]
C = [[1, 0]]
"#;

/// `model check` names every parameter of the unseen combination with its weight and the one
/// a fit holds by the fit's rule, which the JSON carries as `holds` (it named a part of the
/// combination and not the parameter discover then held).
#[test]
fn model_check_names_the_combination_and_the_parameter_a_fit_holds() {
    let dir = scratch("holds");
    let file = dir.join("pendulum.toml");
    std::fs::write(&file, PENDULUM).unwrap();
    let f = file.to_str().unwrap();
    let stdout = ok(&["model", "check", f]);
    assert!(
        stdout.contains(
            "the outputs cannot separate m, l, J: only combinations of them are identifiable \
             (the unseen one, on unit-norm Jacobian columns: m "
        ),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&ok(&["model", "check", f, "--json"])).unwrap();
    let id = &json["identifiability"];
    assert_eq!(id["unseparated"], serde_json::json!([["m", "l", "J"]]));
    assert_eq!(
        id["combinations"][0]["weights"].as_array().unwrap().len(),
        3
    );
    let holds = id["holds"].as_array().unwrap();
    assert_eq!(holds.len(), 1, "{id}");
    let held = holds[0].as_str().unwrap();
    assert!(
        stdout.contains(&format!(
            "a fit holds {held} at its documented value and reports the others given it"
        )) && stdout.contains("a fit on data weighs by the data's Jacobian"),
        "{stdout}"
    );
}

#[test]
fn bounds_the_wrong_way_round_are_named_as_such() {
    let dir = scratch("minmax");
    let file = dir.join("bad.toml");
    let text = TWO_MASS.replace(
        "m2 = { value = 0.5, min = 0.05, max = 5,",
        "m2 = { value = 0.5, min = 5, max = 0.05,",
    );
    assert_ne!(text, TWO_MASS);
    std::fs::write(&file, text).unwrap();
    let stderr = refused(&["model", "check", file.to_str().unwrap()]);
    assert!(
        stderr.contains("bad.toml: parameters.m2: min 5 > max 0.05"),
        "{stderr}"
    );
    assert!(!stderr.contains("lies outside"), "{stderr}");
}

/// A loop that grows without overflowing (a controller pole at 1.02 per sample: 4e8-fold over
/// the record) is named as diverging in `closed_loop_error`, not scored as a fit of -1e16 %.
#[test]
fn a_slowly_diverging_closed_loop_is_named() {
    let dir = scratch("diverging");
    let model = dir.join("lag.toml");
    let controller = "\n[controller]\nsample_rate_hz = 100\ntype = \"discrete\"\n\
                      A = [[1.02]]\nB = [[1]]\nC = [[0.001]]\nD = [[0]]\n";
    std::fs::write(&model, format!("{LAG_MODEL}{controller}")).unwrap();
    let data = dir.join("runs");
    std::fs::create_dir_all(&data).unwrap();
    experiment(&data, "exp1.csv", true, 1);
    let json: serde_json::Value = serde_json::from_str(&ok(&[
        "compare",
        "--model",
        model.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let time_fit = &json["steps"][0]["time_fit"];
    let why = time_fit["closed_loop_error"].as_str().unwrap_or_default();
    assert!(
        why.contains("diverges in") && why.contains("-fold"),
        "{time_fit}"
    );
    assert!(time_fit["closed_loop"].is_null(), "{time_fit}");
}

/// `--band-hz` narrows a periodic estimate to its excited lines within the band (it used to be
/// ignored unless the logs went through Welch); a band without a line is refused.
#[test]
fn a_band_keeps_the_periodic_lines_within_it() {
    let dir = scratch("band");
    let model = dir.join("lag.toml");
    std::fs::write(&model, LAG_MODEL).unwrap();
    let data = dir.join("runs");
    std::fs::create_dir_all(&data).unwrap();
    experiment(&data, "exp1.csv", true, 1);
    let (m, d) = (model.to_str().unwrap(), data.to_str().unwrap());
    let json: serde_json::Value = serde_json::from_str(&ok(&[
        "compare",
        "--model",
        m,
        "--data",
        d,
        "--band-hz",
        "2.5,7.5",
        "--json",
    ]))
    .unwrap();
    assert_eq!(
        json["frequencies_hz"],
        serde_json::json!([3.0, 4.0, 5.0, 6.0, 7.0])
    );
    let stderr = refused(&["compare", "--model", m, "--data", d, "--band-hz", "30,40"]);
    assert!(
        stderr.contains("holds none of the 20 excited lines"),
        "{stderr}"
    );
}

/// Periodic and non-periodic logs in one `--data` directory: the periodic estimate needs every
/// experiment periodic, so all of them go through Welch, and the summary and the JSON say why,
/// naming the experiment that is not periodic.
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
}
