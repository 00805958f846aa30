//! Acceptance tests A1-A9 of spec/tilt.md section 11 and the degenerate inputs.
#![allow(clippy::unwrap_used)]

mod common;

use common::*;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rigid_body::{matrix_set, s2};
use tilt::simulation::{gaussian_vector, measure, TrueState};
use tilt::{
    a_s_eigenvalues, default_tuning, ideal_measurements, least_squares, omega_matrix, Estimator,
    Layout, Options, TiltError, TuningRule, G0,
};

fn relative_error(
    omega: &Matrix3<f64>,
    g: &Vector3<f64>,
    omega_t: &Matrix3<f64>,
    g_t: &Vector3<f64>,
) -> f64 {
    let num = (omega - omega_t).norm_squared() + (g - g_t).norm_squared();
    let den = omega_t.norm_squared() + g_t.norm_squared();
    (num / den).sqrt()
}

/// Reference for the minimum-norm least-squares solution: SVD pseudo-inverse of the stacked
/// 3L x 12 system in the unknowns `(vec(Omega) row-major, g)`.
fn stacked_min_norm(
    positions: &[Vector3<f64>],
    m: &[Vector3<f64>],
) -> (Matrix3<f64>, Vector3<f64>) {
    let l = positions.len();
    let mut a = DMatrix::zeros(3 * l, 12);
    let mut b = DVector::zeros(3 * l);
    for (i, (p, mi)) in positions.iter().zip(m).enumerate() {
        for row in 0..3 {
            for col in 0..3 {
                a[(3 * i + row, 3 * row + col)] = p[col];
            }
            a[(3 * i + row, 9 + row)] = -1.0;
            b[3 * i + row] = mi[row];
        }
    }
    let x = a.svd(true, true).solve(&b, 1e-12).unwrap();
    let omega = Matrix3::from_fn(|r, c| x[3 * r + c]);
    (omega, Vector3::new(x[9], x[10], x[11]))
}

#[test]
fn a1_least_squares_exact_on_noise_free_data() {
    let mut rng = StdRng::seed_from_u64(11);
    for _ in 0..200 {
        let l = rng.random_range(4..9);
        let positions: Vec<_> = (0..l).map(|_| gaussian_vector(&mut rng)).collect();
        let layout = Layout::new(&positions).unwrap();
        let (w, h, g) = (
            gaussian_vector(&mut rng),
            gaussian_vector(&mut rng),
            random_gravity(&mut rng),
        );
        let mut m = vec![Vector3::zeros(); l];
        ideal_measurements(&positions, &w, &h, &g, &mut m);
        let ls = least_squares(&layout, &m).unwrap();
        assert!(!ls.rank_deficient);
        assert!(relative_error(&ls.omega_matrix, &ls.g_raw, &omega_matrix(&w, &h), &g) < 1e-9);
    }
}

#[test]
fn a1_least_squares_rank_deficient_is_min_norm() {
    let mut rng = StdRng::seed_from_u64(12);
    // Three sensors, and five sensors on the affine plane z = 0.3.
    let five: Vec<_> = (0..5)
        .map(|_| {
            Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                0.3,
            )
        })
        .collect();
    for positions in [three_positions().to_vec(), five] {
        let layout = Layout::new(&positions).unwrap();
        assert!(layout.affine_plane().is_some());
        for _ in 0..20 {
            let m: Vec<_> = positions
                .iter()
                .map(|_| gaussian_vector(&mut rng) * 5.0)
                .collect();
            let ls = least_squares(&layout, &m).unwrap();
            assert!(ls.rank_deficient);
            let (omega, g) = stacked_min_norm(&positions, &m);
            assert!(relative_error(&ls.omega_matrix, &ls.g_raw, &omega, &g) < 1e-9);
        }
    }
}

#[test]
fn affine_plane_of_three_sensors() {
    let layout = Layout::new(&three_positions()).unwrap();
    let plane = layout.affine_plane().unwrap();
    let expected = Vector3::new(1.0, 1.0, 1.0).normalize();
    assert!((plane.normal - expected).norm() < 1e-12);
    assert!((plane.offset - 0.05 / 3f64.sqrt()).abs() < 1e-12);
    assert!(simulation_layout().affine_plane().is_none());
}

#[test]
fn a2_noise_free_recovery_from_perturbed_start() {
    let mut rng = StdRng::seed_from_u64(21);
    let positions = simulation_positions();
    let layout = simulation_layout();
    let loose = Estimator::new(layout.clone());
    let tight = Estimator::with_options(
        layout.clone(),
        Options {
            tol: 1e-13,
            ..Options::for_layout(&layout)
        },
    )
    .unwrap();
    let mut worst = (0.0f64, 0.0f64, 0usize);
    for _ in 0..300 {
        let (w, h, g) = (
            gaussian_vector(&mut rng),
            gaussian_vector(&mut rng),
            random_gravity(&mut rng),
        );
        let omega_t = omega_matrix(&w, &h);
        let mut m = [Vector3::zeros(); 4];
        ideal_measurements(&positions, &w, &h, &g, &mut m);
        let e = Matrix3::from_fn(|_, _| rng.sample::<f64, _>(rand_distr::StandardNormal));
        let start_omega = matrix_set::project(&(omega_t + e * (1e-2 / e.norm())))
            .unwrap()
            .matrix;
        let start_g = s2::project(&(g + gaussian_vector(&mut rng).normalize() * 1e-2), G0).unwrap();
        let a = loose.estimate_from(&m, &start_omega, &start_g).unwrap();
        let b = tight.estimate_from(&m, &start_omega, &start_g).unwrap();
        assert!(a.flags.converged && b.flags.converged);
        worst.0 = worst
            .0
            .max(relative_error(&a.omega_matrix, &a.g, &omega_t, &g));
        worst.1 = worst
            .1
            .max(relative_error(&b.omega_matrix, &b.g, &omega_t, &g));
        worst.2 = worst.2.max(a.iterations);
    }
    assert!(
        worst.0 <= 5e-7,
        "tol 1e-8: worst relative error {}",
        worst.0
    );
    assert!(
        worst.1 <= 1e-11,
        "tol 1e-13: worst relative error {}",
        worst.1
    );
    assert!(worst.2 <= 200, "worst iteration count {}", worst.2);
}

/// Residuals of the optimality conditions (2.37)-(2.38) at an estimate.
fn fixed_point_residuals(
    layout: &Layout,
    q: f64,
    r: f64,
    m: &[Vector3<f64>],
    omega: &Matrix3<f64>,
    g: &Vector3<f64>,
) -> (f64, f64) {
    let mut grad_omega = Matrix3::zeros();
    let mut grad_g = Vector3::zeros();
    for (mi, p) in m.iter().zip(layout.positions()) {
        let res = mi - omega * p + g;
        grad_omega += res * p.transpose();
        grad_g += res;
    }
    let omega_fp = matrix_set::project(&(omega + grad_omega * r))
        .unwrap()
        .matrix;
    let g_fp = s2::project(&(g - grad_g * q), G0).unwrap();
    (
        (omega_fp - omega).norm() / omega.norm(),
        (g_fp - g).norm() / G0,
    )
}

#[test]
fn a3_fixed_point_property_on_noisy_data() {
    let mut rng = StdRng::seed_from_u64(31);
    let layout = simulation_layout();
    let estimator = Estimator::new(layout.clone());
    let (q, r) = (estimator.options().tuning.q, estimator.options().tuning.r);
    let mut m = [Vector3::zeros(); 4];
    for _ in 0..2000 {
        let state = TrueState {
            omega: gaussian_vector(&mut rng),
            omega_dot: gaussian_vector(&mut rng) * 3.0,
            g: random_gravity(&mut rng),
        };
        measure(&mut rng, layout.positions(), &state, 7.7e-3, &[], &mut m);
        let e = estimator.estimate(&m).unwrap();
        assert!(e.flags.converged);
        let (ro, rg) = fixed_point_residuals(&layout, q, r, &m, &e.omega_matrix, &e.g);
        assert!(ro <= 1e-7 && rg <= 1e-7, "residuals {ro} {rg}");
        assert!(in_m(&e.omega_matrix, 1e-9));
        assert!((e.g.norm() - G0).abs() <= 1e-12 * G0);
    }
}

#[test]
fn a4_final_cost_not_above_projected_least_squares_start() {
    let mut rng = StdRng::seed_from_u64(41);
    let layout = simulation_layout();
    let estimator = Estimator::new(layout.clone());
    let mut m = [Vector3::zeros(); 4];
    for sigma in [7.7e-4, 7.7e-3, 0.05] {
        for _ in 0..2000 {
            let state = TrueState {
                omega: gaussian_vector(&mut rng),
                omega_dot: gaussian_vector(&mut rng) * 3.0,
                g: random_gravity(&mut rng),
            };
            measure(&mut rng, layout.positions(), &state, sigma, &[], &mut m);
            let e = estimator.estimate(&m).unwrap();
            let ls = least_squares(&layout, &m).unwrap();
            let start = matrix_set::project(&ls.omega_matrix).unwrap().matrix;
            let start_cost = layout.cost(&m, &start, &ls.g.unwrap()).unwrap();
            assert!(
                e.cost <= start_cost * (1.0 + 1e-12),
                "sigma {sigma}: {} > {}",
                e.cost,
                start_cost
            );
        }
    }
}

#[test]
fn a5_tuning_values_of_the_paper_layouts() {
    let sim = default_tuning(&simulation_layout());
    assert_eq!(sim.rule, TuningRule::ClosedForm);
    assert!((sim.q - 0.25).abs() < 1e-15);
    assert!((sim.r - 0.97498).abs() < 1e-4, "r* = {}", sim.r);
    assert!(sim.eigenvalues[0].abs() < 1e-12 && (sim.eigenvalues[1] - 0.94790).abs() < 1e-4);
    assert!(sim.certified());

    let three = default_tuning(&Layout::new(&three_positions()).unwrap());
    assert!((three.r - 400.0).abs() < 1e-3, "r* = {}", three.r);
    assert!((three.eigenvalues[1] - 1.0).abs() < 1e-6);

    let experiment = experiment_layout();
    let manual = a_s_eigenvalues(&experiment, 0.1, 11.5);
    assert!(
        (manual[1] - 1.601).abs() < 1e-3 && (manual[0] - 0.466).abs() < 1e-3,
        "{manual:?}"
    );
    let rule = default_tuning(&experiment);
    assert!(
        (rule.r - 2.178).abs() < 1e-3 && (rule.eigenvalues[1] - 1.729).abs() < 1e-3,
        "{rule:?}"
    );
    assert!(!rule.certified());
}

#[test]
fn a5_clustered_layout_falls_back_to_numerical_tuning() {
    // Five sensors around (1, 0, 0): c < 0 in (2.48); with q = 1/L the infimum of lambda_2 is
    // sqrt(3) and the paper's plus branch gives about 31.5.
    let mut rng = StdRng::seed_from_u64(51);
    let positions: Vec<_> = (0..5)
        .map(|_| Vector3::new(1.0, 0.0, 0.0) + gaussian_vector(&mut rng) * 0.05)
        .collect();
    let layout = Layout::new(&positions).unwrap();
    let (l, t, f) = (
        5.0,
        layout.p_outer().trace(),
        layout.p_outer().norm_squared(),
    );
    let a = layout.p_sum().norm_squared() / l;
    assert!((t * t - 3.0 * a * a) / (f - a * a) < 0.0);
    // The search must beat every point of a fine independent grid and the q = 1/L infimum;
    // its minimum is not below one here, so the gradient step is used (no certificate).
    let numerical = tilt::numerical_tuning(&layout);
    assert_eq!(numerical.rule, TuningRule::Numerical);
    let mut best = f64::INFINITY;
    for i in 0..200 {
        for j in 0..200 {
            let q = 0.1 / l * (20f64).powf(i as f64 / 199.0);
            let r = 1e-3 / t * (4000f64).powf(j as f64 / 199.0);
            let [lo, hi] = a_s_eigenvalues(&layout, q, r);
            best = best.min(lo.abs().max(hi.abs()));
        }
    }
    assert!(
        numerical.spectral_radius() <= best * (1.0 + 1e-9),
        "{} > {best}",
        numerical.spectral_radius()
    );
    assert!(numerical.spectral_radius() < 3f64.sqrt() && !numerical.certified());
    let tuning = default_tuning(&layout);
    assert_eq!(tuning.rule, TuningRule::GradientStep);
    assert!(!tuning.certified());
    let lambda_max = layout.p_outer().symmetric_eigenvalues().max();
    assert!((tuning.q - 0.2).abs() < 1e-15 && (tuning.r * lambda_max - 1.0).abs() < 1e-12);
    // The estimator still works with these step sizes on noisy data.
    let estimator = Estimator::new(layout.clone());
    let mut m = [Vector3::zeros(); 5];
    let mut converged = 0;
    for _ in 0..100 {
        let state = TrueState {
            omega: gaussian_vector(&mut rng),
            omega_dot: gaussian_vector(&mut rng),
            g: random_gravity(&mut rng),
        };
        measure(&mut rng, &positions, &state, 7.7e-4, &[], &mut m);
        let e = estimator.estimate(&m).unwrap();
        converged += usize::from(e.flags.converged);
        let ls = least_squares(&layout, &m).unwrap();
        let start = matrix_set::project(&ls.omega_matrix).unwrap().matrix;
        assert!(e.cost <= layout.cost(&m, &start, &ls.g.unwrap()).unwrap() * (1.0 + 1e-12));
    }
    assert!(converged >= 99, "{converged} of 100 converged");
}

#[test]
fn a6_centred_layouts() {
    let mut rng = StdRng::seed_from_u64(61);
    for _ in 0..500 {
        let l = rng.random_range(4..10);
        let raw: Vec<_> = (0..l).map(|_| gaussian_vector(&mut rng)).collect();
        let mean = raw.iter().sum::<Vector3<f64>>() / l as f64;
        let positions: Vec<_> = raw.iter().map(|p| p - mean).collect();
        let layout = Layout::new(&positions).unwrap();
        let (t, f) = (layout.p_outer().trace(), layout.p_outer().norm_squared());
        let [lo, hi] = a_s_eigenvalues(&layout, 1.0 / l as f64, t / f);
        let expected = (3.0 - t * t / f).sqrt();
        assert!(
            lo.abs() < 1e-9 && (hi - expected).abs() < 1e-9,
            "{lo} {hi} {expected}"
        );
        assert_eq!(hi < 1.0, 2f64.sqrt() * f.sqrt() < t);
    }
}

#[test]
fn a7_octahedron_converges_in_one_step_to_the_global_minimum() {
    let mut rng = StdRng::seed_from_u64(71);
    let mut positions = Vec::new();
    for k in 0..3 {
        for s in [1.0, -1.0] {
            let mut v = Vector3::zeros();
            v[k] = s;
            positions.push(v);
        }
    }
    let layout = Layout::new(&positions).unwrap();
    let options = Options::for_layout(&layout).with_step_sizes(&layout, 1.0 / 6.0, 0.5);
    assert!(options.tuning.spectral_radius() < 1e-12);
    let estimator = Estimator::with_options(layout.clone(), options).unwrap();
    let mut m = [Vector3::zeros(); 6];
    for _ in 0..50 {
        let state = TrueState {
            omega: gaussian_vector(&mut rng),
            omega_dot: gaussian_vector(&mut rng),
            g: random_gravity(&mut rng),
        };
        measure(&mut rng, &positions, &state, 0.05, &[], &mut m);
        let (m_sum, m_bar) = m
            .iter()
            .zip(&positions)
            .fold((Vector3::zeros(), Matrix3::zeros()), |(s, b), (mi, p)| {
                (s + mi, b + mi * p.transpose())
            });
        let omega_ref = matrix_set::project(&(m_bar / 2.0)).unwrap().matrix;
        let g_ref = s2::project(&(-m_sum / 6.0), G0).unwrap();
        let e = estimator.estimate(&m).unwrap();
        assert!((e.omega_matrix - omega_ref).norm() < 1e-12 * omega_ref.norm().max(1.0));
        assert!((e.g - g_ref).norm() < 1e-12 * G0);
        assert!(e.iterations <= 2, "iterations {}", e.iterations);
        for _ in 0..20 {
            let start =
                gaussian_vector(&mut rng).cross_matrix() * gaussian_vector(&mut rng).cross_matrix();
            let other = estimator
                .estimate_from(&m, &start, &random_gravity(&mut rng))
                .unwrap();
            assert!(
                other.cost >= e.cost * (1.0 - 1e-12),
                "restart found {} < {}",
                other.cost,
                e.cost
            );
        }
    }
}

#[test]
fn a8_sign_of_omega_is_unobservable() {
    let mut rng = StdRng::seed_from_u64(81);
    let positions = simulation_positions();
    let estimator = Estimator::new(simulation_layout());
    for _ in 0..100 {
        let (w, h, g) = (
            gaussian_vector(&mut rng),
            gaussian_vector(&mut rng),
            random_gravity(&mut rng),
        );
        let noise: Vec<_> = (0..4).map(|_| gaussian_vector(&mut rng) * 7.7e-3).collect();
        let (mut a, mut b) = ([Vector3::zeros(); 4], [Vector3::zeros(); 4]);
        ideal_measurements(&positions, &w, &h, &g, &mut a);
        ideal_measurements(&positions, &-w, &h, &g, &mut b);
        for i in 0..4 {
            assert!((a[i] - b[i]).norm() <= 1e-12 * a[i].norm());
            a[i] += noise[i];
            b[i] += noise[i];
        }
        let (ea, eb) = (
            estimator.estimate(&a).unwrap(),
            estimator.estimate(&b).unwrap(),
        );
        assert!((ea.g - eb.g).norm() < 1e-9);
        assert!((ea.omega_dot - eb.omega_dot).norm() < 1e-9);
        assert!((ea.omega_norm - eb.omega_norm).abs() < 1e-9);
        assert!((ea.omega - eb.omega).norm() < 1e-9 || (ea.omega + eb.omega).norm() < 1e-9);
        // The reported omega is w or -w, up to the noise.
        let aligned = if ea.omega.dot(&w) < 0.0 {
            -ea.omega
        } else {
            ea.omega
        };
        assert!((aligned - w).norm() < 0.1, "{aligned} vs {w}");
    }
}

#[test]
fn a9_converges_at_zero_angular_velocity() {
    let mut rng = StdRng::seed_from_u64(91);
    let layout = simulation_layout();
    let estimator = Estimator::new(layout.clone());
    let mut m = [Vector3::zeros(); 4];
    let mut converged = 0;
    let mut iterations = 0;
    for _ in 0..300 {
        let state = TrueState {
            omega: Vector3::zeros(),
            omega_dot: gaussian_vector(&mut rng),
            g: random_gravity(&mut rng),
        };
        measure(&mut rng, layout.positions(), &state, 7.7e-4, &[], &mut m);
        let e = estimator.estimate(&m).unwrap();
        converged += usize::from(e.flags.converged);
        iterations += e.iterations;
    }
    assert!(converged >= 297, "{converged} of 300 converged");
    assert!(
        iterations / 300 < 100,
        "mean iterations {}",
        iterations / 300
    );
}

#[test]
fn degenerate_layouts_are_rejected_by_name() {
    let two = [Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 1.0, 0.0)];
    assert_eq!(
        Layout::new(&two).unwrap_err(),
        TiltError::TooFewSensors { got: 2 }
    );
    let planar = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(1.0, 1.0, 0.0),
        Vector3::new(-1.0, 2.0, 0.0),
    ];
    assert_eq!(
        Layout::new(&planar).unwrap_err(),
        TiltError::PositionsDoNotSpan { rank: 2 }
    );
    let mut nan = simulation_positions();
    nan[2].y = f64::NAN;
    assert_eq!(
        Layout::new(&nan).unwrap_err(),
        TiltError::NonFinitePosition { sensor: 2 }
    );
    let many = vec![Vector3::new(1.0, 2.0, 3.0); tilt::MAX_SENSORS + 1];
    assert!(matches!(
        Layout::new(&many),
        Err(TiltError::TooManySensors { .. })
    ));
    assert!(Layout::new(&planar)
        .unwrap_err()
        .to_string()
        .contains("coplanar with the pivot"));
}

#[test]
fn bad_measurements_and_options_are_rejected_by_name() {
    let layout = simulation_layout();
    let estimator = Estimator::new(layout.clone());
    let mut m = [Vector3::new(0.0, 0.0, G0); 4];
    assert_eq!(
        estimator.estimate(&m[..3]).unwrap_err(),
        TiltError::MeasurementCount {
            expected: 4,
            got: 3
        }
    );
    m[1].x = f64::INFINITY;
    assert_eq!(
        estimator.estimate(&m).unwrap_err(),
        TiltError::NonFiniteMeasurement { sensor: 1 }
    );
    m[1].x = f64::NAN;
    assert_eq!(
        least_squares(&layout, &m).unwrap_err(),
        TiltError::NonFiniteMeasurement { sensor: 1 }
    );
    let bad = Options {
        tol: 0.0,
        ..Options::for_layout(&layout)
    };
    assert!(matches!(
        Estimator::with_options(layout.clone(), bad),
        Err(TiltError::InvalidOption { name: "tol", .. })
    ));
    let bad = Options::for_layout(&layout).with_step_sizes(&layout, f64::NAN, 1.0);
    assert!(matches!(
        Estimator::with_options(layout.clone(), bad),
        Err(TiltError::InvalidOption { name: "q", .. })
    ));
    let bad = Options {
        max_iterations: 0,
        ..Options::for_layout(&layout)
    };
    assert!(matches!(
        Estimator::with_options(layout, bad),
        Err(TiltError::InvalidOption {
            name: "max_iterations",
            ..
        })
    ));
}

#[test]
fn three_sensors_flag_omega_along_the_plane_normal() {
    let mut rng = StdRng::seed_from_u64(101);
    let positions = three_positions();
    let estimator = Estimator::new(Layout::new(&positions).unwrap());
    let mut m = [Vector3::zeros(); 3];
    let normal = Vector3::new(1.0, 1.0, 1.0).normalize();
    let mut flagged = 0;
    for _ in 0..100 {
        let state = TrueState {
            omega: normal * 2.0,
            omega_dot: gaussian_vector(&mut rng),
            g: random_gravity(&mut rng),
        };
        measure(&mut rng, &positions, &state, 7.7e-4, &[], &mut m);
        let e = estimator.estimate(&m).unwrap();
        assert!(e.flags.min_norm_start);
        let sine = e.plane_alignment.unwrap();
        assert!((sine - e.omega.normalize().cross(&normal).norm()).abs() < 1e-12);
        if e.flags.omega_along_plane_normal {
            flagged += 1;
            assert!(!e.is_reliable());
        }
    }
    assert!(flagged >= 98, "only {flagged} of 100 flagged");
    // A generic omega is not flagged.
    for _ in 0..100 {
        let state = TrueState {
            omega: Vector3::new(2.0, -1.0, 0.5),
            omega_dot: gaussian_vector(&mut rng),
            g: random_gravity(&mut rng),
        };
        measure(&mut rng, &positions, &state, 7.7e-4, &[], &mut m);
        let e = estimator.estimate(&m).unwrap();
        assert!(!e.flags.omega_along_plane_normal && e.is_reliable());
    }
    let four = Estimator::new(simulation_layout());
    let mut m4 = [Vector3::zeros(); 4];
    measure(
        &mut rng,
        &simulation_positions(),
        &TrueState {
            omega: normal,
            omega_dot: Vector3::zeros(),
            g: down(),
        },
        7.7e-4,
        &[],
        &mut m4,
    );
    assert_eq!(four.estimate(&m4).unwrap().plane_alignment, None);
}

#[test]
fn calibrated_biases_are_removed() {
    let mut rng = StdRng::seed_from_u64(111);
    let positions = simulation_positions();
    let biases: Vec<_> = (0..4).map(|_| gaussian_vector(&mut rng) * 0.3).collect();
    let plain = Estimator::new(simulation_layout());
    let calibrated = Estimator::new(simulation_layout().with_biases(&biases).unwrap());
    let state = TrueState {
        omega: Vector3::new(1.0, 0.5, -0.3),
        omega_dot: Vector3::new(0.2, 0.0, 1.0),
        g: random_gravity(&mut rng),
    };
    let mut m = [Vector3::zeros(); 4];
    measure(&mut rng, &positions, &state, 0.0, &biases, &mut m);
    let e = calibrated.estimate(&m).unwrap();
    assert!((e.g - state.g).norm() < 1e-6);
    assert!((plain.estimate(&m).unwrap().g - state.g).norm() > 1e-2);
    assert_eq!(
        simulation_layout().with_biases(&biases[..2]).unwrap_err(),
        TiltError::MeasurementCount {
            expected: 4,
            got: 2
        }
    );
}

#[test]
fn layout_checks_do_not_depend_on_the_length_unit() {
    for scale in [1e-4, 1e-2, 1.0, 1e3] {
        let three: Vec<_> = three_positions().iter().map(|p| p * scale).collect();
        let plane = Layout::new(&three).unwrap().affine_plane().unwrap();
        assert!((plane.offset / scale - 0.05 / 3f64.sqrt()).abs() < 1e-12);
        let sim: Vec<_> = simulation_positions().iter().map(|p| p * scale).collect();
        assert!(Layout::new(&sim).unwrap().affine_plane().is_none());
        let tuning = default_tuning(&Layout::new(&sim).unwrap());
        // r scales with 1/length^2, the eigenvalues of A_s not at all.
        assert!((tuning.r * scale * scale - 0.97498).abs() < 1e-4);
        assert!((tuning.eigenvalues[1] - 0.94790).abs() < 1e-4);
    }
}

#[test]
fn measurements_too_large_for_f64_are_an_error_not_a_certified_estimate() {
    // 1e300 m/s^2 squared overflows: there is no estimate, so none may claim convergence.
    let estimator = Estimator::new(simulation_layout());
    for scale in [1e300, 1e200, 1e160] {
        let m = [Vector3::new(0.0, 0.0, scale); 4];
        match estimator.estimate(&m) {
            Err(TiltError::Overflow { largest }) => assert_eq!(largest, scale),
            Ok(e) => assert!(
                e.cost.is_finite() && e.g.iter().all(|v| v.is_finite()),
                "scale {scale}: cost {} claimed converged {}",
                e.cost,
                e.flags.converged
            ),
            Err(other) => panic!("scale {scale}: {other}"),
        }
    }
    let huge = [Vector3::new(0.0, 0.0, 1e300); 4];
    assert!(matches!(
        estimator.estimate(&huge),
        Err(TiltError::Overflow { .. })
    ));
}
