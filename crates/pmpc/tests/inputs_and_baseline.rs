//! Named errors for bad input, and the discrete-time baseline against the spec's reproduction.
#![allow(clippy::unwrap_used)]

use nalgebra::DMatrix;
use pmpc::baseline::Backend;
use pmpc::{scenario, simulate, Constraints, Error, Pmpc};
use rigid_body::laguerre::Laguerre;

fn basis() -> Laguerre {
    Laguerre::new(12, 0.7).unwrap()
}

#[test]
fn bad_input_gets_named_errors() {
    let sc = scenario::quad_integrator();
    let (a, b, q, r, c) = (&sc.a, &sc.b, &sc.q, &sc.r, &sc.constraints);
    let non_square = DMatrix::zeros(4, 3);
    assert!(matches!(
        Pmpc::new(&non_square, b, q, r, c, basis(), 0.02),
        Err(Error::Shape { name: "A", .. })
    ));
    let wrong_b = DMatrix::zeros(3, 1);
    assert!(matches!(
        Pmpc::new(a, &wrong_b, q, r, c, basis(), 0.02),
        Err(Error::Shape { name: "B", .. })
    ));
    let mut nan_a = a.clone();
    nan_a[(0, 0)] = f64::NAN;
    assert!(matches!(
        Pmpc::new(&nan_a, b, q, r, c, basis(), 0.02),
        Err(Error::NonFinite("A"))
    ));
    assert!(matches!(
        Pmpc::new(a, b, &(-q), r, c, basis(), 0.02),
        Err(Error::NotPositiveDefinite("Q"))
    ));
    assert!(matches!(
        Pmpc::new(a, b, q, r, c, basis(), 0.0),
        Err(Error::InvalidParameter { name: "Td", .. })
    ));
    let bad_limits = Constraints::boxes(
        &[
            (0.1, 1.0),
            (f64::NEG_INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::INFINITY),
        ],
        &[(-0.5, 0.5)],
    );
    assert!(matches!(
        Pmpc::new(a, b, q, r, &bad_limits, basis(), 0.02),
        Err(Error::Limits { row: 0, .. })
    ));
    assert!(matches!(
        Pmpc::new(a, b, q, r, c, Laguerre::new(3, 0.7).unwrap(), 0.02),
        Err(Error::TooFewBasisFunctions { s: 3, n: 4, m: 1 })
    ));
    // −ν is an eigenvalue of A and B = 0: the equalities are rank deficient.
    let one = DMatrix::from_element(1, 1, 1.0);
    let box1 = Constraints::boxes(&[(f64::NEG_INFINITY, f64::INFINITY)], &[(-1.0, 1.0)]);
    assert!(matches!(
        Pmpc::new(
            &DMatrix::from_element(1, 1, -0.7),
            &DMatrix::zeros(1, 1),
            &one,
            &one,
            &box1,
            basis(),
            0.02
        ),
        Err(Error::RankDeficient(_))
    ));
    let mut mpc = Pmpc::new(a, b, q, r, c, basis(), 0.02).unwrap();
    assert!(matches!(
        mpc.step(&[0.1, 0.2]),
        Err(Error::Shape { name: "x", .. })
    ));
    assert!(matches!(
        mpc.step(&[f64::NAN, 0.0, 0.0, 0.0]),
        Err(Error::NonFinite("x"))
    ));
    assert!(matches!(
        mpc.step(&[-0.1, 0.0, 0.0, 0.0]),
        Err(Error::Infeasible { .. })
    ));
    // Messages name the offending input.
    let msg = Pmpc::new(&non_square, b, q, r, c, basis(), 0.02)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("A is 4x3"), "{msg}");
}

/// §8.5 reproduction: discrete-time MPC with horizon N = 93 on Clarabel reaches J_cl ≈ 12.51.
#[test]
fn discrete_baseline_closed_loop_cost() {
    let sc = scenario::quad_integrator();
    let mut mpc = sc.discrete(93, Backend::Clarabel).unwrap();
    assert_eq!(mpc.size(), (93, 3 * 93));
    let cl = simulate::run_discrete(&mut mpc, &sc.x0, scenario::STEPS).unwrap();
    println!("N = 93: J_cl = {}, failures {}", cl.cost, cl.fallbacks);
    assert!((cl.cost - 12.51).abs() < 0.02 * 12.51, "J_cl = {}", cl.cost);
    assert!(cl.max_violation <= 1e-5);
}

/// Sizes beyond what the dense set-up can hold or finish promptly are refused by name before
/// anything is allocated (s = 100000 used to abort, --horizon 1000000 too, s = 5000 to run
/// for minutes), and the plan is not evaluated before its start.
#[test]
fn huge_sizes_and_negative_times_are_refused() {
    let sc = scenario::quad_integrator();
    for s in [5000, 100_000] {
        let t0 = std::time::Instant::now();
        let err = sc.pmpc(Laguerre::new(s, 0.7).unwrap()).unwrap_err();
        assert!(
            matches!(err, Error::TooLarge { size, limit: 1000, .. } if size == 5 * s),
            "{err}"
        );
        assert!(err.to_string().contains("decision variables"), "{err}");
        assert!(t0.elapsed().as_secs_f64() < 1.0);
    }
    let err = sc.discrete(1_000_000, Backend::Clarabel).unwrap_err();
    assert!(
        matches!(
            err,
            Error::TooLarge {
                size: 4_000_000,
                ..
            }
        ),
        "{err}"
    );
    let mut c = sc.pmpc(basis()).unwrap();
    c.step(&sc.x0).unwrap();
    let mut u = [0.0];
    let mut x = [0.0; 4];
    for t in [-1.0, f64::NAN, f64::NEG_INFINITY] {
        assert!(matches!(
            c.input_at(t, &mut u),
            Err(Error::InvalidParameter { name: "t", .. })
        ));
        assert!(c.state_at(t, &mut x).is_err());
    }
    assert!(matches!(
        c.input_at(0.0, &mut x),
        Err(Error::Shape { name: "out", .. })
    ));
    c.input_at(0.01, &mut u).unwrap();
    assert!(u[0].abs() <= 0.5 + 1e-6);
}
