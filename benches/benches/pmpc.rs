//! Parametrized MPC vs standard discrete-time MPC on the quadruple integrator (spec/pmpc.md
//! §8.5–8.7): time of one warm-started step along each controller's own closed-loop
//! trajectory, and single solves for chains of n integrators.
#![allow(clippy::unwrap_used)]

use criterion::{criterion_group, criterion_main, Criterion};
use pmpc::baseline::{Backend, DiscreteMpc};
use pmpc::{scenario, simulate, Pmpc};
use rigid_body::laguerre::Laguerre;
use std::hint::black_box;

fn pmpc_controller(s: usize) -> Pmpc {
    let sc = scenario::quad_integrator();
    let basis = Laguerre::new(s, scenario::NU).unwrap();
    sc.pmpc(basis).unwrap()
}

fn discrete_controller(backend: Backend) -> DiscreteMpc {
    let sc = scenario::quad_integrator();
    sc.discrete(100, backend).unwrap()
}

fn quad_integrator_step(c: &mut Criterion) {
    let sc = scenario::quad_integrator();
    let mut group = c.benchmark_group("quad_integrator_step");
    for s in [8, 12] {
        let mut ctrl = pmpc_controller(s);
        let states = simulate::run_pmpc(&mut ctrl, &sc.x0, scenario::STEPS, 1)
            .unwrap()
            .x;
        let mut k = 0;
        ctrl.reset();
        group.bench_function(format!("pmpc_s{s}"), |b| {
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
