//! The augmented model with the appendix parameters against the printed A_a, B_a (3.67-3.68).
#![allow(clippy::unwrap_used)]

use flying_platform::{Model, StateSpace};
use nalgebra::DMatrix;

#[rustfmt::skip]
const A_PRINTED: [f64; 81] = [
    -0.896, 0.0, 0.0, 0.0, 9.810, 0.0, 0.0, -0.217, 0.0,
    0.0, -0.896, 0.0, -9.810, 0.0, 0.0, 0.217, 0.0, 0.0,
    0.0, 0.0, -1.852, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    0.0, -14.136, 0.0, 0.0, 0.0, 0.0, 0.856, -0.751, 0.0,
    14.136, 0.0, 0.0, 0.0, 0.0, 0.0, 0.751, 0.856, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -5.366,
];

#[rustfmt::skip]
const B_PRINTED: [f64; 81] = [
    0.087, -0.004, 0.0, -0.046, -0.090, 0.0, -0.048, 0.091, 0.0,
    0.004, 0.108, 0.0, 0.081, -0.048, 0.0, -0.077, -0.047, 0.0,
    0.0, 0.0, 0.097, 0.0, 0.0, 0.090, 0.0, 0.0, 0.067,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.037, 0.980, 0.026, 0.730, -0.433, -0.566, -0.702, -0.427, 0.639,
    -0.789, 0.035, 0.734, 0.413, 0.811, -0.413, 0.438, -0.825, -0.341,
    0.0, -0.706, -0.154, 0.0, -0.686, -0.103, 0.0, -0.704, -0.108,
];

fn printed() -> (DMatrix<f64>, DMatrix<f64>) {
    (
        DMatrix::from_row_slice(9, 9, &A_PRINTED),
        DMatrix::from_row_slice(9, 9, &B_PRINTED),
    )
}

/// Half a unit in the last printed digit of every appendix number, as a perturbation.
type Perturbation = Box<dyn Fn(&mut Model)>;

fn rounding_perturbations() -> Vec<(&'static str, Perturbation)> {
    let mut out: Vec<(&'static str, Perturbation)> = Vec::new();
    for (name, half) in [
        ("c_alpha1", 5e-4),
        ("c_alpha2", 5e-4),
        ("l_alpha1", 5e-4),
        ("l_alpha2", 5e-4),
        ("l_alpha3", 5e-5),
        ("l_alpha4", 5e-4 * 0.11), // Table 3 prints l_alpha4/I3 = 0.362
        ("c_omega_t0", 5e-4),
    ] {
        out.push((
            name,
            Box::new(move |m: &mut Model| {
                let v = m.parameter(name).unwrap();
                m.set_parameter(name, v + half).unwrap();
            }),
        ));
    }
    out.push(("l3", Box::new(|m: &mut Model| m.params.l3 += 5e-4)));
    for i in 0..27 {
        out.push((
            "input matrix entry",
            Box::new(move |m: &mut Model| {
                let mut v = m.params.input.to_vector();
                v[i] += 5e-5;
                m.params.input.set_vector(&v).unwrap();
            }),
        ));
    }
    out
}

/// Built matrices vs print, entrywise within 3-decimal rounding of the print plus the first
/// order effect of the rounding of the appendix parameters (each model entry is affine in
/// every single parameter, so the finite difference is exact).
#[test]
fn augmented_model_reproduces_printed_matrices_to_three_decimals_up_to_parameter_rounding() {
    let model = Model::augmented();
    let (a, b) = model.hover_matrices().unwrap();
    let (ap, bp) = printed();
    let mut bound_a = DMatrix::<f64>::from_element(9, 9, 5e-4 + 1e-12);
    let mut bound_b = bound_a.clone();
    for (_, perturb) in rounding_perturbations() {
        let mut m = model.clone();
        perturb(&mut m);
        let (a2, b2) = m.hover_matrices().unwrap();
        bound_a += (a2 - &a).abs();
        bound_b += (b2 - &b).abs();
    }
    for i in 0..9 {
        for j in 0..9 {
            let (da, db) = (
                (a[(i, j)] - ap[(i, j)]).abs(),
                (b[(i, j)] - bp[(i, j)]).abs(),
            );
            assert!(
                da <= bound_a[(i, j)],
                "A[{i},{j}] = {:.4} vs printed {} (allowed {:.4})",
                a[(i, j)],
                ap[(i, j)],
                bound_a[(i, j)]
            );
            assert!(
                db <= bound_b[(i, j)],
                "B[{i},{j}] = {:.4} vs printed {} (allowed {:.4})",
                b[(i, j)],
                bp[(i, j)],
                bound_b[(i, j)]
            );
        }
    }
    // The spec's looser absolute tolerances (AT-02) hold as well.
    assert!((&a - &ap).amax() < 0.025);
    assert!((&b - &bp).amax() < 0.005);
}

/// Exactly the entries the appendix rounding cannot pin down to 3 decimals miss by more
/// than half a unit; everything else agrees to 3 decimals outright.
#[test]
fn entries_off_by_more_than_rounding_are_only_those_sensitive_to_rounded_parameters() {
    let (a, b) = Model::augmented().hover_matrices().unwrap();
    let (ap, bp) = printed();
    let off_a: Vec<(usize, usize)> = (0..81)
        .map(|k| (k / 9, k % 9))
        .filter(|&(i, j)| (a[(i, j)] - ap[(i, j)]).abs() > 5e-4 + 1e-12)
        .collect();
    // A[wx,vy]/A[wy,vx] (l_alpha2), A[wx,wx]/A[wy,wy] (l_alpha3), the gyro pair, A[wz,wz].
    assert_eq!(
        off_a,
        vec![(6, 1), (6, 6), (6, 7), (7, 0), (7, 6), (7, 7), (8, 8)]
    );
    // In B only the tilt rows (l3 rounded to 0.079) miss 3 decimals.
    for k in 0..81 {
        let (i, j) = (k / 9, k % 9);
        if (b[(i, j)] - bp[(i, j)]).abs() > 5e-4 + 1e-12 {
            assert!(i == 6 || i == 7, "B[{i},{j}] off by more than rounding");
        }
    }
    // The print implies C omega_T0 = 0.751 I1 / 3 = 0.01752 (Table 3 says 0.018); with that
    // value the gyro pair matches to 3 decimals.
    let mut m = Model::augmented();
    m.set_parameter("c_omega_t0", 0.01752).unwrap();
    let (a2, _) = m.hover_matrices().unwrap();
    assert!((a2[(6, 7)] - ap[(6, 7)]).abs() <= 5e-4);
    assert!((a2[(7, 6)] - ap[(7, 6)]).abs() <= 5e-4);
}

/// Spec §8.1: eigenvalues of the printed A_a, and the unstable drag mode of the built one.
#[test]
fn modes_of_printed_and_built_a() {
    let (ap, _) = printed();
    let mut ev: Vec<_> = ap.complex_eigenvalues().iter().copied().collect();
    ev.sort_by(|x, y| y.re.partial_cmp(&x.re).unwrap());
    let expected = [
        (5.001, 0.284),
        (0.0, 0.0),
        (-1.852, 0.0),
        (-2.477, 4.853),
        (-2.563, 4.387),
        (-5.366, 0.0),
    ];
    for (re, im) in expected {
        assert!(
            ev.iter()
                .any(|e| (e.re - re).abs() < 0.01 && (e.im.abs() - im).abs() < 0.01),
            "no eigenvalue near {re} +- {im}j in {ev:?}"
        );
    }
    let ss = Model::augmented().state_space().unwrap();
    assert!(ss.poles().unwrap().iter().any(|p| p.re > 4.5));
    let mut no_drag = Model::augmented();
    no_drag.set_parameter("c_alpha1", 0.0).unwrap();
    no_drag.set_parameter("c_alpha2", 0.0).unwrap();
    let poles = no_drag.state_space().unwrap().poles().unwrap();
    assert!(poles.iter().all(|p| p.re.abs() < 1e-6), "{poles:?}");
    // Gyro only: poles at 0 plus +-0.771j.
    assert!(poles.iter().any(|p| (p.im.abs() - 0.7714).abs() < 1e-3));
}

/// Spec §8.4: FRF of the printed matrices with Td = 45 ms.
#[test]
fn frequency_response_of_printed_model_matches_reference_table() {
    let (ap, bp) = printed();
    let mut c = DMatrix::zeros(6, 9);
    for (r, s) in [0, 1, 2, 6, 7, 8].into_iter().enumerate() {
        c[(r, s)] = 1.0;
    }
    let ss = StateSpace {
        a: ap,
        b: bp,
        c,
        d: DMatrix::zeros(6, 9),
        delay: 0.045,
    };
    // (output row, input col, f Hz, dB, deg)
    let table = [
        (0, 0, 0.2, -24.92, -3.8),
        (0, 0, 1.0, -27.70, -77.8),
        (0, 0, 4.0, -48.03, -156.4),
        (1, 0, 0.2, -50.03, 0.8),
        (1, 0, 1.0, -46.94, -114.5),
        (1, 0, 4.0, -75.07, -161.5),
        (3, 0, 0.2, -64.99, 17.8),
        (3, 0, 1.0, -36.09, -117.3),
        (3, 0, 4.0, -55.20, 174.2),
        (4, 0, 0.2, -39.87, -155.0),
        (4, 0, 1.0, -18.73, 111.6),
        (4, 0, 4.0, -30.02, 27.4),
        (2, 2, 0.2, -27.26, -37.4),
        (2, 2, 1.0, -36.59, -89.8),
        (2, 2, 4.0, -48.29, -150.6),
    ];
    for (row, col, f, db, deg) in table {
        let g = ss
            .frequency_response_at(2.0 * std::f64::consts::PI * f)
            .unwrap()[(row, col)];
        let got_db = 20.0 * g.norm().log10();
        let got_deg = g.arg().to_degrees();
        assert!(
            (got_db - db).abs() < 0.05,
            "({row},{col}) at {f} Hz: {got_db} dB vs {db}"
        );
        let dphi = (got_deg - deg + 540.0).rem_euclid(360.0) - 180.0;
        assert!(
            dphi.abs() < 0.5,
            "({row},{col}) at {f} Hz: {got_deg} deg vs {deg}"
        );
    }
}
