//! Cubli model discovery on balancing logs written by the Cubli scenario (100 Hz, a known
//! multisine on the commanded torques, sensor noise, several seeds and initial tilts).
#![allow(clippy::unwrap_used)]
use std::path::PathBuf;

use sim::progress::Progress;
use sim::scenarios::cubli::{Args, Kind};
use sim::scenarios::{run, Common};
use sim::workbench::cubli::{discover, load_cubli, CubliDiscovery, CubliOptions};

/// Writes four 30 s balancing runs with the given hidden effects and returns their paths.
fn logs(tag: &str, hide: impl Fn(&mut Args)) -> Vec<PathBuf> {
    let dir = std::env::temp_dir().join(format!("cubli-wb-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    [(11u64, 5.0), (12, -4.0), (13, 3.0), (14, -5.0)]
        .iter()
        .map(|&(seed, tilt)| {
            let path = dir.join(format!("run{seed}.mcap"));
            let common = Common {
                duration: 30.0,
                out: Some(path.clone()),
                seed,
            };
            let mut args = Args::new(common, Kind::Balance);
            args.tilt_deg = tilt;
            args.excitation_rms = 0.01;
            hide(&mut args);
            run(&args, &mut Progress::hidden()).unwrap();
            path
        })
        .collect()
}

fn discover_on(tag: &str, hide: impl Fn(&mut Args)) -> CubliDiscovery {
    let paths = logs(tag, hide);
    let data = load_cubli(&paths).unwrap();
    for p in &paths {
        std::fs::remove_file(p).unwrap();
    }
    let d = discover(&data, &CubliOptions::default()).unwrap();
    println!("{tag}:\n{}", d.table());
    d
}

fn param(d: &CubliDiscovery, name: &str) -> f64 {
    d.steps
        .last()
        .unwrap()
        .params
        .iter()
        .find(|p| p.name == name)
        .unwrap()
        .value
}

#[test]
fn clean_logs_find_nothing() {
    let d = discover_on("clean", |_| {});
    assert!(d.found.is_empty(), "{:?}", d.found);
    assert!(!d.unexplained, "{}", d.verdict());
}

#[test]
fn hidden_viscous_friction_is_found_within_15_percent() {
    let c = 2e-5;
    let d = discover_on("viscous", |a| a.viscous = vec![c; 3]);
    assert_eq!(d.found, ["wheel_viscous_friction"]);
    let est = param(&d, "wheel_viscous_friction");
    assert!((est - c).abs() < 0.15 * c, "{est}");
}
