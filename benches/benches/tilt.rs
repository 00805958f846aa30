//! Time per sample of the maximum-likelihood tilt estimator against its peer, the linear
//! least-squares method (Trimpe and D'Andrea), on the paper's 4-sensor simulation layout with
//! noisy samples of the paper's random motion (sigma_n = 7.7e-4 m/s^2).
#![allow(clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::SeedableRng;
use tilt::simulation::{measure, simulate_trajectory, TrajectoryConfig};
use tilt::{least_squares, Estimator, Layout};

fn samples() -> (Layout, Vec<[Vector3<f64>; 4]>) {
    let positions = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
    ];
    let mut rng = StdRng::seed_from_u64(1);
    let states = simulate_trajectory(&mut rng, &TrajectoryConfig::default());
    let samples = states
        .iter()
        .map(|s| {
            let mut m = [Vector3::zeros(); 4];
            measure(&mut rng, &positions, s, 7.7e-4, &[], &mut m);
            m
        })
        .collect();
    (Layout::new(&positions).unwrap(), samples)
}

fn tilt_estimate(c: &mut Criterion) {
    let (layout, samples) = samples();
    let estimator = Estimator::new(layout.clone());
    let mut group = c.benchmark_group("tilt_estimate");
    let mut k = 0;
    group.bench_function("ml_4sensors", |b| {
        b.iter(|| {
            k = (k + 1) % samples.len();
            black_box(estimator.estimate(black_box(&samples[k])).unwrap())
        })
    });
    group.bench_function("least_squares_4sensors", |b| {
        b.iter(|| {
            k = (k + 1) % samples.len();
            black_box(least_squares(&layout, black_box(&samples[k])).unwrap())
        })
    });
    group.finish();
}

criterion_group!(benches, tilt_estimate);
criterion_main!(benches);
