//! Cubli: evaluation time of the backstepping and guiding controllers against the cheapest
//! peer a user would otherwise pick (a linear state feedback u = −K x, as from LQR on the
//! upright linearization), the same for the edge balancer against an LQR gain from
//! `rigid_body::lti::lqr` on the planar linearization, and the real-time factor of the
//! closed-loop simulation and of one face → edge jump trial.
#![allow(clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use cubli::edge::{EdgeJump, EdgeJumpModel};
use cubli::jump::{face_attitude, pre_brake_state, ImpactModel, JumpModel};
use cubli::simulate::{quiet, simulate, RunConfig};
use cubli::{
    jump_trial, Backstepping, FullState, Gains, GuidingController, JumpConfig, JumpControllers,
    JumpReference, Params, Plant, ReducedState,
};
use nalgebra::{DMatrix, RowVector3, SMatrix, SVector, UnitQuaternion, Vector3};

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

/// Planar states (φ, p, p_w) about edge e1 and the reduced states the edge balancer reads.
fn edge_states(edge: &EdgeJump) -> Vec<(Vector3<f64>, ReducedState)> {
    let up = -edge.params().m().normalize();
    let side = Vector3::x().cross(&up);
    (0..64)
        .map(|i| {
            let a = i as f64 * 0.37;
            let s = Vector3::new(0.2 * a.sin(), 0.02 * a.cos(), 0.05 * a.sin());
            let g = (up * s[0].cos() + side * s[0].sin()) * 9.81;
            let x = ReducedState {
                g,
                p_h: Vector3::new(s[1], 0.0, 0.0),
                p_w: Vector3::new(s[2], 0.0, 0.0),
            };
            (s, x)
        })
        .collect()
}

fn edge(c: &mut Criterion) {
    let p = Params::reference();
    let edge = EdgeJump::new(&p, 0).unwrap();
    let ctrl = edge.balancer(Gains::paper());
    let xs = edge_states(&edge);
    // Peer: LQR (Q = diag(100, 10, 0.01), R = 100) on the upright linearization of the plane.
    let (ie, mgl) = (edge.inertia(), edge.mg());
    let a = DMatrix::from_row_slice(
        3,
        3,
        &[0.0, -1.0 / ie, 1.0 / ie, -mgl, 0.0, 0.0, 0.0, 0.0, 0.0],
    );
    let b = DMatrix::from_row_slice(3, 1, &[0.0, 0.0, 1.0]);
    let q = DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&[100.0, 10.0, 0.01]));
    let r = DMatrix::from_element(1, 1, 100.0);
    let lqr = rigid_body::lti::lqr(&a, &b, &q, &r).unwrap();
    let k = RowVector3::new(lqr.k[(0, 0)], lqr.k[(0, 1)], lqr.k[(0, 2)]);

    let mut group = c.benchmark_group("cubli_edge_controller");
    group.throughput(Throughput::Elements(xs.len() as u64));
    group.bench_function("edge_backstepping", |b| {
        b.iter(|| {
            for (_, x) in &xs {
                black_box(ctrl.control(black_box(x)).unwrap());
            }
        })
    });
    group.bench_function("peer_planar_lqr", |b| {
        b.iter(|| {
            for (s, _) in &xs {
                black_box(-(k * black_box(s)));
            }
        })
    });
    group.finish();

    let plant = Plant::ideal(*edge.params());
    let theta = Vector3::new(
        EdgeJumpModel::new(&edge).unwrap().nominal_wheel_speed() * 1.0136,
        0.0,
        0.0,
    );
    let cfg = JumpConfig {
        brake: ImpactModel::Lock,
        ..JumpConfig::default()
    };
    let mut group = c.benchmark_group("cubli_edge_jump");
    group.bench_function("trial_flight_and_4s_balance", |b| {
        b.iter(|| {
            let controllers = JumpControllers {
                guide: None,
                balance: Some(&ctrl),
            };
            black_box(jump_trial(&plant, face_attitude(), &theta, controllers, &cfg).unwrap());
        })
    });
    group.finish();
}

criterion_group!(benches, controllers, simulation, edge);
criterion_main!(benches);
