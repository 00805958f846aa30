//! Non-parametric frequency response from periodic multi-experiment data (spec §6.3-6.4).
//!
//! Per excited line the experiments are stacked, `U = [Ū_1 .. Ū_E]`, and the plant is
//! `Ĝ = Ȳ W` with `W = U^+` (least squares) or `W = R^H (U R^H)^-1` (instrumental variable,
//! unbiased under feedback because the reference R is independent of the noise). The noise
//! covariance of `vec Ĝ` follows by error propagation, `Σ_e (w_e w_e^H) ⊗ C_e`, where `C_e`
//! is the covariance of the period mean of `Y - Ĝ U`, estimated from the whole record's
//! bins around the line (see [`FrfLine::noise_spectra`]) and pooled across experiments. The
//! record's transient is taken out of the line and of those bins by a local polynomial
//! ([`super::transient`]).
use nalgebra::DMatrix;
use serde::Serialize;

use super::dataset::{column_moves, Dataset};
use super::distortion::Distortion;
use super::spectra::{excited_bins, period_mean, Dft, C64};
use super::transient::{self, local_noise, LocalNoise};
use crate::error::{Result, SimError};

/// Complex matrix.
pub type CMatrix = DMatrix<C64>;

/// Which non-parametric estimator produced an FRF.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Estimator {
    /// `Ĝ = Y U^+`: biased under feedback of noise.
    LeastSquares,
    /// `Ĝ = (Y R^H)(U R^H)^-1` with the logged excitation R.
    InstrumentalVariable,
    /// Welch-averaged cross-spectra `S_yu S_uu^-1` (non-periodic logs).
    H1Welch,
    /// Welch-averaged `S_yr S_ur^-1` with the logged excitation (non-periodic closed loop).
    H1WelchInstrumental,
}

impl Estimator {
    /// Human-readable description for summaries.
    pub fn describe(self) -> &'static str {
        match self {
            Self::LeastSquares => "least squares Y U^+ (biased under feedback)",
            Self::InstrumentalVariable => "instrumental variable (Y R^H)(U R^H)^-1",
            Self::H1Welch => "H1 Welch S_yu S_uu^-1 (biased under feedback)",
            Self::H1WelchInstrumental => "Welch instrumental variable S_yr S_ur^-1",
        }
    }

    /// True for the estimators that use the measured input as their own instrument (least
    /// squares, H1 Welch): in closed loop the input carries fed-back noise, so they are biased.
    pub fn biased_under_feedback(self) -> bool {
        matches!(self, Self::LeastSquares | Self::H1Welch)
    }
}

/// Which estimator to use for periodic data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorChoice {
    /// Instrumental variable when the excitation is logged, least squares otherwise.
    Auto,
    /// Always least squares (the paper's estimator).
    LeastSquares,
    /// Instrumental variable; an error when the excitation is missing.
    InstrumentalVariable,
}

/// The FRF at one excited line with its noise description.
#[derive(Debug, Clone)]
pub struct FrfLine {
    /// Frequency in Hz.
    pub freq_hz: f64,
    /// Estimate, outputs x inputs.
    pub g: CMatrix,
    /// Covariance of vec(Ĝ) (column-major), (ny nu) x (ny nu).
    pub cov: CMatrix,
    /// The stacking weights W (experiments x inputs): `Ĝ = Ȳ W`.
    pub weights: CMatrix,
    /// Per-period noise covariance of `y - Ĝ u` (outputs x outputs).
    pub period_noise: CMatrix,
    /// Period-averaged input spectra per experiment (inputs x experiments).
    pub u_mean: CMatrix,
    /// Period-averaged output spectra per experiment (outputs x experiments).
    pub y_mean: CMatrix,
    /// Coherence per output (non-periodic estimates only).
    pub coherence: Option<Vec<f64>>,
    /// When the covariance is `M ⊗ S` (noise pooled over experiments): `(M, S)`.
    pub kronecker: Option<(CMatrix, CMatrix)>,
    /// Periodic estimates: per experiment the whole record's transforms `(U, Y)` around the
    /// line at the bins no period harmonic holds, scaled to per-period noise, with the
    /// record's transient taken out (channels x degrees of freedom, see
    /// [`super::transient`]), from which [`model_noise`] re-estimates `S` with a model; empty
    /// for Welch.
    ///
    /// Why not each period's deviation from the period mean: a period's transform of a system
    /// out of periodic steady state carries the transient `tau (x_p - x_(p+1))` of the states
    /// at its ends. Over the periods these terms telescope, so the mean that makes the
    /// estimate's error holds one of them divided by `P`, while every period's deviation holds
    /// a whole one. Where a slow closed-loop mode moves the states by much from one period to
    /// the next (an arm or a cart the loop holds loosely) the deviations overstate the noise:
    /// on a loop with a mode of two periods' time constant the mean's variance was 0.67-0.77
    /// of what they said, on every line, and the true model's cost 0.835 of the reference. The
    /// whole record's bins see the noise at the mean's resolution and one transient, which
    /// the local polynomial takes out of them and of the line.
    pub noise_spectra: Vec<(CMatrix, CMatrix)>,
    /// Periodic estimates: per experiment the noise variance of the period mean with the
    /// transient taken out, in units of the per-period `S`: `(1 + inflation) / P` (see
    /// [`super::transient::LocalNoise::inflation`]); empty for Welch.
    pub mean_variance: Vec<f64>,
    /// Welch estimates: the window's kernel, through which the line sees the plant's response
    /// at the bins beside it (see [`KernelTap`]); empty for periodic estimates, whose lines
    /// see the response at their own frequency.
    pub kernel: Vec<KernelTap>,
    /// Welch estimates: `M_kj` of `Cov(vec Ĝ_k, vec Ĝ_j) = M_kj ⊗ S` for the lines `j = k - 1,
    /// k - 2, ...` before this one, nearest first (neighbouring bins share the window's
    /// kernel, see [`crate::welch::CORRELATED_LINES`]); empty for periodic estimates, whose
    /// lines are independent.
    pub previous: Vec<CMatrix>,
}

/// One bin of the window's kernel at a Welch line. A Hann-windowed transform is
/// `X_w(k) = X(k)/2 - X(k-1)/4 - X(k+1)/4` in the segment's plain transforms, and a linear
/// plant gives `Y(m) = G(m) U(m)` there up to a smooth transient that the window's
/// differencing suppresses. So the estimate's line holds `Σ_d G(k+d) c_d U(k+d) W`, not
/// `G(k)`: where the response bends within a bin (an unstable pole or a resonance a few bins
/// wide) the two differ, and a model compared with the line at its own frequency absorbs the
/// difference as an effect. A model seen through these taps does not.
#[derive(Debug, Clone)]
pub struct KernelTap {
    /// The bin's frequency, Hz.
    pub freq_hz: f64,
    /// `c_d U(k+d)` per segment (inputs x segments): the segments' plain input transforms at
    /// the bin times the window's coefficient.
    pub u: CMatrix,
    /// `c_d U(k+d) W` (inputs x inputs): how the response at the bin enters the line.
    pub gain: CMatrix,
}

/// A model's FRF as an estimate sees it.
#[derive(Debug, Clone, Default)]
pub struct ModelFrf {
    /// Per line, what the estimate's line holds for this model (outputs x inputs).
    pub lines: Vec<CMatrix>,
    /// Per line, the response at each of its kernel taps (empty for lines without a kernel).
    pub taps: Vec<Vec<CMatrix>>,
}

/// The frequencies at which a model must be evaluated to be compared with an estimate's
/// lines (the lines' own, or with a Welch kernel the bins beside them, each once), and how
/// each line combines them.
#[derive(Debug, Clone)]
pub struct LineMap {
    grid_hz: Vec<f64>,
    /// Per line: grid index and tap gain (`None`: the line sees the response itself).
    taps: Vec<Vec<(usize, Option<CMatrix>)>>,
}

impl LineMap {
    /// The map of `frf`'s lines.
    pub fn new(frf: &FrfEstimate) -> Self {
        let mut grid_hz: Vec<f64> = frf
            .lines
            .iter()
            .flat_map(|l| {
                if l.kernel.is_empty() {
                    vec![l.freq_hz]
                } else {
                    l.kernel.iter().map(|t| t.freq_hz).collect()
                }
            })
            .collect();
        grid_hz.sort_by(f64::total_cmp);
        grid_hz.dedup();
        let index = |f: f64| grid_hz.partition_point(|&g| g < f);
        let taps = frf
            .lines
            .iter()
            .map(|l| {
                if l.kernel.is_empty() {
                    vec![(index(l.freq_hz), None)]
                } else {
                    l.kernel
                        .iter()
                        .map(|t| (index(t.freq_hz), Some(t.gain.clone())))
                        .collect()
                }
            })
            .collect();
        Self { grid_hz, taps }
    }

    /// Frequencies (Hz, ascending) at which the model is evaluated.
    pub fn grid_hz(&self) -> &[f64] {
        &self.grid_hz
    }

    /// One line's value from per-grid-frequency matrices `grid`: `Σ_d G_d K_d`.
    fn line(&self, k: usize, grid: &[CMatrix]) -> CMatrix {
        let term = |(i, gain): &(usize, Option<CMatrix>)| match gain {
            Some(gain) => &grid[*i] * gain,
            None => grid[*i].clone(),
        };
        match self.taps[k].split_first() {
            Some((first, rest)) => rest.iter().fold(term(first), |acc, t| acc + term(t)),
            None => CMatrix::zeros(0, 0),
        }
    }

    /// The lines' view of the model FRF `grid` (one matrix per [`LineMap::grid_hz`]).
    pub fn seen(&self, grid: &[CMatrix]) -> ModelFrf {
        ModelFrf {
            lines: (0..self.taps.len()).map(|k| self.line(k, grid)).collect(),
            taps: self
                .taps
                .iter()
                .map(|t| match t.as_slice() {
                    [(_, None)] => Vec::new(),
                    t => t.iter().map(|(i, _)| grid[*i].clone()).collect(),
                })
                .collect(),
        }
    }

    /// The lines' view of FRF derivatives `d[f][i] = dG(f)/dθ_i` on the grid: per line and
    /// parameter (the kernel is linear in the response).
    pub fn seen_derivatives(&self, d: &[Vec<CMatrix>]) -> Vec<Vec<CMatrix>> {
        let params = d.first().map_or(0, |v| v.len());
        let columns: Vec<Vec<CMatrix>> = (0..params)
            .map(|i| d.iter().map(|df| df[i].clone()).collect())
            .collect();
        (0..self.taps.len())
            .map(|k| columns.iter().map(|c| self.line(k, c)).collect())
            .collect()
    }
}

/// A non-parametric FRF over the excited lines.
#[derive(Debug, Clone)]
pub struct FrfEstimate {
    /// The estimator used.
    pub estimator: Estimator,
    /// Input names (columns of G).
    pub inputs: Vec<String>,
    /// Output names (rows of G).
    pub outputs: Vec<String>,
    /// Sample rate in Hz (for the sample-and-hold factor of models).
    pub sample_rate_hz: f64,
    /// One entry per excited line, ascending in frequency.
    pub lines: Vec<FrfLine>,
    /// Complex degrees of freedom of the pooled noise covariance.
    pub noise_dof: usize,
    /// Segmentation of a Welch estimate (non-periodic logs).
    pub welch: Option<super::welch::WelchLayout>,
    /// Period found in the logged excitation of records without period metadata.
    pub detected_period: Option<usize>,
    /// The test for nonlinear distortion at the lines a periodic excitation leaves out;
    /// `None` for Welch estimates and where no line is left out.
    pub distortion: Option<Distortion>,
}

impl FrfEstimate {
    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.outputs.len()
    }
    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.inputs.len()
    }
    /// The estimator, and for a Welch estimate its segmentation, in words.
    pub fn describe(&self) -> String {
        match &self.welch {
            Some(w) => format!(
                "{}, Hann segments of {} samples ({:.3} Hz resolution), 50% overlap, {} segments",
                self.estimator.describe(),
                w.segment,
                w.resolution_hz,
                w.segments
            ),
            None => match self.detected_period {
                Some(p) => format!(
                    "{}, period detected from the excitation: {p} samples",
                    self.estimator.describe()
                ),
                None => self.estimator.describe().to_string(),
            },
        }
    }
    /// Line frequencies in Hz.
    pub fn freqs_hz(&self) -> Vec<f64> {
        self.lines.iter().map(|l| l.freq_hz).collect()
    }
}

/// Spectra of one experiment's period mean at the excited bins: per bin, one per channel.
struct ExperimentSpectra {
    u: Vec<Vec<C64>>,
    y: Vec<Vec<C64>>,
    r: Option<Vec<Vec<C64>>>,
}

/// Estimates the FRF from periodic experiments (all with the same period).
pub fn periodic_frf(data: &Dataset, choice: EstimatorChoice) -> Result<FrfEstimate> {
    data.validate()?;
    let (layouts, detected_period) = data.periodic_layouts().ok_or_else(|| {
        let e = data
            .experiments
            .iter()
            .find(|e| e.periodic.is_none())
            .map_or("an experiment", |e| e.name.as_str());
        SimError::invalid(
            format!("period_samples of {e}"),
            "absent",
            "periodic FRF needs every experiment to be periodic (experiment metadata period_samples, periods, or a logged excitation that repeats with the period of the others)",
        )
    })?;
    let n = layouts[0].period;
    if let Some((e, l)) = data
        .experiments
        .iter()
        .zip(&layouts)
        .find(|(_, l)| l.period != n)
    {
        return Err(SimError::invalid(
            format!("period_samples of {}", e.name),
            l.period,
            format!("all experiments must share one period; the first has {n}"),
        ));
    }
    let use_iv = uses_instrumental_variable(data, choice)?;
    let nu = data.inputs.len();
    let ny = data.outputs.len();
    let ne = data.experiments.len();
    if ne < nu {
        return Err(SimError::invalid(
            "number of periodic experiments",
            ne,
            format!(
                "a multi-experiment FRF of {nu} inputs needs at least {nu} experiments: at each line one periodic record gives one input direction, so give one record per input (each exciting another input, or the same lines with other phases), or records whose excitation is not periodic (Welch)"
            ),
        ));
    }
    let dft = Dft::new(n);
    let half = n.div_ceil(2); // bins 1..half are below Nyquist

    // Excited lines from the period-averaged excitation (or input) spectrum.
    let mut power = vec![0.0; half];
    for (e, l) in data.experiments.iter().zip(&layouts) {
        let src = if use_iv {
            e.r.as_ref().unwrap_or(&e.u)
        } else {
            &e.u
        };
        for c in 0..nu {
            let mean = period_mean(src, c, l.transient, n, l.periods);
            for (k, p) in power.iter_mut().enumerate().skip(1) {
                *p += dft.bin(mean.iter().cloned(), k).norm_sqr();
            }
        }
    }
    let bins = excited_bins(&power);
    let distortion = super::distortion::test(data, &layouts, &power, &bins);
    if bins.is_empty() {
        return Err(SimError::invalid(
            "excitation",
            "no excited line",
            format!("no frequency line below Nyquist carries excitation power in periods of {n} samples"),
        ));
    }

    // Per experiment and line, the noise around the line with the record's transient taken
    // out (see [`super::transient`]).
    let local: Vec<(Vec<LocalNoise>, Vec<LocalNoise>)> = data
        .experiments
        .iter()
        .zip(&layouts)
        .map(|(e, l)| (local_noise(&e.u, l, &bins), local_noise(&e.y, l, &bins)))
        .collect();
    let spectra: Vec<ExperimentSpectra> = data
        .experiments
        .iter()
        .zip(&layouts)
        .zip(&local)
        .map(|((e, l), (lu, ly))| {
            // The transform of the period mean is the mean of the periods' transforms; the
            // transient's estimate is taken out of the inputs and outputs (a logged
            // excitation repeats exactly and has none).
            let block = |m: &DMatrix<f64>, out: Option<&[LocalNoise]>| -> Vec<Vec<C64>> {
                let means: Vec<Vec<f64>> = (0..m.ncols())
                    .map(|c| period_mean(m, c, l.transient, n, l.periods))
                    .collect();
                bins.iter()
                    .enumerate()
                    .map(|(bi, &k)| {
                        means
                            .iter()
                            .enumerate()
                            .map(|(c, x)| {
                                dft.bin(x.iter().copied(), k)
                                    - out.map_or(C64::new(0.0, 0.0), |o| o[bi].transient[c])
                            })
                            .collect()
                    })
                    .collect()
            };
            ExperimentSpectra {
                u: block(&e.u, Some(lu)),
                y: block(&e.y, Some(ly)),
                r: if use_iv {
                    e.r.as_ref().map(|r| block(r, None))
                } else {
                    None
                },
            }
        })
        .collect();

    let noise_dof: usize = layouts.iter().map(|l| transient::dof(n, l.periods)).sum();
    let mut lines = Vec::with_capacity(bins.len());
    for (bi, &k) in bins.iter().enumerate() {
        let freq_hz = k as f64 * data.sample_rate_hz / n as f64;
        let mean = |pick: &dyn Fn(&ExperimentSpectra) -> &Vec<C64>, rows: usize| {
            CMatrix::from_fn(rows, ne, |c, e| pick(&spectra[e])[c])
        };
        let u = mean(&|s| &s.u[bi], nu);
        let y = mean(&|s| &s.y[bi], ny);
        let weights = if use_iv {
            let r = mean(&|s| s.r.as_ref().map_or(&s.u[bi], |r| &r[bi]), nu);
            r.adjoint() * invert(&(&u * r.adjoint()), "U R^H", freq_hz)?
        } else {
            u.adjoint() * invert(&(&u * u.adjoint()), "U U^H", freq_hz)?
        };
        let g = &y * &weights;
        let noise_spectra: Vec<(CMatrix, CMatrix)> = local
            .iter()
            .map(|(lu, ly)| (lu[bi].noise.clone(), ly[bi].noise.clone()))
            .collect();
        let s = period_noise(&noise_spectra, &g, noise_dof);
        // The period mean's noise variance per experiment, in units of the per-period S.
        let mean_variance: Vec<f64> = layouts
            .iter()
            .zip(&local)
            .map(|(l, (_, ly))| (1.0 + ly[bi].inflation) / l.periods as f64)
            .collect();
        let m = pooled_weights(&weights, &mean_variance);
        let cov = m.kronecker(&s);
        lines.push(FrfLine {
            freq_hz,
            g,
            cov,
            weights,
            period_noise: s.clone(),
            u_mean: u,
            y_mean: y,
            coherence: None,
            kronecker: Some((m, s)),
            noise_spectra,
            mean_variance,
            kernel: Vec::new(),
            previous: Vec::new(),
        });
    }
    Ok(FrfEstimate {
        estimator: if use_iv {
            Estimator::InstrumentalVariable
        } else {
            Estimator::LeastSquares
        },
        inputs: data.inputs.clone(),
        outputs: data.outputs.clone(),
        sample_rate_hz: data.sample_rate_hz,
        lines,
        noise_dof,
        welch: None,
        detected_period,
        distortion,
    })
}

/// `M` of a periodic line's pooled noise, `Cov(vec Ĝ) = Σ_e (w_e w_e^H v_e) ⊗ S = M ⊗ S`:
/// `weights` (experiments x inputs) and the period mean's noise variance `v_e` per experiment
/// ([`FrfLine::mean_variance`]).
pub(crate) fn pooled_weights(weights: &CMatrix, mean_variance: &[f64]) -> CMatrix {
    let mut m = CMatrix::zeros(weights.ncols(), weights.ncols());
    for (e, &v) in mean_variance.iter().enumerate() {
        let w = weights.row(e).transpose();
        m += &w * w.adjoint() * C64::from(v);
    }
    m
}

/// Whether `choice` resolves to the instrumental-variable estimate on `data` (`Auto` picks it
/// when the excitation is logged); asking for it without a logged excitation is an error.
pub(crate) fn uses_instrumental_variable(data: &Dataset, choice: EstimatorChoice) -> Result<bool> {
    match choice {
        EstimatorChoice::LeastSquares => Ok(false),
        EstimatorChoice::Auto => Ok(data.has_excitation()),
        EstimatorChoice::InstrumentalVariable => {
            if let Some(e) = data.experiments.iter().find(|e| e.r.is_none()) {
                return Err(SimError::invalid(
                    format!("excitation of {}", e.name),
                    "absent",
                    "the instrumental-variable estimate needs the logged excitation topic",
                ));
            }
            Ok(true)
        }
    }
}

/// Refuses data that leave an input unexcited in every experiment, naming it: an input that
/// never moves, or under the instrumental variable an excitation that never does, makes every
/// line's stacking matrix singular, which the estimate could only report as a condition
/// number at its first line.
pub(crate) fn check_excited(data: &Dataset, instrumental: bool) -> Result<()> {
    let files = || {
        let names: Vec<&str> = data.experiments.iter().map(|e| e.name.as_str()).collect();
        match names.len() {
            0..=3 => names.join(", "),
            k => format!("{}, ... ({k} in all)", names[..2].join(", ")),
        }
    };
    for (j, name) in data.inputs.iter().enumerate() {
        if !data.experiments.iter().any(|e| column_moves(&e.u, j)) {
            return Err(SimError::invalid(
                format!("input {name}"),
                "constant in every experiment",
                format!(
                    "nothing excites it ({}), so its responses cannot be estimated; excite it in some experiment, or make it a parameter of the model instead of an input",
                    files()
                ),
            ));
        }
        if instrumental
            && !data
                .experiments
                .iter()
                .any(|e| e.r.as_ref().is_some_and(|r| column_moves(r, j)))
        {
            return Err(SimError::invalid(
                format!("excitation of input {name}"),
                "constant in every experiment",
                format!(
                    "the instrumental-variable estimate needs every input's logged excitation to move in some experiment ({}); excite {name}, or use the least-squares estimate (--estimator ls, estimator=\"ls\" in Python), biased in closed loop",
                    files()
                ),
            ));
        }
    }
    Ok(())
}

/// Pooled per-period noise covariance of `y - G u` at one line from the whole record's bins
/// beside it (one `(U, Y)` per experiment, see [`FrfLine::noise_spectra`]) over `dof` complex
/// degrees of freedom. No period harmonic falls there, so no excitation: at the true `G` this
/// is the noise alone, independent of the means that make the estimate's error. With the
/// estimate itself for `G` it also carries its own error times the input's noise part (in
/// closed loop, feedback of noise).
fn period_noise(spectra: &[(CMatrix, CMatrix)], g: &CMatrix, dof: usize) -> CMatrix {
    let ny = g.nrows();
    let mut s = CMatrix::zeros(ny, ny);
    for (u, y) in spectra {
        let r = y - g * u;
        s += &r * r.adjoint();
    }
    s / C64::from(dof as f64)
}

/// Noise covariance `S` of every line re-estimated from the residual of the model FRF
/// `model` (as the estimate's lines see it, [`LineMap::seen`]): for periodic estimates `y - G u` at the whole record's
/// bins around each line, the transient taken out ([`period_noise`]), for Welch estimates the segment residual projected away
/// from the weights ([`super::welch::model_noise`]). This is what the instrumental-variable
/// cost is weighted with in discovery: at the true model its distribution is the Monte-Carlo
/// reference's.
pub fn model_noise(frf: &FrfEstimate, model: &ModelFrf) -> Result<Vec<CMatrix>> {
    if model.lines.len() != frf.lines.len() {
        return Err(SimError::invalid(
            "model FRF",
            format!("{} lines", model.lines.len()),
            format!("need one per FRF line ({})", frf.lines.len()),
        ));
    }
    if frf.welch.is_some() {
        return super::welch::model_noise(frf, model);
    }
    Ok(frf
        .lines
        .iter()
        .zip(&model.lines)
        .map(|(line, g)| period_noise(&line.noise_spectra, g, frf.noise_dof))
        .collect())
}

/// Inverse of a square stacking matrix, with an error naming the line when it is singular.
pub(crate) fn invert(a: &CMatrix, what: &str, freq_hz: f64) -> Result<CMatrix> {
    let sv = a.singular_values();
    let max = sv.max();
    let min = sv.min();
    if max.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || min < 1e-12 * max {
        return Err(SimError::invalid(
            format!("{what} at {freq_hz:.3} Hz"),
            format!("condition number {:.3e}", max / min.max(f64::MIN_POSITIVE)),
            "the inputs are not independently excited at this line: the experiments' excitations there must span all inputs (each input on lines of its own, or with shared lines a different mix per experiment, e.g. the line sets rotated between experiments, at least one experiment per input)",
        ));
    }
    a.clone().try_inverse().ok_or_else(|| {
        SimError::invalid(
            format!("{what} at {freq_hz:.3} Hz"),
            "singular",
            "cannot invert",
        )
    })
}
