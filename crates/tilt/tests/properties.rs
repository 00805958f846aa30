//! Property tests of the mathematical invariants (proptest, 256 cases each).
#![allow(clippy::unwrap_used)]

mod common;

use common::*;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::SeedableRng;
use rigid_body::matrix_set;
use tilt::simulation::{gaussian_vector, measure, TrueState};
use tilt::{
    a_s_eigenvalues, d_criterion, d_criterion_bound, default_tuning, fisher_information,
    ideal_measurements, least_squares, omega_matrix, Estimator, Layout, TuningRule, G0,
};

/// A random layout of 4 to 8 sensors with N(0, scale^2) coordinates (non-coplanar almost surely).
fn layout_from_seed(seed: u64, scale: f64) -> (Vec<Vector3<f64>>, Layout) {
    let mut rng = StdRng::seed_from_u64(seed);
    let l = 4 + (seed % 5) as usize;
    let positions: Vec<_> = (0..l).map(|_| gaussian_vector(&mut rng) * scale).collect();
    let layout = Layout::new(&positions).unwrap();
    (positions, layout)
}

fn state_from_seed(seed: u64) -> TrueState {
    let mut rng = StdRng::seed_from_u64(seed ^ 0x5eed);
    TrueState {
        omega: gaussian_vector(&mut rng) * 2.0,
        omega_dot: gaussian_vector(&mut rng) * 5.0,
        g: random_gravity(&mut rng),
    }
}

proptest! {
    // Fixed seed: the same 256 cases on every run.
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20_170_101),
        ..ProptestConfig::default()
    })]

    #[test]
    fn least_squares_recovers_noise_free_states(seed in any::<u64>(), scale in 0.05f64..5.0) {
        let (positions, layout) = layout_from_seed(seed, scale);
        let s = state_from_seed(seed);
        let mut m = vec![Vector3::zeros(); positions.len()];
        ideal_measurements(&positions, &s.omega, &s.omega_dot, &s.g, &mut m);
        let ls = least_squares(&layout, &m).unwrap();
        let omega_t = omega_matrix(&s.omega, &s.omega_dot);
        prop_assert!((ls.omega_matrix - omega_t).norm() <= 1e-7 * (omega_t.norm() + G0 / (scale * scale)));
        prop_assert!((ls.g_raw - s.g).norm() <= 1e-7 * G0);
    }

    #[test]
    fn estimate_is_feasible_and_not_worse_than_its_start(seed in any::<u64>(), sigma in 1e-4f64..0.1) {
        let (positions, layout) = layout_from_seed(seed, 1.0);
        let estimator = Estimator::new(layout.clone());
        let mut rng = StdRng::seed_from_u64(seed);
        let mut m = vec![Vector3::zeros(); positions.len()];
        measure(&mut rng, &positions, &state_from_seed(seed), sigma, &[], &mut m);
        let e = estimator.estimate(&m).unwrap();
        prop_assert!(in_m(&e.omega_matrix, 1e-9));
        prop_assert!((e.g.norm() - G0).abs() <= 1e-12 * G0);
        let ls = least_squares(&layout, &m).unwrap();
        let start = matrix_set::project(&ls.omega_matrix).unwrap().matrix;
        prop_assert!(e.cost <= layout.cost(&m, &start, &ls.g.unwrap()).unwrap() * (1.0 + 1e-12));
        // Reported pieces agree with Omega.
        let rebuilt = omega_matrix(&e.omega, &e.omega_dot);
        prop_assert!((rebuilt - e.omega_matrix).norm() <= 1e-9 * e.omega_matrix.norm().max(1.0));
        prop_assert!((e.omega.norm() - e.omega_norm).abs() <= 1e-12 * e.omega_norm.max(1.0));
    }

    #[test]
    fn estimator_is_rotation_equivariant(seed in any::<u64>()) {
        let (positions, layout) = layout_from_seed(seed, 1.0);
        let mut rng = StdRng::seed_from_u64(seed);
        let t = random_rotation(&mut rng);
        let mut m = vec![Vector3::zeros(); positions.len()];
        measure(&mut rng, &positions, &state_from_seed(seed), 7.7e-3, &[], &mut m);
        let rotated_positions: Vec<_> = positions.iter().map(|p| t * p).collect();
        let rotated_m: Vec<_> = m.iter().map(|v| t * v).collect();
        let a = Estimator::new(layout).estimate(&m).unwrap();
        let b = Estimator::new(Layout::new(&rotated_positions).unwrap()).estimate(&rotated_m).unwrap();
        prop_assume!(a.flags.converged && b.flags.converged);
        prop_assert!((b.g - t * a.g).norm() <= 1e-6 * G0);
        let rotated: Matrix3<f64> = t * a.omega_matrix * t.transpose();
        prop_assert!((b.omega_matrix - rotated).norm() <= 1e-6 * rotated.norm().max(1.0));
    }

    #[test]
    fn cramer_rao_bound_is_rotation_invariant_and_positive(seed in any::<u64>()) {
        let (positions, layout) = layout_from_seed(seed, 1.0);
        let s = state_from_seed(seed);
        let mut rng = StdRng::seed_from_u64(seed);
        let t = random_rotation(&mut rng);
        let rotated = Layout::new(&positions.iter().map(|p| t * p).collect::<Vec<_>>()).unwrap();
        let a = fisher_information(&layout, &s.omega, &s.omega_dot, &s.g, 0.01).unwrap();
        let b = fisher_information(&rotated, &(t * s.omega), &(t * s.omega_dot), &(t * s.g), 0.01).unwrap();
        prop_assert_eq!(a.rank(), 8);
        let (ca, cb) = (a.crb().unwrap(), b.crb().unwrap());
        for (x, y) in [(ca.tilt, cb.tilt), (ca.omega, cb.omega), (ca.omega_dot, cb.omega_dot)] {
            prop_assert!((x.trace() - y.trace()).abs() <= 1e-8 * x.trace());
            prop_assert!(x.symmetric_eigenvalues().min() >= -1e-12 * x.trace());
        }
        prop_assert!((a.matrix() - a.matrix().transpose()).norm() <= 1e-12 * a.matrix().norm());
    }

    #[test]
    fn d_criterion_never_exceeds_the_bound(seed in any::<u64>()) {
        let mut rng = StdRng::seed_from_u64(seed);
        let l = 4 + (seed % 5) as usize;
        let positions: Vec<_> = (0..l).map(|_| {
            let v = gaussian_vector(&mut rng);
            v / v.norm().max(1.0)
        }).collect();
        let layout = Layout::new(&positions).unwrap();
        let d = d_criterion(&layout, &random_gravity(&mut rng));
        prop_assert!(d >= 0.0 && d <= d_criterion_bound(l, G0) * (1.0 + 1e-12));
    }

    #[test]
    fn closed_form_step_size_minimises_lambda_2(seed in any::<u64>(), factor in 0.5f64..2.0) {
        let (_, layout) = layout_from_seed(seed, 1.0);
        let tuning = default_tuning(&layout);
        prop_assume!(tuning.rule == TuningRule::ClosedForm);
        let l = layout.len() as f64;
        let lambda2 = |r: f64| {
            let expected = (Matrix3::identity() - layout.p_outer() * r).norm() + r * layout.p_sum().norm_squared() / l;
            let [lo, hi] = a_s_eigenvalues(&layout, 1.0 / l, r);
            assert!(lo.abs() < 1e-9 * hi.max(1.0) && (hi - expected).abs() < 1e-9 * expected);
            hi
        };
        prop_assert!(lambda2(tuning.r) <= lambda2(tuning.r * factor) * (1.0 + 1e-12));
    }
}
