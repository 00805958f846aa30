//! Where the time of a pmpc step goes on the quadruple integrator: per-step wall time (best of
//! 5 replays) and the solver's work counters along the x0 = 0.3·𝟙 closed loop, with the 15
//! slowest steps listed (`cargo run --release -p pmpc --example step_profile -- [s] [budget]`).
//! `POLISH=k` sets the Newton moves per addition (`Settings::polish_steps`), `NU=ν` the basis
//! decay rate (default the paper's 0.7 1/s); `HOT=1` instead
//! replays the 20 slowest steps from saved controller states many times, for a profiler.
#![allow(clippy::unwrap_used)]

use pmpc::{scenario, simulate, Pmpc};
use rigid_body::laguerre::Laguerre;
use std::time::Instant;

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
    let nu = std::env::var("NU").map_or(scenario::NU, |v| {
        v.parse().unwrap_or_else(|_| {
            eprintln!("step_profile: NU must be a number (1/s), got {v:?}");
            std::process::exit(2)
        })
    });
    let sc = scenario::quad_integrator();
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
                ..Default::default()
            });
        match budget {
            Some(b) => c.with_budget(b),
            None => c,
        }
    };
    let mut ctrl = make();
    let cl = simulate::run_pmpc(&mut ctrl, &sc.x0, scenario::STEPS, 40).unwrap();
    let mut best = vec![f64::INFINITY; cl.x.len()];
    for _ in 0..5 {
        ctrl.reset();
        for (k, x) in cl.x.iter().enumerate() {
            let t0 = Instant::now();
            std::hint::black_box(ctrl.step(x).unwrap());
            best[k] = best[k].min(t0.elapsed().as_secs_f64() * 1e6);
        }
    }
    let mut order: Vec<usize> = (1..best.len()).collect();
    order.sort_by(|&a, &b| best[b].total_cmp(&best[a]));
    let tot = |f: &dyn Fn(&pmpc::StepInfo) -> usize| -> usize { cl.steps[1..].iter().map(f).sum() };
    let n = (cl.steps.len() - 1) as f64;
    let mut sorted = best[1..].to_vec();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
    println!(
        "s={s} budget={budget:?}: step time best of 5 replays, median {:.1} us, p99 {:.1} us, max {:.1} us",
        at(0.5),
        at(0.99),
        at(1.0)
    );
    println!(
        "s={s} budget={budget:?}: J_cl {:.4}, violation {:.1e}, fallbacks {}; mean per step: {:.1} us, iterations {:.2}, taylor {:.1}, adds {:.2}, drops {:.2}, moves {:.2}",
        cl.cost,
        cl.max_violation,
        cl.fallbacks,
        best[1..].iter().sum::<f64>() / n,
        tot(&|i| i.stats.iterations) as f64 / n,
        tot(&|i| i.stats.taylor_steps) as f64 / n,
        tot(&|i| i.stats.adds) as f64 / n,
        tot(&|i| i.stats.drops) as f64 / n,
        tot(&|i| i.stats.moves) as f64 / n,
    );
    println!("slowest steps: k, us, iterations, taylor, adds, drops, moves, active, source");
    if std::env::var("HOT").is_ok() {
        let slow: Vec<usize> = order.iter().take(20).copied().collect();
        hot(&mut ctrl, &cl.x, &slow);
        return;
    }
    for &k in order.iter().take(15) {
        let i = cl.steps[k];
        println!(
            "{k:5} {:7.1} {:4} {:5} {:4} {:4} {:4} {:3} {:?}",
            best[k],
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

fn hot(ctrl_fresh: &mut Pmpc, xs: &[Vec<f64>], slow: &[usize]) {
    // Replay the slow steps from saved controller states (for a profiler).
    let mut saved = Vec::new();
    ctrl_fresh.reset();
    for (k, x) in xs.iter().enumerate() {
        if slow.contains(&k) {
            saved.push((ctrl_fresh.clone(), x.clone()));
        }
        ctrl_fresh.step(x).unwrap();
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
