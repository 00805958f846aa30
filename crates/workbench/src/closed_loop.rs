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

/// A sentence when `model` at the fitted `params`, sampled at the logs' rate, is unstable in closed loop
/// with the model file's controller: its response to a disturbance of every state grows over
/// the longest record. The logs come from a loop that held, so such a fit is wrong where the
/// loop's margins lie, which closed-loop logs barely excite (a hopper's fitted model diverged
/// 3e8-fold with its controller beside "explained"), or the file's controller is not the one
/// that ran. `None` without a controller at the logs' rate, or when the loop is stable.
pub fn unstable_loop(
    model: &super::model::Model,
    params: &[super::fit::ParamEstimate],
    data: &Dataset,
) -> crate::error::Result<Option<String>> {
    let Some(controller) = model.structure().controller() else {
        return Ok(None);
    };
    let rate = controller_rate(&controller);
    if (rate - data.sample_rate_hz).abs() > 1e-9 * rate {
        return Ok(None);
    }
    let theta: Vec<f64> = model
        .parameters()?
        .iter()
        .map(|q| {
            params
                .iter()
                .find(|p| p.name == q.name)
                .map_or(q.value, |p| p.value)
        })
        .collect();
    // A model that cannot be sampled there has failed the fit's own checks already.
    let Some(disc) = model
        .state_space(&theta)
        .ok()
        .and_then(|ss| ss.discretize(1.0 / rate).ok())
    else {
        return Ok(None);
    };
    let samples = data
        .experiments
        .iter()
        .map(|e| e.u.nrows())
        .max()
        .unwrap_or(0)
        .max(4 * UNSTABLE_MIN_SAMPLES);
    let r = DMatrix::zeros(samples, disc.gamma0.ncols());
    let mut first = true;
    let run = run_loop(&disc, &controller, &r, &mut |w, _| {
        if std::mem::take(&mut first) {
            w.fill(1.0);
        }
    });
    let seconds = samples as f64 / rate;
    let grown = match run {
        Err(k) => Some(format!("diverges after {:.1} s", k as f64 / rate)),
        Ok((_, y)) => {
            // Against the first quarter, which holds the response to the disturbance: a
            // stable loop's last quarter is far below it.
            let q = samples / 4;
            let g = y
                .column_iter()
                .map(|c| c.rows(samples - q, q).norm() / c.rows(0, q).norm().max(f64::MIN_POSITIVE))
                .fold(0.0, f64::max);
            (g > GROWTH).then(|| format!("grows {g:.1e}-fold over {seconds:.0} s"))
        }
    };
    // A nonlinear model is checked through its linearization, whose slope a law that is not
    // smooth at the operating point does not share with the loop (a cart's dry friction
    // smoothed over a small speed is a huge damping there: the true plant's linearization
    // failed this check with its own controller).
    let (what, unless) = if model.structure().is_nonlinear() {
        (
            "the fitted model's linearization at the operating point",
            "; unless a law in it is not smooth there (dry friction, a dead zone), whose slope at the operating point the loop never sees",
        )
    } else {
        ("the fitted model", "")
    };
    Ok(grown.map(|how| {
        format!(
            "{what} is unstable in closed loop with the model file's controller (its response to a disturbance {how}), while the logged loop held: the fit is wrong where the loop's stability margins lie, which closed-loop logs barely excite, or the [controller] in the file is not the one that ran{unless}; do not design on this model before finding out which"
        )
    }))
}

/// Fewest samples of each quarter of [`unstable_loop`]'s run.
const UNSTABLE_MIN_SAMPLES: usize = 250;

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

    /// The input of one sample, excitation `r` included, and the outputs measured with it,
    /// from the plant's state `x` and `measure(u)`, the outputs under input `u`. The outputs
    /// of a sample see its input (feed-through, the convention of the fits), and a dynamic
    /// controller reads them: the two are solved together. `None`: `measure` failed, or the
    /// loop through the feed-through has no solution (`I - Dc D` singular) or does not settle.
    pub fn close(
        &mut self,
        x: &[f64],
        r: &DVector<f64>,
        measure: &mut dyn FnMut(&DVector<f64>) -> Option<DVector<f64>>,
    ) -> Option<(DVector<f64>, DVector<f64>)> {
        // The part of the input that does not read the outputs.
        let base = self.step(x, None) + r;
        let Controller::Discrete { d: dc, .. } = self.controller else {
            let y = measure(&base)?;
            return Some((base, y));
        };
        // u = base + Dc y(u): where the outputs do not see the input one pass settles it,
        // otherwise Newton's method on the outputs' differences (one step for a linear h).
        let y = measure(&base)?;
        let mut u = &base + dc * &y;
        let mut y_u = measure(&u)?;
        if y_u == y {
            self.step(x, Some(&y_u));
            return Some((u, y_u));
        }
        for _ in 0..FEEDTHROUGH_ITERATIONS {
            let residual = &u - &base - dc * &y_u;
            if residual.amax() <= 1e-12 * (1.0 + u.amax()) {
                self.step(x, Some(&y_u));
                return Some((u, y_u));
            }
            let mut slope = DMatrix::zeros(y_u.len(), u.len());
            for j in 0..u.len() {
                let h = 1e-7 * (1.0 + u[j].abs());
                let mut moved = u.clone();
                moved[j] += h;
                slope.set_column(j, &((measure(&moved)? - &y_u) / h));
            }
            let jacobian = DMatrix::identity(u.len(), u.len()) - dc * slope;
            u -= jacobian.lu().solve(&residual)?;
            y_u = measure(&u)?;
        }
        None
    }

    /// The input of one sample (the excitation not included) from the plant's state `x` and
    /// the measured outputs `y` (`None`: the part that does not read them, and the
    /// controller's state stays), then with `y` the controller's next state.
    fn step(&mut self, x: &[f64], y: Option<&DVector<f64>>) -> DVector<f64> {
        match self.controller {
            Controller::StateFeedback { k: gain, .. } => {
                // The gain acts on the file's states, which come first in the fitted model
                // (a lag's states are appended).
                let nk = gain.ncols().min(x.len());
                -(gain.columns(0, nk) * DVector::from_column_slice(&x[..nk]))
            }
            Controller::Discrete { a, b, c, d, .. } => match y {
                None => c * &self.xc,
                Some(y) => {
                    let out = c * &self.xc + d * y;
                    self.xc = a * &self.xc + b * y;
                    out
                }
            },
        }
    }
}

/// Most Newton steps [`ControllerState::close`] takes through a feed-through.
const FEEDTHROUGH_ITERATIONS: usize = 20;

/// A simulated loop's inputs and measured outputs (samples in rows), or the sample after
/// which the plant's state was no longer finite.
pub type LoopRun = Result<(DMatrix<f64>, DMatrix<f64>), usize>;

/// Runs the sampled model `disc` in closed loop with `controller`, driven by the excitation
/// `r` (samples x inputs), from zero plant and controller states; returns the inputs and the
/// measured outputs, samples in rows. `noise(w, v)` may add process noise `w` (states) to each
/// next state and sensor noise `v` (outputs) to each measured output the controller sees; it
/// is called once per sample, both vectors zeroed. The outputs of a sample see its input
/// ([`ControllerState::close`]). `Err(k)`: the state is no longer finite after sample `k`, or
/// the loop through a feed-through has no input there.
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
        // A delayed input is known before this sample's is chosen; without a delay the
        // outputs see this sample's input.
        let mut y0 = &disc.c * &x + &v;
        if disc.d_shift > 0 && k >= disc.d_shift {
            y0 += &disc.d * u.row(k - disc.d_shift).transpose();
        }
        let now = disc.d_shift == 0;
        let (uk, yk) = control
            .close(x.as_slice(), &r.row(k).transpose(), &mut |u| {
                Some(if now { &y0 + &disc.d * u } else { y0.clone() })
            })
            .ok_or(k)?;
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

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use nalgebra::DMatrix;

    use super::*;
    use crate::dataset::Experiment;
    use crate::model::Model;
    use crate::model_file::ModelFile;

    /// The loop test agrees with the closed loop's eigenvalues (`Phi - Gamma K`, the sampled
    /// pendulum under its state feedback) on both sides of the stability boundary, here at a
    /// mass of 0.76 kg: stable below, unstable above, and it names the growth.
    #[test]
    fn an_unstable_fitted_loop_is_named_as_the_eigenvalues_say() {
        let data = Dataset {
            sample_rate_hz: 100.0,
            inputs: vec!["T".into()],
            outputs: vec!["theta".into()],
            experiments: vec![Experiment {
                name: "e0".into(),
                u: DMatrix::zeros(3000, 1),
                y: DMatrix::zeros(3000, 1),
                r: None,
                periodic: None,
            }],
        };
        for m in [0.2, 0.5, 0.65, 0.9, 1.2, 1.5] {
            let text = format!(
                "{}\n[controller]\nsample_rate_hz = 100\nK = [[3.0, 0.3]]\n",
                crate::model_file::tests::PENDULUM
                    .replace("value = 0.5,", &format!("value = {m},"))
            );
            let file = Arc::new(ModelFile::parse(&text, Path::new("p.toml")).unwrap());
            let model = Model::new(file);
            let disc = model
                .state_space(&model.documented().unwrap())
                .unwrap()
                .discretize(0.01)
                .unwrap();
            let k = DMatrix::from_row_slice(1, 2, &[3.0, 0.3]);
            let rho = rigid_body::lti::spectral_radius(&(&disc.phi - &disc.gamma0 * k)).unwrap();
            let said = unstable_loop(&model, &[], &data).unwrap();
            assert_eq!(said.is_some(), rho > 1.0, "m {m}: rho {rho}, {said:?}");
            if let Some(s) = said {
                assert!(
                    s.contains("unstable in closed loop") && s.contains("-fold"),
                    "{s}"
                );
            }
        }
        // The same pendulum written as a nonlinear model is checked through its
        // linearization, and the sentence says so.
        let nonlinear = "[nonlinear]\nf.theta = \"omega\"\nf.omega = \"(m*g*l*sin(theta) + T)/Jp\"\nh.theta = \"theta\"\noperating_point = { theta = 0, omega = 0, T = 0 }\n";
        let base = crate::model_file::tests::PENDULUM;
        let start = base.find("[linear]").unwrap();
        let text = format!(
            "{}{nonlinear}\n[controller]\nsample_rate_hz = 100\nK = [[3.0, 0.3]]\n",
            base[..start].replace("value = 0.5,", "value = 1.5,")
        );
        let model = Model::new(Arc::new(
            ModelFile::parse(&text, Path::new("p.toml")).unwrap(),
        ));
        let said = unstable_loop(&model, &[], &data).unwrap().unwrap();
        assert!(
            said.starts_with("the fitted model's linearization at the operating point is unstable")
                && said.contains("not smooth there"),
            "{said}"
        );
    }
}
