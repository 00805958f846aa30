//! Scalability of the Cor 13 design in the number of vehicles (acceptance test 25): M = 3..6
//! complete with verified certificates, and the full-communication bound c* grows with M.
//! Larger platoons run in the `platoon_scaling` example (times in the README).
#![allow(clippy::unwrap_used)]

use event_est::model::platoon;
use event_est::synth::{complete_with, step1, step2_unit, BudgetBase, Stability};

#[test]
fn cor13_design_scales_to_six_vehicles() {
    // c* of the spec's CVXPY + Clarabel reproduction.
    let reference = [(3, 0.010244), (4, 0.01535), (5, 0.02213), (6, 0.02914)];
    let mut last = 0.0;
    for (m, c_ref) in reference {
        let (sys, _) = platoon(m).unwrap();
        let s1 = step1(&sys, Stability::Cor13).unwrap();
        assert_eq!(s1.stability_lmis, m + 1);
        assert!(s1.stability_margins.iter().all(|(_, v)| *v < 0.0));
        assert!(
            (s1.c_star - c_ref).abs() / c_ref < 5e-3,
            "M = {m}: c* = {}",
            s1.c_star
        );
        assert!(s1.true_h2 <= s1.c_star * (1.0 + 1e-4));
        assert!(s1.c_star > last);
        last = s1.c_star;
        let unit = step2_unit(&sys, &s1.l, 1.0).unwrap();
        assert!(unit.delta.iter().all(|d| d[(0, 0)] > 0.0));
    }
}

#[test]
fn exact_h2_budget_gives_larger_thresholds_with_the_same_guarantee() {
    // For M = 4, Cor 13's bound c* = 0.01535 is loose (true H2 of L: 0.01368).
    let (sys, _) = platoon(4).unwrap();
    let s1 = step1(&sys, Stability::Cor13).unwrap();
    assert!(s1.true_h2 < 0.95 * s1.c_star);
    let j_max = 0.05;
    let thesis = complete_with(&sys, s1.clone(), j_max, BudgetBase::Step1Bound).unwrap();
    let exact = complete_with(&sys, s1, j_max, BudgetBase::ExactH2).unwrap();
    for (a, b) in thesis.design.delta.iter().zip(&exact.design.delta) {
        assert!(b[(0, 0)] > a[(0, 0)]);
    }
    assert!(
        exact.bound.bound <= j_max * (1.0 + 1e-3),
        "{}",
        exact.bound.bound
    );
}
