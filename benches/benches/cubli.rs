//! Cubli: evaluation time of the backstepping and guiding controllers against the cheapest
//! peer a user would otherwise pick (a linear state feedback u = −K x, as from LQR on the
//! upright linearization), and the real-time factor of the closed-loop simulation.
#![allow(clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use cubli::jump::{face_attitude, pre_brake_state, JumpModel};
use cubli::simulate::{quiet, simulate, RunConfig};
use cubli::{
    Backstepping, FullState, Gains, GuidingController, JumpReference, Params, Plant, ReducedState,
};
use nalgebra::{SMatrix, SVector, UnitQuaternion, Vector3};

fn states(p: &Params) -> Vec<ReducedState> {
    (0..64)
        .map(|i| {
            let a = i as f64 * 0.37;
            let g = Vector3::new(a.sin() * 0.3, a.cos() * 0.3, -1.0).normalize() * p.gravity();
            ReducedState {
                g,
                p_h: Vector3::new(0.01 * a.cos(), -0.02, 0.01 * a.sin()),
                p_w: Vector3::new(0.05, 0.01 * a.sin(), -0.03),
            }
        })
        .collect()
}

fn controllers(c: &mut Criterion) {
    let p = Params::reference();
    let xs = states(&p);
    let ctrl = Backstepping::new(p, Gains::paper());
    let jm = JumpModel::new(p, &Vector3::new(0.0, 0.0, -9.81)).unwrap();
    let pre = pre_brake_state(&p, face_attitude(), &jm.nominal_wheel_speeds());
    let guide = GuidingController::new(
        p,
        &Gains::paper(),
        JumpReference::at_brake(&p, &pre).unwrap(),
    );
    let fulls: Vec<FullState> = xs
        .iter()
        .enumerate()
        .map(|(i, x)| FullState {
            attitude: UnitQuaternion::from_scaled_axis(Vector3::new(0.01 * i as f64, 0.2, 0.1)),
            p_h: x.p_h,
            p_w: x.p_w,
        })
        .collect();
    let k = SMatrix::<f64, 3, 9>::from_fn(|i, j| ((i * 9 + j) as f64 * 0.1).sin());

    let mut group = c.benchmark_group("cubli_controller");
    group.throughput(Throughput::Elements(xs.len() as u64));
    group.bench_function("backstepping", |b| {
        b.iter(|| {
            for x in &xs {
                black_box(ctrl.control(black_box(x)).unwrap());
            }
        })
    });
    group.bench_function("guiding_feedback_linearization", |b| {
        b.iter(|| {
            for x in &fulls {
                black_box(guide.control(black_box(x)).unwrap());
            }
        })
    });
    // The peer's state vectors are packed beforehand so that only the 3 x 9 product is timed.
    let packed: Vec<SVector<f64, 9>> = xs
        .iter()
        .map(|x| {
            SVector::<f64, 9>::from_column_slice(&[
                x.g[0], x.g[1], x.g[2], x.p_h[0], x.p_h[1], x.p_h[2], x.p_w[0], x.p_w[1], x.p_w[2],
            ])
        })
        .collect();
    group.bench_function("peer_linear_state_feedback", |b| {
        b.iter(|| {
            for v in &packed {
                black_box(-(k * black_box(v)));
            }
        })
    });
    group.finish();
}

fn simulation(c: &mut Criterion) {
    let p = Params::reference();
    let plant = Plant::ideal(p);
    let up = UnitQuaternion::rotation_between(&p.m_hat(), &Vector3::z()).unwrap();
    let x0 = FullState::from_velocities(
        &p,
        UnitQuaternion::from_scaled_axis(up * Vector3::new(0.05, -0.05, 0.0)) * up,
        &Vector3::zeros(),
        &Vector3::zeros(),
    );
    let cfg = RunConfig {
        duration: 10.0,
        ..RunConfig::default()
    };
    let mut group = c.benchmark_group("cubli_simulation");
    // Elements are simulated seconds: elements per second is the real-time factor.
    group.throughput(Throughput::Elements(10));
    group.bench_function("balance_10s_rk4_1ms_control_20ms", |b| {
        b.iter(|| {
            let mut ctrl = Backstepping::new(p, Gains::paper());
            black_box(simulate(&plant, &x0, &mut ctrl, &cfg, &mut quiet).unwrap());
        })
    });
    group.finish();
}

criterion_group!(benches, controllers, simulation);
criterion_main!(benches);
