//! Seeded reproduction of the simulation study of the paper (spec section 8, acceptance
//! tests S1-S6) and of the Cramer-Rao comparison F4. The full study runs here (50 trajectories
//! of 2 s per configuration, about a second in release); `examples/reproduce.rs` prints the
//! same numbers for the README.
#![allow(clippy::unwrap_used)]

mod common;

use common::*;
use nalgebra::Vector3;
use tilt::simulation::TrueState;
use tilt::study::{fixed_state_study, run_study, StudyConfig};
use tilt::{Estimator, Layout, G0};

fn within(value: f64, lo: f64, hi: f64) -> bool {
    value >= lo && value <= hi
}

#[test]
fn s1_s6_tables_1_and_2_at_the_effective_noise_level() {
    let r = run_study(
        &Estimator::new(simulation_layout()),
        &StudyConfig::paper(7.7e-4, 1),
    )
    .unwrap();
    assert_eq!(r.samples, 5000);
    assert_eq!((r.non_finite, r.not_converged), (0, 0));
    assert!(within(r.tilt_ml.mean, 0.72e-3, 0.95e-3), "{r:?}");
    assert!(within(r.tilt_ml.var, 1.7e-7, 2.8e-7), "{r:?}");
    assert!(within(r.tilt_ls.mean, 1.35e-3, 1.65e-3), "{r:?}");
    assert!(within(r.mean_reduction(), 0.38, 0.50), "{r:?}");
    assert!(within(r.var_reduction(), 0.55, 0.72), "{r:?}");
    assert!(within(r.omega_dot_error, 0.95e-3, 1.25e-3), "{r:?}");
    assert!(within(r.omega_abs_error, 0.5e-3, 1.4e-3), "{r:?}");
    assert!(within(r.iterations.mean, 22.0, 31.0), "{r:?}");
    assert!(within(r.iterations.std(), 7.0, 13.0), "{r:?}");
    // The raw (unnormalised) least squares is worse than the normalised baseline.
    assert!(r.tilt_ls_raw.mean > 1.1 * r.tilt_ls.mean);
    // Along the trajectories the ML error is within 10 % of the Cramer-Rao bound.
    let (mse, crb) = r.tilt_mse_vs_crb;
    assert!(
        within(mse / crb, 0.9, 1.1),
        "tilt MSE / CRB = {}",
        mse / crb
    );
    let (mse, crb) = r.omega_dot_mse_vs_crb;
    assert!(
        within(mse / crb, 0.9, 1.1),
        "omega_dot MSE / CRB = {}",
        mse / crb
    );
}

#[test]
fn s2_s6_printed_noise_level() {
    let low = run_study(
        &Estimator::new(simulation_layout()),
        &StudyConfig::paper(7.7e-4, 1),
    )
    .unwrap();
    let r = run_study(
        &Estimator::new(simulation_layout()),
        &StudyConfig::paper(7.7e-3, 1),
    )
    .unwrap();
    assert_eq!(r.non_finite, 0);
    assert!(within(r.tilt_ml.mean, 7.2e-3, 9.5e-3), "{r:?}");
    assert!(within(r.tilt_ls.mean, 13.5e-3, 16.5e-3), "{r:?}");
    assert!(within(r.mean_reduction(), 0.38, 0.50), "{r:?}");
    assert!(within(r.iterations.mean, 28.0, 42.0), "{r:?}");
    // About ten times the errors of the effective noise level.
    for (a, b) in [
        (r.tilt_ml.mean, low.tilt_ml.mean),
        (r.omega_dot_error, low.omega_dot_error),
        (r.tilt_ls.mean, low.tilt_ls.mean),
    ] {
        assert!(within(a / b, 8.0, 12.0), "{a} / {b}");
    }
}

#[test]
fn s3_table_3_bias() {
    let estimator = Estimator::new(simulation_layout());
    let mut previous = (0.0, 0.0);
    for (w, ml_paper, ls_paper) in [
        (0.1, 0.065, 0.116),
        (0.5, 0.323, 0.582),
        (1.0, 0.643, 1.165),
    ] {
        let config = StudyConfig {
            bias_half_width: w,
            ..StudyConfig::paper(7.7e-4, 2)
        };
        let r = run_study(&estimator, &config).unwrap();
        assert!(
            within(r.tilt_ml.mean / ml_paper, 0.8, 1.2),
            "bias {w}: ML {}",
            r.tilt_ml.mean
        );
        assert!(
            within(r.tilt_ls.mean / ls_paper, 0.8, 1.2),
            "bias {w}: LS {}",
            r.tilt_ls.mean
        );
        assert!(r.tilt_ml.mean < r.tilt_ls.mean);
        assert!(r.tilt_ml.mean > previous.0 && r.tilt_ls.mean > previous.1);
        // Proportional to the bias range (same seed, same draws scaled).
        assert!(
            within(r.tilt_ml.mean / w, 0.55, 0.75),
            "{}",
            r.tilt_ml.mean / w
        );
        previous = (r.tilt_ml.mean, r.tilt_ls.mean);
    }
}

#[test]
fn s4_omega_sweep() {
    let estimator = Estimator::new(simulation_layout());
    let mut errors = Vec::new();
    for wx in [1.0, 0.5, 0.2, 0.1] {
        let state = TrueState {
            omega: Vector3::new(wx, 0.0, 0.0),
            omega_dot: Vector3::zeros(),
            g: down(),
        };
        errors.push(fixed_state_study(&estimator, &state, 7.7e-4, 300, 4).unwrap());
    }
    for pair in errors.windows(2) {
        assert!(
            pair[1].omega_abs_error >= pair[0].omega_abs_error,
            "omega error must grow as omega_x falls"
        );
    }
    // The omega error follows sigma / |omega| (here within 30 %).
    for (r, wx) in errors.iter().zip([1.0, 0.5, 0.2, 0.1]) {
        assert!(
            within(r.omega_abs_error * wx / 7.7e-4, 0.8, 1.3),
            "{}",
            r.omega_abs_error
        );
    }
    let (t0, d0) = (errors[0].tilt_error, errors[0].omega_dot_error);
    for r in &errors {
        assert!(within(r.tilt_error / t0, 0.7, 1.3) && within(r.omega_dot_error / d0, 0.7, 1.3));
    }
}

#[test]
fn s5_three_sensors() {
    let layout = Layout::new(&three_positions()).unwrap();
    let r = run_study(&Estimator::new(layout), &StudyConfig::paper(7.7e-4, 5)).unwrap();
    assert_eq!(r.non_finite, 0);
    assert!(
        r.not_converged * 100 <= r.samples,
        "{} of {} did not converge",
        r.not_converged,
        r.samples
    );
    assert!(r.tilt_ml_median < 2e-3, "median {}", r.tilt_ml_median);
}

#[test]
fn f4_monte_carlo_attains_the_cramer_rao_bound() {
    let estimator = Estimator::new(simulation_layout());
    let state = TrueState {
        omega: Vector3::new(1.0, -0.5, 0.8),
        omega_dot: Vector3::new(2.0, 1.0, -1.0),
        g: Vector3::new(0.0, 0.0, -G0),
    };
    for sigma in [1e-4, 7.7e-4, 7.7e-3] {
        let r = fixed_state_study(&estimator, &state, sigma, 4000, 3).unwrap();
        let (tilt, omega, omega_dot) = r.crb_traces.unwrap();
        assert!((tilt / (sigma * sigma) - 1.2704).abs() < 1e-3);
        for (mse, bound) in [
            (r.tilt_mse, tilt),
            (r.omega_mse, omega),
            (r.omega_dot_mse, omega_dot),
        ] {
            assert!(
                within(mse / bound, 0.9, 1.1),
                "sigma {sigma}: MSE {mse} vs CRB {bound}"
            );
        }
    }
}
