//! The 20-vehicle platoon of the thesis (Section 7): Cor 13 gains (Step 1) and thresholds
//! (Step 2) on the Schur-complement interior-point method, the certified bound, and closed-loop
//! runs at 10 % packet loss with the leader starting at +5 m/s: steady distance errors and
//! communication rates per vehicle.
//!
//! `cargo run --release -p event_est --example platoon20 -- [vehicles=20] [runs=5] [seconds=1000] [J_max/c* ...=10]`
#![allow(clippy::unwrap_used)]

use event_est::model::{platoon, System, UniformNoise};
use event_est::sim::{simulate_with, Design, SimConfig};
use event_est::synth::{
    analyse, step1_using, step2_unit_using, thresholds, Solver, Stability, Step1, UnitThresholds,
};
use nalgebra::DVector;
use std::time::Instant;

/// Steps per second at Ts = 20 ms.
const RATE: usize = 50;
/// Steady state: t ≥ 500 s (the +5 m/s transient of 20 vehicles has decayed).
const STEADY_FROM_S: usize = 500;

fn main() {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let arg = |i: usize, default: f64| args.get(i).copied().unwrap_or(default);
    let m = arg(0, 20.0) as usize;
    let runs = arg(1, 5.0) as usize;
    let seconds = arg(2, 1000.0) as usize;
    let factors = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec![10.0]
    };
    let (sys, noise) = platoon(m).unwrap();
    println!(
        "{m} vehicles: n = {}, Cor 13 with {} vertex LMIs of size {}",
        sys.n(),
        m + 1,
        2 * sys.n()
    );

    let t0 = Instant::now();
    let s1 = step1_using(&sys, Stability::Cor13, Solver::SchurIpm).unwrap();
    let t1 = t0.elapsed().as_secs_f64();
    println!(
        "Step 1: {} variables, {t1:.1} s ({} iterations, {}), c* = {:.5}, true H2 = {:.5}, \
         centralised Kalman = {:.5}",
        s1.variables, s1.iterations, s1.status, s1.c_star, s1.true_h2, s1.kalman_cost
    );
    let worst = s1
        .stability_margins
        .iter()
        .map(|(_, v)| *v)
        .fold(f64::NEG_INFINITY, f64::max);
    println!(
        "post-verification: {} stability inequalities, largest relative eigenvalue {worst:.2e}",
        s1.stability_margins.len()
    );

    let t0 = Instant::now();
    let unit = step2_unit_using(&sys, &s1.l, 1.0, Solver::SchurIpm).unwrap();
    let t2 = t0.elapsed().as_secs_f64();
    println!("Step 2: {t2:.1} s ({})", unit.status);
    for factor in factors {
        closed_loop(&sys, &noise, &s1, &unit, factor, runs, seconds);
    }
}

/// Thresholds for J_max = `factor`·c*, their certified bound, and `runs` simulations.
fn closed_loop(
    sys: &System,
    noise: &UniformNoise,
    s1: &Step1,
    unit: &UnitThresholds,
    factor: f64,
    runs: usize,
    seconds: usize,
) {
    let m = sys.agents();
    let j_max = factor * s1.c_star;
    let delta = thresholds(sys, unit, s1.c_star, j_max).unwrap();
    let design = Design {
        l: s1.l.clone(),
        delta,
    };
    let bound = analyse(sys, &design).unwrap();
    let d: Vec<f64> = design.delta.iter().map(|d| d[(0, 0)]).collect();
    println!(
        "J_max = {factor} c* = {j_max:.4}: certified bound {:.4}",
        bound.bound
    );
    println!(
        "Δ = {:?}",
        d.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>()
    );

    let steps = seconds * RATE;
    let steady = (STEADY_FROM_S * RATE).min(steps / 2);
    let mut rates = vec![Vec::new(); m];
    let mut worst_distance = 0.0f64;
    let mut power = Vec::new();
    for run in 0..runs {
        let mut cfg = SimConfig::new(sys, steps, Some(noise.clone()), 1000 + run as u64);
        cfg.loss = 0.1;
        cfg.window_start = steady;
        let mut x0 = DVector::zeros(sys.n());
        x0[0] = 5.0; // leader +5 m/s
        cfg.x0 = x0;
        let mut max_d = 0.0f64;
        let r = simulate_with(sys, &design, &cfg, |s| {
            if s.k >= steady {
                // Distance deviations d_i sit at the odd state indices.
                for i in (1..s.x.len()).step_by(2) {
                    max_d = max_d.max(s.x[i].abs());
                }
            }
        })
        .unwrap();
        worst_distance = worst_distance.max(max_d);
        power.push(r.error_power);
        for (i, rate) in r.rates.iter().enumerate() {
            rates[i].push(*rate);
        }
        println!(
            "run {run}: total rate {:.4}, ‖e‖_P {:.4}, max |distance error| (t ≥ {} s) {max_d:.3} m",
            r.total_rate,
            r.error_power,
            steady / RATE
        );
    }
    if runs > 0 {
        println!("per-vehicle communication rate (mean ± std over {runs} runs of {seconds} s):");
        for (i, r) in rates.iter().enumerate() {
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / r.len() as f64;
            println!("  vehicle {:2}: {:.4} ± {:.4}", i + 1, mean, var.sqrt());
        }
        println!(
            "largest steady distance error over all runs: {worst_distance:.3} m; mean ‖e‖_P {:.4}",
            power.iter().sum::<f64>() / power.len() as f64
        );
    }
}
