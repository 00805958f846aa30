//! Parametrized MPC vs standard discrete-time MPC on the quadruple integrator (spec/pmpc.md
//! §8.5–8.7): time of one warm-started step along each controller's own closed-loop
//! trajectory (with the median / p99 / max of a recorded closed loop printed before each
//! criterion run), and single solves for chains of n integrators.
#![allow(clippy::unwrap_used)]

use criterion::{criterion_group, criterion_main, Criterion};
use pmpc::baseline::{Backend, DiscreteMpc};
use pmpc::{scenario, simulate, Pmpc};
use rigid_body::laguerre::Laguerre;
use rigid_body::siqp::Settings;
use std::hint::black_box;
use std::time::Instant;

/// Per-step iteration budget of the real-time configuration for each s (shifted previous plan
/// as fallback), as in `crates/pmpc/tests/budget.rs` and `py/bench/pmpc_peers.py`.
fn budget(s: usize, nu: f64) -> usize {
    let paper = nu == scenario::NU;
    match s {
        ..=8 => 15,
        9..=10 if paper => 6,
        9..=10 => scenario::REAL_TIME_BUDGET,
        _ if paper => 4,
        _ => 6,
    }
}

fn pmpc_controller(s: usize, nu: f64, budget: Option<usize>) -> Pmpc {
    let sc = scenario::quad_integrator();
    let basis = Laguerre::new(s, nu).unwrap();
    let c = sc.pmpc(basis).unwrap().with_settings(Settings {
        max_check_steps: 100,
        ..Settings::default()
    });
    match budget {
        Some(b) => c.with_budget(b),
        None => c,
    }
}

/// Median, mean, p99 and max over the steps (after the first) of the recorded closed loop of
/// each step's time, the fastest of `rounds` replays of the loop (a replay repeats the same
/// solves, so the minimum removes the preemptions of a shared machine, not solver work);
/// criterion itself reports only the mean.
fn step_tail(name: &str, ctrl: &mut Pmpc, states: &[Vec<f64>], rounds: usize) {
    let mut best = vec![f64::INFINITY; states.len()];
    for _ in 0..rounds {
        ctrl.reset();
        for (k, x) in states.iter().enumerate() {
            let t0 = Instant::now();
            black_box(ctrl.step(black_box(x)).unwrap()[0]);
            best[k] = best[k].min(t0.elapsed().as_secs_f64() * 1e6);
        }
    }
    let mut times = best.split_off(1);
    times.sort_by(f64::total_cmp);
    let at = |q: f64| times[((times.len() - 1) as f64 * q).round() as usize];
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    eprintln!(
        "quad_integrator_step/{name} recorded loop ({} steps, best of {rounds}): median {:.1} us, mean {mean:.1} us, p99 {:.1} us, max {:.1} us",
        times.len(),
        at(0.5),
        at(0.99),
        at(1.0)
    );
}

fn discrete_controller(backend: Backend) -> DiscreteMpc {
    let sc = scenario::quad_integrator();
    sc.discrete(100, backend).unwrap()
}

fn quad_integrator_step(c: &mut Criterion) {
    let sc = scenario::quad_integrator();
    let mut group = c.benchmark_group("quad_integrator_step");
    let bases = [
        (8, scenario::NU),
        (10, scenario::NU),
        (12, scenario::NU),
        (10, scenario::REAL_TIME_NU),
        (12, scenario::REAL_TIME_NU),
    ];
    for (s, nu) in bases {
        for budget in [None, Some(budget(s, nu))] {
            let mut ctrl = pmpc_controller(s, nu, budget);
            let states = simulate::run_pmpc(&mut ctrl, &sc.x0, scenario::STEPS, 1)
                .unwrap()
                .x;
            let basis = if nu == scenario::NU {
                format!("pmpc_s{s}")
            } else {
                format!("pmpc_s{s}_nu{nu}")
            };
            let name = match budget {
                None => basis,
                Some(b) => format!("{basis}_budget{b}"),
            };
            step_tail(&name, &mut ctrl, &states, 5);
            let mut k = 0;
            ctrl.reset();
            group.bench_function(name, |b| {
                b.iter(|| {
                    if k == states.len() {
                        k = 0;
                        ctrl.reset();
                    }
                    let u = ctrl.step(black_box(&states[k])).unwrap()[0];
                    k += 1;
                    u
                })
            });
        }
    }
    // discrete_osqp_N100 is absent: osqp-sys cannot be built offline (it clones qdldl).
    {
        let mut ctrl = discrete_controller(Backend::Clarabel);
        let states = simulate::run_discrete(&mut ctrl, &sc.x0, scenario::STEPS)
            .unwrap()
            .x;
        let mut k = 0;
        ctrl.reset();
        group.bench_function("discrete_clarabel_N100", |b| {
            b.iter(|| {
                if k == states.len() {
                    k = 0;
                    ctrl.reset();
                }
                let u = ctrl.step(black_box(&states[k])).unwrap().u[0];
                k += 1;
                u
            })
        });
    }
    group.finish();
}

fn integrator_chain(c: &mut Criterion) {
    let mut group = c.benchmark_group("integrator_chain");
    for n in 2..=7 {
        let sc = scenario::integrator_chain(n);
        let basis = Laguerre::new(12, scenario::NU).unwrap();
        let mut ctrl = sc.pmpc(basis).unwrap();
        // Cold single solve of the open-loop problem (no warm start, no allocation).
        group.bench_function(format!("pmpc_n{n}"), |b| {
            b.iter(|| {
                ctrl.reset();
                ctrl.step(black_box(&sc.x0)).unwrap()[0]
            })
        });
    }
    group.finish();
}

criterion_group!(benches, quad_integrator_step, integrator_chain);
criterion_main!(benches);
