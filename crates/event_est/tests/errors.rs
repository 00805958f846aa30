//! Bad input gives named errors, never a panic or a silent wrong answer.
#![allow(clippy::unwrap_used)]

use event_est::model::{platoon, System};
use event_est::sim::{simulate, Design, SimConfig};
use event_est::synth::{step1, step2_unit, Stability};
use event_est::EventEstError;
use nalgebra::DMatrix;

fn eye(n: usize) -> DMatrix<f64> {
    DMatrix::identity(n, n)
}

/// Two states, one input of agent 1 (F = 0, so A + BF = A), C = I, V^½ = I; the varied parts
/// are A, the rows of B, the output blocks and W.
fn two_state(
    a: DMatrix<f64>,
    b_rows: usize,
    outputs: Vec<usize>,
    w: DMatrix<f64>,
) -> Result<System, EventEstError> {
    System::new(
        a,
        DMatrix::zeros(b_rows, 1),
        eye(2),
        DMatrix::zeros(1, 2),
        outputs,
        vec![1, 0],
        w,
        eye(2),
    )
}

#[test]
fn wrong_dimensions_are_named() {
    let err = two_state(eye(2), 3, vec![1, 1], eye(2)).unwrap_err();
    assert!(
        matches!(err, EventEstError::Dimension { name: "B", .. }),
        "{err}"
    );
    let err = two_state(eye(2) * 0.5, 2, vec![1, 2], eye(2)).unwrap_err();
    assert!(matches!(err, EventEstError::BlockSizes { .. }), "{err}");
}

#[test]
fn unstable_feedback_and_bad_covariance_are_named() {
    let err = two_state(eye(2) * 1.5, 2, vec![1, 1], eye(2)).unwrap_err();
    assert!(
        matches!(err, EventEstError::UnstableFeedback { rho } if (rho - 1.5).abs() < 1e-12),
        "{err}"
    );
    let err = two_state(eye(2) * 0.5, 2, vec![1, 1], -eye(2)).unwrap_err();
    assert_eq!(err, EventEstError::NotPositiveDefinite { name: "W" });
}

#[test]
fn undetectable_plant_fails_in_the_kalman_design() {
    // The unstable second state is invisible to C.
    let a = DMatrix::from_row_slice(2, 2, &[0.5, 0.0, 0.0, 1.2]);
    let b = eye(2);
    let f = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, 0.0, -1.0]);
    let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
    let sys = System::new(a, b, c, f, vec![1, 0], vec![1, 1], eye(1), eye(2)).unwrap();
    let err = step1(&sys, Stability::Cor12).unwrap_err();
    assert!(matches!(err, EventEstError::Lti { .. }), "{err}");
    assert!(err.to_string().contains("detectable"), "{err}");
}

#[test]
fn bad_designs_are_rejected_by_the_simulator_and_step2() {
    let (sys, noise) = platoon(3).unwrap();
    let cfg = SimConfig::new(&sys, 10, Some(noise), 1);
    let l = DMatrix::zeros(5, 3);
    let err = simulate(&sys, &Design::scalar(l.clone(), &[0.1, -0.1, 0.1]), &cfg).unwrap_err();
    assert_eq!(err, EventEstError::NotPositiveDefinite { name: "Δ_i" });
    let err = simulate(&sys, &Design::scalar(DMatrix::zeros(4, 3), &[0.1; 3]), &cfg).unwrap_err();
    assert!(
        matches!(err, EventEstError::Dimension { name: "L", .. }),
        "{err}"
    );
    // L = 0 leaves the integrators of the platoon unobserved: (I − LC)A is not Schur.
    let err = step2_unit(&sys, &l, 1.0).unwrap_err();
    assert!(matches!(err, EventEstError::Verification { .. }), "{err}");
    assert!(platoon(1).is_err());
}
