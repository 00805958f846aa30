//! Closed-loop re-simulation: the fitted model in the loop with the experimenter's controller
//! (a model file's `[controller]`), driven by the logged excitation alone, against the
//! measured outputs. Unlike a free run this is meaningful for an unstable plant: the loop the
//! experimenter ran is stable.
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::dataset::Dataset;
use super::model_file::Controller;
use super::timedomain::{fit_percent_from, Discrete};

/// The re-simulation's fit.
#[derive(Debug, Clone, Serialize)]
pub struct ClosedLoopFit {
    /// How it was made.
    pub policy: String,
    /// Fit % per output, pooled over the experiments.
    pub fit: Vec<(String, f64)>,
}

/// Re-simulates every experiment with an excitation; `Err` says why it cannot be done.
pub fn closed_loop_fit(
    data: &Dataset,
    disc: &Discrete,
    controller: &Controller,
) -> Result<ClosedLoopFit, String> {
    let rate = controller_rate(controller);
    if (rate - data.sample_rate_hz).abs() > 1e-9 * rate {
        return Err(format!(
            "the controller runs at {rate} Hz, the data at {} Hz",
            data.sample_rate_hz
        ));
    }
    let mut measured = Vec::new();
    let mut simulated = Vec::new();
    let mut first_scored = 0;
    for e in &data.experiments {
        let r =
            e.r.as_ref()
                .ok_or_else(|| format!("{} has no logged excitation to drive the loop", e.name))?;
        let samples = r.nrows();
        let from = e
            .periodic
            .as_ref()
            .map_or(samples / 10, |p| p.transient)
            .min(samples / 2);
        first_scored = from;
        let (_, y) = run_loop(disc, controller, r, &mut |_, _| {}).map_err(|k| {
            format!(
                "the loop of the fitted model and the controller diverges in {} at sample {k}",
                e.name
            )
        })?;
        let mut ym = e.y.clone();
        for mut c in ym.column_iter_mut() {
            let mean = c.mean();
            c.add_scalar_mut(-mean);
        }
        let growth = growth(&y);
        if growth > GROWTH {
            return Err(format!(
                "the loop of the fitted model and the controller diverges in {}: the output rms \
                 grows {growth:.1e}-fold from the second to the last quarter of the record",
                e.name
            ));
        }
        measured.push((ym, from));
        simulated.push(y);
    }
    let fit = fit_percent_from(&measured, &simulated);
    Ok(ClosedLoopFit {
        policy: format!(
            "the fitted model in closed loop with the model file's controller at {rate} Hz \
             (zero-order hold), driven by the logged excitation only (no noise), from zero \
             plant and controller states; measured outputs as deviations from their record \
             means; scored after the transient (from sample {first_scored}); fit % pooled over \
             the experiments"
        ),
        fit: data.outputs.iter().cloned().zip(fit).collect(),
    })
}

/// Growth of the output rms over a record above which a simulated loop counts as diverged
/// (a stable loop driven by a stationary excitation and noise keeps its level; an unstable one
/// that is slow to overflow, such as a controller pole just outside the unit circle, would
/// otherwise score a fit of -1e24 %).
pub const GROWTH: f64 = 10.0;

/// The largest ratio over the outputs of the rms over the last quarter of `y` to the rms over
/// its second quarter (the first holds the start-up).
pub fn growth(y: &DMatrix<f64>) -> f64 {
    let q = y.nrows() / 4;
    if q == 0 {
        return 1.0;
    }
    y.column_iter()
        .map(|c| {
            let rms = |from: usize| c.rows(from, q).norm();
            rms(y.nrows() - q) / rms(q).max(f64::MIN_POSITIVE)
        })
        .fold(0.0, f64::max)
}

/// The rate the controller runs at, Hz.
pub fn controller_rate(controller: &Controller) -> f64 {
    match controller {
        Controller::StateFeedback { sample_rate_hz, .. }
        | Controller::Discrete { sample_rate_hz, .. } => *sample_rate_hz,
    }
}

/// The experimenter's controller between samples. It acts on deviations from the operating
/// point: `u = -K x` on the plant's state, or `xc[k+1] = A xc[k] + B y[k]`,
/// `u[k] = C xc[k] + D y[k]` on the measured outputs, from zero controller states.
#[derive(Debug)]
pub struct ControllerState<'a> {
    controller: &'a Controller,
    xc: DVector<f64>,
}

impl<'a> ControllerState<'a> {
    /// The controller at zero state.
    pub fn new(controller: &'a Controller) -> Self {
        let xc = match controller {
            Controller::Discrete { a, .. } => DVector::zeros(a.nrows()),
            Controller::StateFeedback { .. } => DVector::zeros(0),
        };
        Self { controller, xc }
    }

    /// The input of one sample (the excitation not included) from the plant's state `x` and
    /// the measured outputs `y`, then the controller's next state.
    pub fn step(&mut self, x: &[f64], y: &DVector<f64>) -> DVector<f64> {
        match self.controller {
            Controller::StateFeedback { k: gain, .. } => {
                // The gain acts on the file's states, which come first in the fitted model
                // (a lag's states are appended).
                let nk = gain.ncols().min(x.len());
                -(gain.columns(0, nk) * DVector::from_column_slice(&x[..nk]))
            }
            Controller::Discrete { a, b, c, d, .. } => {
                let out = c * &self.xc + d * y;
                self.xc = a * &self.xc + b * y;
                out
            }
        }
    }
}

/// A simulated loop's inputs and measured outputs (samples in rows), or the sample after
/// which the plant's state was no longer finite.
pub type LoopRun = Result<(DMatrix<f64>, DMatrix<f64>), usize>;

/// Runs the sampled model `disc` in closed loop with `controller`, driven by the excitation
/// `r` (samples x inputs), from zero plant and controller states; returns the inputs and the
/// measured outputs, samples in rows. `noise(w, v)` may add process noise `w` (states) to each
/// next state and sensor noise `v` (outputs) to each measured output the controller sees; it
/// is called once per sample, both vectors zeroed. `Err(k)`: the state is no longer finite
/// after sample `k`.
pub fn run_loop(
    disc: &Discrete,
    controller: &Controller,
    r: &DMatrix<f64>,
    noise: &mut dyn FnMut(&mut DVector<f64>, &mut DVector<f64>),
) -> LoopRun {
    let (n, m, p) = (disc.phi.nrows(), disc.gamma0.ncols(), disc.c.nrows());
    let samples = r.nrows();
    let mut x = DVector::zeros(n);
    let mut control = ControllerState::new(controller);
    let (mut w, mut v) = (DVector::zeros(n), DVector::zeros(p));
    let mut u = DMatrix::zeros(samples, m);
    let mut y = DMatrix::zeros(samples, p);
    for k in 0..samples {
        w.fill(0.0);
        v.fill(0.0);
        noise(&mut w, &mut v);
        let mut yk = &disc.c * &x + &v;
        if k >= disc.d_shift {
            yk += &disc.d * u.row(k - disc.d_shift).transpose();
        }
        let uk = control.step(x.as_slice(), &yk) + r.row(k).transpose();
        u.row_mut(k).copy_from(&uk.transpose());
        y.row_mut(k).copy_from(&yk.transpose());
        let mut next = &disc.phi * &x + &w;
        if k >= disc.whole {
            next += &disc.gamma0 * u.row(k - disc.whole).transpose();
        }
        if k > disc.whole {
            next += &disc.gamma1 * u.row(k - disc.whole - 1).transpose();
        }
        x = next;
        if !x.iter().all(|v| v.is_finite()) {
            return Err(k);
        }
    }
    Ok((u, y))
}
