//! The per-step work bound of the budgeted controller (issue 14, item 2) on the two
//! trajectory sets of the peer benchmark: x0 = 0.3·𝟙 for 1000 steps and 10 starts drawn from
//! [0, 0.2]⁴ for 250 steps each. On every step after the first the solver stays within the
//! bound stated before the run; where the budget runs out the shifted previous plan is
//! applied, and the closed loop still satisfies the constraints on a 0.5 ms grid, keeps the
//! MPC value function decreasing, and reaches a closed-loop cost at most 1 % above the
//! unbudgeted controller's (a fallback may also lower it: the budgeted loop is a different
//! controller, and the shifted plan is sometimes the cheaper one). The real-time basis keeps
//! the closed-loop cost within 1 % of the discrete-time MPC.
#![allow(clippy::unwrap_used)]

use pmpc::baseline::Backend;
use pmpc::{scenario, simulate, Pmpc, Source};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rigid_body::laguerre::Laguerre;
use rigid_body::siqp::Settings;

/// (s, ν, outer iterations per step) of the peer benchmark (README), and Taylor steps per row
/// check. At s = 8 a budget below 13 makes fallbacks that cost 3-6 % in J_cl (which step
/// falls back matters more than how many); at ν = 1.3, s = 12 with 4 iterations is 3 % and s = 10
/// with 2 is 1.3 % above its unbudgeted loop on x0 = 0.3, and neither is offered; s = 10 with 4
/// has been +0.3 %, +0.85 % and +1.1 % there after changes at rounding level (which step falls
/// back moves), so it is not offered either.
const BUDGETS: [(usize, f64, usize); 12] = [
    (8, scenario::NU, 15),
    (10, scenario::NU, 6),
    (10, scenario::NU, 8),
    (10, scenario::NU, 15),
    (12, scenario::NU, 4),
    (12, scenario::NU, 5),
    (12, scenario::NU, 6),
    (12, scenario::NU, 8),
    (12, scenario::NU, 15),
    (10, scenario::REAL_TIME_NU, scenario::REAL_TIME_BUDGET),
    (10, scenario::REAL_TIME_NU, 6),
    (12, scenario::REAL_TIME_NU, 6),
];
const CHECK_STEPS: usize = 100;

fn controller(s: usize, nu: f64, budget: Option<usize>) -> Pmpc {
    let c = scenario::quad_integrator()
        .pmpc(Laguerre::new(s, nu).unwrap())
        .unwrap()
        .with_settings(Settings {
            max_check_steps: CHECK_STEPS,
            ..Settings::default()
        });
    match budget {
        Some(b) => c.with_budget(b),
        None => c,
    }
}

fn starts() -> Vec<(Vec<f64>, usize)> {
    let mut rng = StdRng::seed_from_u64(14);
    let mut v = vec![(vec![0.3; 4], scenario::STEPS)];
    for _ in 0..10 {
        v.push(((0..4).map(|_| rng.random_range(0.0..0.2)).collect(), 250));
    }
    v
}

#[test]
fn budget_bounds_every_step_of_both_trajectory_sets() {
    for (s, nu, budget) in BUDGETS {
        let mut budgeted = controller(s, nu, Some(budget));
        let bound = budgeted.work_bound().unwrap();
        assert_eq!(bound.iterations, budget);
        assert_eq!(bound.taylor_steps, budget * 2 * CHECK_STEPS);
        // Two constrained rows; the working set holds m·s − n = s − 4 instants; 3 Newton moves.
        assert_eq!(bound.adds, budget * 2);
        assert_eq!(bound.drops, (s - 4) * (1 + budget * 2 * 5));
        let mut free = controller(s, nu, None);
        let (mut steps, mut fallbacks, mut worst, mut most_drops) = (0, 0, 0, 0);
        let (mut lowest, mut highest) = (f64::INFINITY, f64::NEG_INFINITY);
        for (x0, n) in starts() {
            let cl = simulate::run_pmpc(&mut budgeted, &x0, n, 40).unwrap();
            let reference = simulate::run_pmpc(&mut free, &x0, n, 40).unwrap();
            for (k, info) in cl.steps.iter().enumerate().skip(1) {
                let st = info.stats;
                assert!(
                    st.iterations <= bound.iterations
                        && st.taylor_steps <= bound.taylor_steps
                        && st.adds <= bound.adds
                        && st.drops <= bound.drops
                        && st.moves <= bound.moves,
                    "s={s} nu={nu} x0={x0:?} step {k}: {st:?} exceeds {bound:?}"
                );
                worst = worst.max(st.iterations);
                most_drops = most_drops.max(st.drops);
                steps += 1;
                fallbacks += matches!(info.source, Source::Fallback(_)) as usize;
            }
            assert!(
                cl.max_violation <= 1e-6,
                "s={s} nu={nu} x0={x0:?}: violation {}",
                cl.max_violation
            );
            for w in cl.steps.windows(2) {
                assert!(w[1].cost <= w[0].cost + 1e-5, "s={s} nu={nu} x0={x0:?}");
            }
            let change = cl.cost / reference.cost - 1.0;
            lowest = lowest.min(change);
            highest = highest.max(change);
            assert!(
                change <= 0.01,
                "s={s} nu={nu} x0={x0:?}: J_cl {} vs unbudgeted {}",
                cl.cost,
                reference.cost
            );
        }
        eprintln!(
            "s={s} nu={nu}: budget {budget}, worst {worst} iterations, {most_drops} drops (bound {}), fallbacks {fallbacks}/{steps} steps, \
             J_cl change vs unbudgeted {:+.2} % ... {:+.2} % over the starts",
            bound.drops,
            100.0 * lowest,
            100.0 * highest
        );
    }
}

/// Mean closed-loop cost (4.102) over the starts of a trajectory set.
fn mean_cost(starts: &[(Vec<f64>, usize)], mut run: impl FnMut(&[f64], usize) -> f64) -> f64 {
    starts.iter().map(|(x0, n)| run(x0, *n)).sum::<f64>() / starts.len() as f64
}

/// The real-time basis (s = 10, ν = REAL_TIME_NU, unbudgeted and with budgets of 3, 4 and 6)
/// keeps the closed-loop cost within 1 % of the discrete-time MPC at N = 93 (solved by
/// Clarabel) on both trajectory sets, where the paper's ν = 0.7 is more than 3 % above on the
/// random starts.
#[test]
fn real_time_basis_is_within_one_percent_of_the_discrete_mpc() {
    let sc = scenario::quad_integrator();
    let all = starts();
    for set in [&all[..1], &all[1..]] {
        let mut mpc = sc.discrete(93, Backend::Clarabel).unwrap();
        let reference = mean_cost(set, |x0, n| {
            simulate::run_discrete(&mut mpc, x0, n).unwrap().cost
        });
        let pmpc_cost = |nu: f64, budget: Option<usize>| {
            let mut c = controller(10, nu, budget);
            mean_cost(set, |x0, n| {
                simulate::run_pmpc(&mut c, x0, n, 40).unwrap().cost
            })
        };
        for budget in [None, Some(scenario::REAL_TIME_BUDGET), Some(4), Some(6)] {
            let cost = pmpc_cost(scenario::REAL_TIME_NU, budget);
            eprintln!(
                "{} starts, budget {budget:?}: J_cl {cost:.4} vs discrete N = 93 {reference:.4} ({:+.2} %)",
                set.len(),
                100.0 * (cost / reference - 1.0)
            );
            assert!(cost <= 1.01 * reference, "J_cl {cost} vs {reference}");
        }
        if set.len() > 1 {
            let paper = pmpc_cost(scenario::NU, None);
            assert!(paper > 1.03 * reference, "ν = 0.7: {paper} vs {reference}");
        }
    }
}
