//! Synthesis time of the event-based estimator's gains for the M-vehicle platoon (Step 1 with
//! the H-free Cor 13) on Clarabel against the thesis's Cor 13 formulation with the auxiliary
//! variable H, and the same H-free Cor 13 SDP on the Schur-complement interior-point method
//! (`event_est::ipm`), in one group. The CVXPY + Clarabel formulation of the same SDP is timed
//! by `py/bench/lmi_peers.py`.
//!
//! `cargo bench -p stabilis-benches --bench event_est -- --warm-up-time 1 --measurement-time 3`
//!
//! With `EVENT_EST_BENCH_20=1` the Schur method also runs the 20-vehicle design (≈ 100 s per
//! sample, 10 samples).
#![allow(clippy::unwrap_used)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use event_est::model::platoon;
use event_est::synth::{step1, step1_using, Solver, Stability};

fn synthesis(c: &mut Criterion) {
    let mut group = c.benchmark_group("event_est_synthesis");
    group.sample_size(10);
    for m in [3usize, 4, 6, 8] {
        let (sys, _) = platoon(m).unwrap();
        group.bench_with_input(BenchmarkId::new("cor13_h_free", m), &sys, |b, sys| {
            b.iter(|| step1(sys, Stability::Cor13).unwrap())
        });
        group.bench_with_input(BenchmarkId::new("cor13_with_h", m), &sys, |b, sys| {
            b.iter(|| step1(sys, Stability::Cor13WithH).unwrap())
        });
    }
    let mut sizes = vec![3usize, 4, 6, 8, 10];
    if std::env::var_os("EVENT_EST_BENCH_20").is_some() {
        sizes.push(20);
    }
    for m in sizes {
        let (sys, _) = platoon(m).unwrap();
        group.bench_with_input(BenchmarkId::new("cor13_schur_ipm", m), &sys, |b, sys| {
            b.iter(|| step1_using(sys, Stability::Cor13, Solver::SchurIpm).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, synthesis);
criterion_main!(benches);
