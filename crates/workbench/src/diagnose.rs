//! Where a model fails: per line and per output channel, the weighted misfit against what the
//! noise alone would give (the Monte-Carlo reference), time-domain fit % per channel, and the
//! statistical verdict on the whole cost.
use nalgebra::DMatrix;
use serde::Serialize;

use super::cost::WeightedCost;
use super::frf::{CMatrix, FrfEstimate};
use super::noise::NoiseReference;
use super::stats::chi2_sf;

/// Significance level of every test the workbench makes.
pub const LEVEL: f64 = 0.01;

/// Misfit of one group (a line or a channel) against its noise reference.
#[derive(Debug, Clone, Serialize)]
pub struct GroupMisfit {
    /// Line frequency (Hz) or channel name.
    pub label: String,
    /// Weighted misfit of the group.
    pub misfit: f64,
    /// What noise alone would give on average.
    pub expected: f64,
    /// Probability of a misfit this large from noise alone.
    pub p_value: f64,
    /// Significant after a Bonferroni correction over the groups.
    pub flagged: bool,
}

/// Where the misfit sits.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Per excited line.
    pub lines: Vec<GroupMisfit>,
    /// Per output channel (standardised errors summed over lines and inputs).
    pub outputs: Vec<GroupMisfit>,
    /// The three FRF entries with the largest excess misfit, `(output, input, misfit/expected)`.
    pub worst_entries: Vec<(String, String, f64)>,
    /// Frequency span (Hz) of the flagged lines.
    pub band_hz: Option<(f64, f64)>,
    /// Time-domain fit % per output (periodic steady state on the excited lines).
    pub fit_percent: Vec<(String, f64)>,
    /// Of the worst entries, `(output, input)` where the misfit is at least
    /// [`UNMODELLED_RATIO`] times the noise's and the model's response is zero at every line:
    /// a path the data show and the model lacks (axes a gyroscopic effect couples).
    pub unmodelled_paths: Vec<(String, String)>,
}

/// How many times its noise-alone mean an entry's misfit must be before a path the model
/// lacks is named.
pub const UNMODELLED_RATIO: f64 = 2.0;

impl Diagnosis {
    /// Names of the flagged outputs.
    pub fn flagged_outputs(&self) -> Vec<String> {
        self.outputs
            .iter()
            .filter(|g| g.flagged)
            .map(|g| g.label.clone())
            .collect()
    }
}

/// Tail probability of `x` under a scaled chi-square matched to `mean` and `sd` (moment
/// matching: `x / a ~ chi2(nu)` with `a = sd^2 / (2 mean)`, `nu = 2 mean^2 / sd^2`).
pub fn matched_sf(x: f64, mean: f64, sd: f64) -> f64 {
    if !(mean > 0.0 && sd > 0.0) {
        return if x > mean { 0.0 } else { 1.0 };
    }
    let a = sd * sd / (2.0 * mean);
    let nu = 2.0 * mean * mean / (sd * sd);
    chi2_sf(x / a, nu)
}

/// Diagnoses model FRFs `model` fitted with `free` parameters.
pub fn diagnose(
    frf: &FrfEstimate,
    cost: &WeightedCost,
    noise: &NoiseReference,
    model: &[CMatrix],
    absorbed: f64,
) -> Diagnosis {
    // A fit absorbing `absorbed` residuals' worth of noise (one per free parameter for
    // independent residuals) removes that share of the expected misfit, spread evenly.
    let shrink = 1.0 - absorbed / noise.n_residuals as f64;
    let nl = frf.lines.len();
    let lines: Vec<GroupMisfit> = frf
        .lines
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let misfit = cost.line_cost(k, &model[k]);
            let expected = noise.line_mean[k] * shrink;
            let p_value = matched_sf(misfit, expected, noise.line_sd[k]);
            GroupMisfit {
                label: format!("{:.2} Hz", l.freq_hz),
                misfit,
                expected,
                p_value,
                flagged: p_value < LEVEL / nl as f64,
            }
        })
        .collect();
    let z = cost.standardised(model);
    let total_z = z.iter().fold(
        DMatrix::zeros(frf.ny(), frf.nu()),
        |acc: DMatrix<f64>, m| acc + m,
    );
    let outputs: Vec<GroupMisfit> = frf
        .outputs
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let misfit = total_z.row(i).sum();
            let expected = noise.row_mean[i] * shrink;
            let p_value = matched_sf(misfit, expected, noise.row_sd[i]);
            GroupMisfit {
                label: name.clone(),
                misfit,
                expected,
                p_value,
                flagged: p_value < LEVEL / frf.ny() as f64,
            }
        })
        .collect();
    let mut entries: Vec<(String, String, f64)> = (0..frf.ny())
        .flat_map(|i| (0..frf.nu()).map(move |j| (i, j)))
        .map(|(i, j)| {
            let e = noise.entry_mean[(i, j)].max(1e-300) * shrink;
            (
                frf.outputs[i].clone(),
                frf.inputs[j].clone(),
                total_z[(i, j)] / e,
            )
        })
        .collect();
    entries.sort_by(|a, b| b.2.total_cmp(&a.2));
    entries.truncate(3);
    let flagged: Vec<f64> = frf
        .lines
        .iter()
        .zip(&lines)
        .filter(|(_, g)| g.flagged)
        .map(|(l, _)| l.freq_hz)
        .collect();
    let band_hz = match (flagged.first(), flagged.last()) {
        (Some(a), Some(b)) => Some((*a, *b)),
        _ => None,
    };
    // Zero relative to the model's largest response anywhere (exact zeros in practice: the
    // structure has no path).
    let largest = model
        .iter()
        .flat_map(|g| g.iter().map(|v| v.norm()))
        .fold(0.0, f64::max);
    let unmodelled_paths = entries
        .iter()
        .filter(|(_, _, ratio)| *ratio >= UNMODELLED_RATIO)
        .filter(|(o, i, _)| {
            let (r, c) = (
                frf.outputs.iter().position(|n| n == o).unwrap_or(0),
                frf.inputs.iter().position(|n| n == i).unwrap_or(0),
            );
            model.iter().all(|g| g[(r, c)].norm() <= 1e-12 * largest)
        })
        .map(|(o, i, _)| (o.clone(), i.clone()))
        .collect();
    Diagnosis {
        lines,
        outputs,
        worst_entries: entries,
        band_hz,
        fit_percent: fit_percent(frf, model),
        unmodelled_paths,
    }
}

/// Time-domain fit % per output, `100 (1 - |y - ŷ| / |y - mean y|)`, of the periodic steady
/// state on the excited lines: `ŷ = G Ū` against the period average `Ȳ` of every experiment
/// (Parseval turns the time-domain norms into sums over the lines; the transient is discarded,
/// so no initial condition enters).
pub fn fit_percent(frf: &FrfEstimate, model: &[CMatrix]) -> Vec<(String, f64)> {
    frf.outputs
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let (mut err, mut sig) = (0.0, 0.0);
            for (l, g) in frf.lines.iter().zip(model) {
                let yhat = g * &l.u_mean;
                for e in 0..l.y_mean.ncols() {
                    err += (l.y_mean[(i, e)] - yhat[(i, e)]).norm_sqr();
                    sig += l.y_mean[(i, e)].norm_sqr();
                }
            }
            let fit = if sig > 0.0 {
                100.0 * (1.0 - (err / sig).sqrt())
            } else {
                0.0
            };
            (name.clone(), fit)
        })
        .collect()
}
