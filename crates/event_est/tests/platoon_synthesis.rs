//! Reproduction of the 3-vehicle platoon design (Section 10.1 of the spec).
#![allow(clippy::unwrap_used)]

use event_est::model::platoon;
use event_est::synth::{step1, step2_unit, Stability};

#[test]
fn explore() {
    let (sys, _) = platoon(3).unwrap();
    for st in [Stability::None, Stability::Cor12, Stability::Cor13, Stability::Thm11, Stability::Cor13WithH] {
        let t = std::time::Instant::now();
        let r = step1(&sys, st);
        match r {
            Ok(r) => {
                println!("{st:?}: c*={:.6} true={:.6} kf={:.6} {} {:?} maxmargin {:e}", r.c_star, r.true_h2, r.kalman_cost, r.status, t.elapsed(), r.stability_margins.iter().map(|m| m.1).fold(f64::MIN, f64::max));
                let u = step2_unit(&sys, &r.l, 1.0).unwrap();
                println!("  unit {:?} {}", u.delta.iter().map(|d| d[(0,0)]).collect::<Vec<_>>(), u.status);
            }
            Err(e) => println!("{st:?}: {e}"),
        }
    }
}
