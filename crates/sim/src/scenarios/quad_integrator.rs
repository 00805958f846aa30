//! `stabilis sim quad-integrator`: the quadruple integrator of the parametrized-MPC paper
//! (x'''' = u, |u| ≤ 0.5, x ≥ 0, x0 = 0.3·𝟙) under parametrized infinite-horizon MPC or the
//! standard discrete-time MPC baseline. Logs `/quad_integrator/input` (`u`) and
//! `/quad_integrator/state` (`x dx ddx dddx`) at every sample.
use pmpc::baseline::Backend;
use pmpc::{scenario, simulate};
use rigid_body::laguerre::Laguerre;

use crate::error::{Result, SimError};
use crate::log::Experiment;
use crate::progress::Progress;
use crate::scenarios::{Common, Recorder, Scenario};

/// Topic prefix.
pub const TOPIC: &str = "/quad_integrator";

/// Which MPC runs the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Controller {
    /// Parametrized infinite-horizon MPC (Laguerre basis, constraints for all t).
    Pmpc,
    /// Discrete-time MPC with horizon N, condensed, Clarabel.
    Discrete,
}

/// Options of `stabilis sim quad-integrator`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Args {
    /// Shared options (the paper runs 20 s: `--duration 20`).
    #[command(flatten)]
    pub common: Common,
    /// Controller.
    #[arg(long, value_enum, default_value_t = Controller::Pmpc)]
    pub controller: Controller,
    /// Number of Laguerre functions (pmpc).
    #[arg(long, default_value_t = 12)]
    pub s: usize,
    /// Laguerre decay rate, 1/s (pmpc).
    #[arg(long, default_value_t = scenario::NU)]
    pub nu: f64,
    /// Horizon in samples (discrete).
    #[arg(long, default_value_t = 93)]
    pub horizon: usize,
}

impl Scenario for Args {
    fn common(&self) -> &Common {
        &self.common
    }

    fn run(&self, recorder: &mut Recorder, progress: &mut Progress) -> Result<()> {
        let duration = self.common.duration;
        let steps = super::samples(duration, 1.0 / scenario::TD)?;
        let sc = scenario::quad_integrator();
        let domain = |e: pmpc::Error| SimError::domain("quadruple-integrator MPC", e);
        let closed_loop = match self.controller {
            Controller::Pmpc => {
                let basis = Laguerre::new(self.s, self.nu)
                    .map_err(|e| SimError::domain("Laguerre basis", e))?;
                let mut ctrl = sc.pmpc(basis).map_err(domain)?;
                simulate::run_pmpc(&mut ctrl, &sc.x0, steps, 10).map_err(domain)?
            }
            Controller::Discrete => {
                let mut ctrl = sc
                    .discrete(self.horizon, Backend::Clarabel)
                    .map_err(domain)?;
                simulate::run_discrete(&mut ctrl, &sc.x0, steps).map_err(domain)?
            }
        };
        let mut experiment = Experiment::new(1.0 / scenario::TD);
        let name = match self.controller {
            Controller::Pmpc => format!("pmpc s={} nu={}", self.s, self.nu),
            Controller::Discrete => format!("discrete N={}", self.horizon),
        };
        for (key, value) in [
            ("system", "quad-integrator".to_string()),
            ("duration_s", duration.to_string()),
            ("controller", name),
        ] {
            experiment.extra.insert(key.into(), value);
        }
        recorder.experiment(&experiment)?;
        let input = recorder.add_topic(&format!("{TOPIC}/input"), &["u"])?;
        let state = recorder.add_topic(&format!("{TOPIC}/state"), &["x", "dx", "ddx", "dddx"])?;
        for ((t, x), u) in closed_loop.t.iter().zip(&closed_loop.x).zip(&closed_loop.u) {
            recorder.record(input, *t, u)?;
            recorder.record(state, *t, x)?;
        }
        progress.set(100);
        let last = closed_loop
            .x
            .last()
            .map_or(0.0, |x| x.iter().map(|v| v * v).sum::<f64>().sqrt());
        recorder.summarize("closed_loop_cost", closed_loop.cost);
        recorder.summarize("max_constraint_violation", closed_loop.max_violation);
        recorder.summarize("fallbacks", closed_loop.fallbacks as u64);
        recorder.summarize("final_state_norm", last);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(controller: Controller, duration: f64) -> crate::scenarios::Recording {
        let args = Args {
            common: Common {
                duration,
                out: None,
                seed: 0,
            },
            controller,
            s: 12,
            nu: scenario::NU,
            horizon: 93,
        };
        let mut recorder = Recorder::new(None).unwrap();
        args.run(&mut recorder, &mut Progress::hidden()).unwrap();
        recorder.finish().unwrap()
    }

    /// Both controllers keep |u| ≤ 0.5 and x ≥ 0 at the samples over the first 2 s, and the log
    /// has one sample per T_d.
    #[test]
    fn both_controllers_respect_the_constraints() {
        for controller in [Controller::Pmpc, Controller::Discrete] {
            let rec = run(controller, 2.0);
            let u = rec.topics["/quad_integrator/input"].column("u").unwrap();
            let x = rec.topics["/quad_integrator/state"].column("x").unwrap();
            assert_eq!(u.len(), 101);
            assert!(u.iter().all(|v| v.abs() <= 0.5 + 1e-6));
            assert!(x.iter().all(|v| *v >= -1e-5));
        }
    }

    #[test]
    fn bad_duration_is_rejected() {
        let args = Args {
            common: Common {
                duration: -1.0,
                out: None,
                seed: 0,
            },
            controller: Controller::Pmpc,
            s: 12,
            nu: scenario::NU,
            horizon: 93,
        };
        let mut recorder = Recorder::new(None).unwrap();
        assert!(args.run(&mut recorder, &mut Progress::hidden()).is_err());
    }
}
