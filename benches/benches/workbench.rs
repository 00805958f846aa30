//! End to end workbench time on the paper's identification data (18 experiments x 2700
//! samples, 6 outputs, 9 inputs, closed loop): FRF with covariance, noise reference, the
//! discovery loop (4 candidates, every fit with standard errors). The data are simulated once
//! outside the timed region. The second entry times the non-parametric part alone. The third
//! group is a user's system through its model file (the cart-pole of py/tests/data), the
//! fourth the same system as a nonlinear model file under the time-domain criterion.
#![allow(clippy::unwrap_used)]
use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use sim::systems::flying_platform::{embedded_dataset, FlyingPlatform};
use workbench::{
    Controller, Dataset, EstimatorChoice, Experiment, ModelFile, ModelStructure, Periodic,
    Workbench,
};

fn workbench(c: &mut Criterion) {
    let data = embedded_dataset().unwrap();
    let samples: usize = data.experiments.iter().map(|e| e.u.nrows()).sum();
    assert_eq!(samples, 18 * 2700);
    let mut group = c.benchmark_group("workbench_18x2700");
    group.sample_size(10);
    group.bench_function("discover_end_to_end", |b| {
        b.iter(|| {
            let wb = Workbench::new(
                Arc::new(FlyingPlatform::default()),
                data.clone(),
                EstimatorChoice::Auto,
            )
            .unwrap();
            wb.discover().unwrap()
        })
    });
    group.bench_function("frf_and_noise_reference", |b| {
        b.iter(|| {
            Workbench::new(
                Arc::new(FlyingPlatform::default()),
                data.clone(),
                EstimatorChoice::Auto,
            )
            .unwrap()
        })
    });
    group.finish();
}

/// A cart-pole campaign of the size (4 experiments x 8300 samples at 100 Hz, one
/// input, two outputs), simulated once outside the timed region: the model file's linear model
/// with its declared friction on (b = 0.8), in closed loop with the file's own discrete
/// controller, a periodic multisine excitation (1000-sample period, lines 1-70), force noise and
/// sensor noise.
fn cart_pole_campaign(file: &ModelFile) -> Dataset {
    let with = vec!["cart_friction".to_string()];
    let mut theta: Vec<f64> = file
        .parameters(&with)
        .unwrap()
        .iter()
        .map(|p| p.value)
        .collect();
    *theta.last_mut().unwrap() = 0.8;
    let ss = file.state_space(&with, &theta).unwrap();
    let (phi, gamma) = rigid_body::lti::c2d_zoh(&ss.a, &ss.b, 0.01).unwrap();
    let Some(Controller::Discrete { a, b, c, d, .. }) = file.controller() else {
        panic!("the cart-pole file gives a discrete controller")
    };
    let (period, periods, transient) = (1000, 8, 300);
    let n = transient + period * periods;
    let experiments = (0..4u64)
        .map(|seed| {
            let mut rng = StdRng::seed_from_u64(seed);
            let phases: Vec<f64> = (0..70)
                .map(|_| rng.random::<f64>() * std::f64::consts::TAU)
                .collect();
            let r: Vec<f64> = (0..n)
                .map(|k| {
                    let t = (k % period) as f64 / period as f64;
                    phases
                        .iter()
                        .enumerate()
                        .map(|(l, ph)| (std::f64::consts::TAU * (l + 1) as f64 * t + ph).cos())
                        .sum::<f64>()
                        * 0.05
                })
                .collect();
            let mut x = DVector::zeros(4);
            let mut xc = DVector::zeros(a.nrows());
            let (mut u, mut y, mut rr) = (
                DMatrix::zeros(n, 1),
                DMatrix::zeros(n, 2),
                DMatrix::zeros(n, 1),
            );
            for k in 0..n {
                let noise = DVector::from_fn(2, |i, _| {
                    [2e-4, 5e-4][i] * rng.sample::<f64, _>(StandardNormal)
                });
                let yk = &ss.c * &x + noise;
                let uk = (&c * &xc + &d * &yk)[0] + r[k];
                xc = &a * &xc + &b * &yk;
                let w = 0.05 * rng.sample::<f64, _>(StandardNormal);
                x = &phi * &x + &gamma * (uk + w);
                u[(k, 0)] = uk;
                rr[(k, 0)] = r[k];
                y.row_mut(k).copy_from(&yk.transpose());
            }
            Experiment {
                name: format!("experiment {seed}"),
                u,
                y,
                r: Some(rr),
                periodic: Some(Periodic {
                    period,
                    periods,
                    transient,
                }),
            }
        })
        .collect();
    Dataset {
        sample_rate_hz: 100.0,
        inputs: file.inputs(),
        outputs: file.outputs(),
        experiments,
    }
}

fn own_system(c: &mut Criterion) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../py/tests/data/cart_pole.toml");
    let file = Arc::new(ModelFile::from_path(&path).unwrap());
    let data = cart_pole_campaign(&file);
    let mut group = c.benchmark_group("workbench_model_file_4x8300");
    group.sample_size(10);
    group.bench_function("discover_end_to_end", |b| {
        b.iter(|| {
            let wb = Workbench::new(file.clone(), data.clone(), EstimatorChoice::Auto).unwrap();
            let d = wb.discover().unwrap();
            assert_eq!(d.conclusion.found, ["cart_friction"]);
            d
        })
    });
    group.finish();
}

/// A campaign of the nonlinear cart-pole file (4 experiments x 8300 samples at 100 Hz) with
/// its viscous friction on (b = 1.2): the file's own nonlinear model integrated by RK4 on 10
/// sub-steps per sample, in closed loop with its controller, white excitation of rms 1 N held
/// per sample, force noise 0.05 N and sensor noise 2e-4 m, 5e-4 rad.
fn nonlinear_campaign(file: &ModelFile) -> Dataset {
    let with = vec!["cart_viscous".to_string()];
    let mut theta: Vec<f64> = file
        .parameters(&with)
        .unwrap()
        .iter()
        .map(|p| p.value)
        .collect();
    *theta.last_mut().unwrap() = 1.2;
    let plant = file.dynamics(&with, &theta).unwrap().unwrap();
    let Some(Controller::Discrete { a, b, c, d, .. }) = file.controller() else {
        panic!("the cart-pole file gives a discrete controller")
    };
    let n = 8300;
    let experiments = (0..4u64)
        .map(|seed| {
            let mut rng = StdRng::seed_from_u64(100 + seed);
            let mut x = vec![0.0; 4];
            let mut xc = DVector::zeros(a.nrows());
            let (mut u, mut y, mut rr) = (
                DMatrix::zeros(n, 1),
                DMatrix::zeros(n, 2),
                DMatrix::zeros(n, 1),
            );
            let mut scratch = Vec::new();
            let mut f = |x: &[f64], u: f64, out: &mut [f64]| {
                plant.f(x, &[u], out, &mut scratch).unwrap();
            };
            for k in 0..n {
                let yk = DVector::from_fn(2, |i, _| {
                    x[2 * i] + [2e-4, 5e-4][i] * rng.sample::<f64, _>(StandardNormal)
                });
                let r: f64 = rng.sample::<f64, _>(StandardNormal);
                let uk = (&c * &xc + &d * &yk)[0] + r;
                xc = &a * &xc + &b * &yk;
                let force = uk + 0.05 * rng.sample::<f64, _>(StandardNormal);
                let h = 0.001;
                for _ in 0..10 {
                    let (mut k1, mut k2, mut k3, mut k4) = ([0.0; 4], [0.0; 4], [0.0; 4], [0.0; 4]);
                    f(&x, force, &mut k1);
                    let x2: Vec<f64> = (0..4).map(|i| x[i] + 0.5 * h * k1[i]).collect();
                    f(&x2, force, &mut k2);
                    let x3: Vec<f64> = (0..4).map(|i| x[i] + 0.5 * h * k2[i]).collect();
                    f(&x3, force, &mut k3);
                    let x4: Vec<f64> = (0..4).map(|i| x[i] + h * k3[i]).collect();
                    f(&x4, force, &mut k4);
                    for i in 0..4 {
                        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                    }
                }
                u[(k, 0)] = uk;
                rr[(k, 0)] = r;
                y.row_mut(k).copy_from(&yk.transpose());
            }
            Experiment {
                name: format!("experiment {seed}"),
                u,
                y,
                r: Some(rr),
                periodic: None,
            }
        })
        .collect();
    Dataset {
        sample_rate_hz: 100.0,
        inputs: file.inputs(),
        outputs: file.outputs(),
        experiments,
    }
}

fn nonlinear_system(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../py/tests/data/cart_pole_nonlinear.toml");
    let file = Arc::new(ModelFile::from_path(&path).unwrap());
    let data = nonlinear_campaign(&file);
    let mut group = c.benchmark_group("workbench_nonlinear_4x8300");
    group.sample_size(10);
    group.bench_function("discover_time_criterion", |b| {
        b.iter(|| {
            let wb = Workbench::new(file.clone(), data.clone(), EstimatorChoice::Auto).unwrap();
            let d = wb.discover().unwrap();
            assert_eq!(d.conclusion.found, ["cart_viscous"]);
            d
        })
    });
    group.bench_function("compare_time_criterion", |b| {
        b.iter(|| {
            let wb = Workbench::new(file.clone(), data.clone(), EstimatorChoice::Auto).unwrap();
            wb.compared().unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, workbench, own_system, nonlinear_system);
criterion_main!(benches);
