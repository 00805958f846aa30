//! Where the time of a pmpc step goes on the quadruple integrator: per-step wall time (best of
//! 5 replays) and the solver's work counters along the x0 = 0.3·𝟙 closed loop, with the 15
//! slowest steps listed (`cargo run --release -p pmpc --example step_profile -- [s] [budget]`).
//! `POLISH=k` sets the Newton moves per addition (`Settings::polish_steps`), `NU=ν` the basis
//! decay rate (default the paper's 0.7 1/s), `SCAN=k` the iterations before the check scans
//! whole rows in the cold first step (`Settings::scan_after_cold`), `SCAN_WARM=k` in the warm
//! steps (`Settings::scan_after_warm`), `STARTS=random` runs the 10 starts from [0, 0.2]⁴ of
//! 250 steps each of `tests/budget.rs` instead; `HOT=1` replays the 20 slowest steps from saved
//! controller states many times, for a profiler; `EVICT=k` writes k MiB between the timed steps
//! (beyond the last-level cache: the step runs from memory, as after the other work of a loop).
#![allow(clippy::unwrap_used)]

use pmpc::{scenario, simulate, Pmpc, StepInfo};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rigid_body::laguerre::Laguerre;
use std::time::Instant;

/// One timed step: start index, step index, best time (µs), diagnostics.
struct Timed {
    start: usize,
    k: usize,
    us: f64,
    info: StepInfo,
}

fn main() {
    let number = |name: &str, text: String| -> usize {
        text.parse().unwrap_or_else(|_| {
            eprintln!("step_profile: {name} must be a positive integer, got {text:?}");
            std::process::exit(2)
        })
    };
    let mut args = std::env::args().skip(1);
    let s = args.next().map_or(10, |a| number("s", a));
    let budget = args.next().map(|a| number("budget", a));
    let polish = std::env::var("POLISH").map_or(3, |v| number("POLISH", v));
    let scan_after = std::env::var("SCAN")
        .map_or(rigid_body::siqp::Settings::default().scan_after_cold, |v| {
            number("SCAN", v)
        });
    let scan_after_warm = std::env::var("SCAN_WARM")
        .map_or(rigid_body::siqp::Settings::default().scan_after_warm, |v| {
            number("SCAN_WARM", v)
        });
    let nu = std::env::var("NU").map_or(scenario::NU, |v| {
        v.parse().unwrap_or_else(|_| {
            eprintln!("step_profile: NU must be a number (1/s), got {v:?}");
            std::process::exit(2)
        })
    });
    let sc = scenario::quad_integrator();
    let starts: Vec<(Vec<f64>, usize)> = match std::env::var("STARTS").as_deref() {
        Ok("random") => {
            let mut rng = StdRng::seed_from_u64(14);
            (0..10)
                .map(|_| ((0..4).map(|_| rng.random_range(0.0..0.2)).collect(), 250))
                .collect()
        }
        Ok(other) if !other.is_empty() => {
            eprintln!("step_profile: STARTS must be \"random\", got {other:?}");
            std::process::exit(2)
        }
        _ => vec![(sc.x0.clone(), scenario::STEPS)],
    };
    let make = || -> Pmpc {
        let c = Laguerre::new(s, nu)
            .map_err(pmpc::Error::from)
            .and_then(|basis| sc.pmpc(basis))
            .unwrap_or_else(|e| {
                eprintln!("step_profile: s = {s}: {e}");
                std::process::exit(2)
            })
            .with_settings(rigid_body::siqp::Settings {
                polish_steps: polish,
                scan_after_cold: scan_after,
                scan_after_warm,
                ..Default::default()
            });
        match budget {
            Some(b) => c.with_budget(b),
            None => c,
        }
    };
    let mut ctrl = make();
    let mut evict = std::env::var("EVICT")
        .ok()
        .map(|v| vec![0u64; number("EVICT", v) << 17]);
    let (mut timed, mut loops) = (Vec::new(), Vec::new());
    let (mut cost, mut violation, mut fallbacks) = (0.0, f64::NEG_INFINITY, 0);
    let (mut first_iterations, mut first_us) = (0, 0.0f64);
    for (start, (x0, steps)) in starts.iter().enumerate() {
        let cl = simulate::run_pmpc(&mut ctrl, x0, *steps, 40).unwrap();
        let mut best = vec![f64::INFINITY; cl.x.len()];
        for _ in 0..5 {
            ctrl.reset();
            for (k, x) in cl.x.iter().enumerate() {
                if let Some(buf) = evict.as_mut() {
                    buf.iter_mut().for_each(|v| *v = v.wrapping_add(1));
                    std::hint::black_box(&buf);
                }
                let t0 = Instant::now();
                std::hint::black_box(ctrl.step(x).unwrap());
                best[k] = best[k].min(t0.elapsed().as_secs_f64() * 1e6);
            }
        }
        first_iterations = first_iterations.max(cl.steps[0].stats.iterations);
        first_us = first_us.max(best[0]);
        cost += cl.cost / starts.len() as f64;
        violation = violation.max(cl.max_violation);
        fallbacks += cl.fallbacks;
        timed.extend((1..best.len()).map(|k| Timed {
            start,
            k,
            us: best[k],
            info: cl.steps[k],
        }));
        loops.push(cl.x);
    }
    let n = timed.len() as f64;
    let mut sorted: Vec<f64> = timed.iter().map(|t| t.us).collect();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
    let mean = |f: &dyn Fn(&Timed) -> f64| timed.iter().map(f).sum::<f64>() / n;
    println!(
        "s={s} budget={budget:?}: step time best of 5 replays, median {:.1} us, p99 {:.1} us, max {:.1} us",
        at(0.5),
        at(0.99),
        at(1.0)
    );
    println!(
        "s={s} budget={budget:?}: J_cl {cost:.4} (mean over {} starts), violation {violation:.1e}, fallbacks {fallbacks}; mean per step: {:.1} us, iterations {:.2}, taylor {:.1}, adds {:.2}, drops {:.2}, moves {:.2}",
        starts.len(),
        mean(&|t| t.us),
        mean(&|t| t.info.stats.iterations as f64),
        mean(&|t| t.info.stats.taylor_steps as f64),
        mean(&|t| t.info.stats.adds as f64),
        mean(&|t| t.info.stats.drops as f64),
        mean(&|t| t.info.stats.moves as f64),
    );
    println!(
        "s={s} budget={budget:?}: first (cold) step, worst over the starts: {first_iterations} iterations, {first_us:.1} us"
    );
    timed.sort_by(|a, b| b.us.total_cmp(&a.us));
    if std::env::var("HOT").is_ok() {
        hot(&mut ctrl, &loops, &timed[..timed.len().min(20)]);
        return;
    }
    println!("slowest steps: start, k, us, iterations, taylor, adds, drops, moves, active, source");
    for t in timed.iter().take(15) {
        let i = t.info;
        println!(
            "{:2} {:5} {:7.1} {:4} {:5} {:4} {:4} {:4} {:3} {:?}",
            t.start,
            t.k,
            t.us,
            i.stats.iterations,
            i.stats.taylor_steps,
            i.stats.adds,
            i.stats.drops,
            i.stats.moves,
            i.active,
            i.source
        );
    }
}

/// Replay the slow steps from saved controller states (for a profiler).
fn hot(ctrl_fresh: &mut Pmpc, loops: &[Vec<Vec<f64>>], slow: &[Timed]) {
    let mut saved = Vec::new();
    for (start, xs) in loops.iter().enumerate() {
        ctrl_fresh.reset();
        for (k, x) in xs.iter().enumerate() {
            if slow.iter().any(|t| t.start == start && t.k == k) {
                saved.push((ctrl_fresh.clone(), x.clone()));
            }
            ctrl_fresh.step(x).unwrap();
        }
    }
    let t0 = Instant::now();
    let mut n = 0;
    for _ in 0..3000 {
        for (c, x) in &saved {
            let mut c = c.clone();
            std::hint::black_box(c.step(x).unwrap());
            n += 1;
        }
    }
    println!(
        "hot replay: {:.1} us per step (with clone)",
        t0.elapsed().as_secs_f64() * 1e6 / n as f64
    );
}
