//! End to end workbench time on the paper's identification data (18 experiments x 2700
//! samples, 6 outputs, 9 inputs, closed loop): FRF with covariance, noise reference, the
//! discovery loop (4 candidates, every fit with standard errors). The data are simulated once
//! outside the timed region. The second entry times the non-parametric part alone.
#![allow(clippy::unwrap_used)]
use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion};
use sim::workbench::flying_platform::{embedded_dataset, FlyingPlatform};
use sim::workbench::{EstimatorChoice, Workbench};

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

criterion_group!(benches, workbench);
criterion_main!(benches);
