//! Full reproduction of the simulation study of the paper (spec section 8) and of the
//! Cramer-Rao comparison (acceptance test F4); prints the numbers recorded in README.
//!
//! `cargo run --release -p tilt --example reproduce`
#![allow(clippy::unwrap_used)]

use nalgebra::Vector3;
use tilt::simulation::TrueState;
use tilt::study::{fixed_state_study, run_study, StudyConfig};
use tilt::{Estimator, Layout, Options, G0};

fn paper_layout() -> Layout {
    Layout::new(&[
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
    ])
    .unwrap()
}

fn main() {
    let layout = paper_layout();
    let options = Options::for_layout(&layout);
    println!(
        "tuning: q = {:.4}, r = {:.5}, eig(A_s) = {:.5?}",
        options.tuning.q, options.tuning.r, options.tuning.eigenvalues
    );
    let estimator = Estimator::new(layout.clone());

    println!("\nTables 1-2 (50 trajectories x 2 s, seed 1)");
    println!("sigma_n   | E|g-g| ML | Var ML   | E|g-g| LS | Var LS   | LS raw   | red mean/var | E|abs w| | E|w_dot| | iter mean (std) | MSE/CRB tilt | MSE/CRB w_dot");
    for sigma in [7.7e-4, 7.7e-3] {
        let r = run_study(&estimator, &StudyConfig::paper(sigma, 1)).unwrap();
        println!(
            "{sigma:.1e}  | {:.3e} | {:.2e} | {:.3e} | {:.2e} | {:.3e} | {:.1}% / {:.1}% | {:.2e} | {:.2e} | {:.1} ({:.1}) | {:.3} | {:.3}   [non-converged {}, non-finite {}]",
            r.tilt_ml.mean, r.tilt_ml.var, r.tilt_ls.mean, r.tilt_ls.var, r.tilt_ls_raw.mean,
            100.0 * r.mean_reduction(), 100.0 * r.var_reduction(), r.omega_abs_error,
            r.omega_dot_error, r.iterations.mean, r.iterations.std(),
            r.tilt_mse_vs_crb.0 / r.tilt_mse_vs_crb.1,
            r.omega_dot_mse_vs_crb.0 / r.omega_dot_mse_vs_crb.1,
            r.not_converged, r.non_finite,
        );
    }

    println!("\nTable 3 (bias, 50 trajectories x 2 s, sigma_n = 7.7e-4, seed 2)");
    for w in [0.1, 0.5, 1.0] {
        let config = StudyConfig {
            bias_half_width: w,
            ..StudyConfig::paper(7.7e-4, 2)
        };
        let r = run_study(&estimator, &config).unwrap();
        println!(
            "bias U[-{w}, {w}]: ML {:.3}  LS {:.3}  LS raw {:.3}  reduction {:.1}%  iterations {:.1}",
            r.tilt_ml.mean, r.tilt_ls.mean, r.tilt_ls_raw.mean, 100.0 * r.mean_reduction(), r.iterations.mean
        );
    }

    println!("\nCramer-Rao bound at omega = (1, -0.5, 0.8), omega_dot = (2, 1, -1), g = (0, 0, -g0), 4000 draws");
    let state = TrueState {
        omega: Vector3::new(1.0, -0.5, 0.8),
        omega_dot: Vector3::new(2.0, 1.0, -1.0),
        g: Vector3::new(0.0, 0.0, -G0),
    };
    for sigma in [1e-4, 7.7e-4, 7.7e-3] {
        let r = fixed_state_study(&estimator, &state, sigma, 4000, 3).unwrap();
        let (ct, cw, cd) = r.crb_traces.unwrap();
        println!(
            "sigma {sigma:.1e}: MSE/CRB tilt {:.3} ({:.3e} vs {:.3e}), omega {:.3} ({:.3e} vs {:.3e}), omega_dot {:.3} ({:.3e} vs {:.3e})",
            r.tilt_mse / ct, r.tilt_mse, ct, r.omega_mse / cw, r.omega_mse, cw, r.omega_dot_mse / cd, r.omega_dot_mse, cd
        );
    }

    println!("\nFig. 2.8 omega sweep (omega = (w_x, 0, 0), omega_dot = 0, 300 draws, seed 4)");
    for sigma in [7.7e-4, 7.7e-3] {
        print!("sigma {sigma:.1e}:");
        for wx in [1.0, 0.5, 0.2, 0.1, 0.05, 0.0] {
            let state = TrueState {
                omega: Vector3::new(wx, 0.0, 0.0),
                omega_dot: Vector3::zeros(),
                g: Vector3::new(0.0, 0.0, -G0),
            };
            let r = fixed_state_study(&estimator, &state, sigma, 300, 4).unwrap();
            print!(
                "  w_x={wx}: w {:.2e} g {:.2e} w_dot {:.2e} it {:.0}",
                r.omega_abs_error, r.tilt_error, r.omega_dot_error, r.mean_iterations
            );
        }
        println!();
    }

    println!("\nThree sensors at 0.05 m on the axes (q = 1/3, r = 400), 50 trajectories, sigma_n = 7.7e-4, seed 5");
    let three = Layout::new(&[
        Vector3::new(0.05, 0.0, 0.0),
        Vector3::new(0.0, 0.05, 0.0),
        Vector3::new(0.0, 0.0, 0.05),
    ])
    .unwrap();
    let options = Options::for_layout(&three);
    println!(
        "tuning: q = {:.4}, r = {:.3}, eig(A_s) = {:.6?}",
        options.tuning.q, options.tuning.r, options.tuning.eigenvalues
    );
    let r = run_study(&Estimator::new(three), &StudyConfig::paper(7.7e-4, 5)).unwrap();
    println!(
        "median tilt error {:.2e}, mean {:.2e}, iterations {:.1}, non-converged {} of {}",
        r.tilt_ml_median, r.tilt_ml.mean, r.iterations.mean, r.not_converged, r.samples
    );

    println!("\nExperimental layout (synthetic data, q = 0.1, r = 11.5), 50 trajectories, sigma_n = 7.7e-3, seed 6");
    let experiment = Layout::new(&[
        Vector3::new(0.122, 0.013, 0.145),
        Vector3::new(0.145, 0.122, 0.013),
        Vector3::new(0.028, 0.013, 0.005),
        Vector3::new(0.005, 0.122, 0.013),
    ])
    .unwrap();
    let options = Options::for_layout(&experiment).with_step_sizes(&experiment, 0.1, 11.5);
    println!("eig(A_s) = {:.3?}", options.tuning.eigenvalues);
    let r = run_study(
        &Estimator::with_options(experiment, options).unwrap(),
        &StudyConfig::paper(7.7e-3, 6),
    )
    .unwrap();
    println!(
        "ML {:.3e}  LS {:.3e}  reduction {:.1}%  iterations {:.1}  non-converged {} of {}",
        r.tilt_ml.mean,
        r.tilt_ls.mean,
        100.0 * r.mean_reduction(),
        r.iterations.mean,
        r.not_converged,
        r.samples
    );
}
