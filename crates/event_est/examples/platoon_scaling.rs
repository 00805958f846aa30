//! Synthesis time and bounds of the M-vehicle platoon with Cor 13 (Step 1 + Step 2).
//!
//! `cargo run --release -p event_est --example platoon_scaling -- [clarabel|schur] 3 4 6 8`
//! (the SDP solver defaults to Clarabel; `schur` is the Schur-complement interior-point method).
#![allow(clippy::unwrap_used)]

use event_est::model::platoon;
use event_est::synth::{step1_using, step2_unit_using, Solver, Stability};
use std::time::Instant;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let solver = match args.first().map(|a| Solver::parse(a)) {
        Some(Ok(s)) => {
            args.remove(0);
            s
        }
        _ => Solver::Clarabel,
    };
    let sizes: Vec<usize> = args.iter().map(|a| a.parse().unwrap()).collect();
    let sizes = if sizes.is_empty() {
        vec![3, 4, 5, 6]
    } else {
        sizes
    };
    println!("| M | n | variables | Step 1 | status | c* | true H2 | Step 2 | wall total |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for m in sizes {
        let (sys, _) = platoon(m).unwrap();
        let t0 = Instant::now();
        match step1_using(&sys, Stability::Cor13, solver) {
            Ok(s1) => {
                let t1 = t0.elapsed().as_secs_f64();
                let unit = step2_unit_using(&sys, &s1.l, 1.0, solver);
                let t2 = t0.elapsed().as_secs_f64() - t1;
                let step2 = match &unit {
                    Ok(_) => format!("{t2:.2} s"),
                    Err(e) => format!("failed: {e}"),
                };
                println!(
                    "| {m} | {} | {} | {t1:.2} s | {} ({} it) | {:.5} | {:.5} | {step2} | {:.2} s |",
                    sys.n(),
                    s1.variables,
                    s1.status,
                    s1.iterations,
                    s1.c_star,
                    s1.true_h2,
                    t0.elapsed().as_secs_f64()
                );
            }
            Err(e) => println!(
                "| {m} | {} | - | {:.2} s | {e} | | | | |",
                sys.n(),
                t0.elapsed().as_secs_f64()
            ),
        }
    }
}
