//! Which effect is missing: fit every candidate, test the best one for significance, add it
//! if the data demand it, repeat; then say whether what is left is noise.
use std::fmt::Write as _;

use serde::Serialize;

use super::cost::WeightedCost;
use super::diagnose::{diagnose, matched_sf, Diagnosis, LEVEL};
use super::fit::{fit, fit_noise_weighted, FitResult, ParamEstimate};
use super::frf::{CMatrix, Estimator};
use super::model::{Drift, Model};
use super::residual::{residual_tests, ResidualTests, DEFAULT_LAGS};
use super::search::{forward_selection, Search};
use super::stats::{chi2_sf, f_sf};
use super::timedomain::{time_fit, TimeFit, DEFAULT_HORIZON, DEFAULT_WINDOW};
use super::Workbench;
use std::sync::Mutex;

use crate::error::{Result, SimError};

/// Score of one candidate effect at one step.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateScore {
    /// Effect name.
    pub effect: String,
    /// Cost with the effect added and all parameters refitted.
    pub cost: f64,
    /// Cost reduction relative to the step's model, %.
    pub reduction_percent: f64,
    /// Free parameters added (parameters held for lack of information do not count).
    pub added_parameters: usize,
    /// F statistic of the nested-model test (divided by `design_effect`).
    pub f_statistic: f64,
    /// How many times more noise than their count the added parameters absorb
    /// ([`crate::fit::Information::design_effect`]): above 1 where neighbouring Welch lines
    /// correlate, 1 for independent residuals.
    pub design_effect: f64,
    /// Its p-value.
    pub p_value: f64,
    /// p-value of the robustness check: on FRF data the same test without the line that
    /// gained most; on Cubli time-domain data the test with generic probe regressors as
    /// nuisance columns (significance beyond any structured misfit they absorb).
    pub robust_p_value: f64,
    /// Change of AIC = V/s + 2p (s: noise scale of one squared residual).
    pub delta_aic: f64,
    /// Change of BIC = V/s + p ln n.
    pub delta_bic: f64,
    /// Its cost reduction exceeds what noise alone varies the cost by (one standard deviation
    /// of the noise-only cost).
    pub exceeds_noise: bool,
    /// Passes the F test at the Bonferroni-corrected level and its robustness check, and
    /// lowers BIC: every test but the effect size.
    pub passes_tests: bool,
    /// Passes the tests and exceeds the noise.
    pub significant: bool,
    /// Its fit stopped once the linear model of its cost showed it could not become
    /// significant (the time-domain criterion): `cost` is then where it stopped, an upper
    /// bound of the fitted one.
    pub abandoned: bool,
    /// Standard deviation of the cost under noise alone, in cost units.
    pub noise_spread: f64,
    /// Noise variance of one residual in cost units (what [`rivals`] weighs cost gaps by).
    pub scale: f64,
    /// When the loop followed this candidate through a search of its own beside the one
    /// reported (see [`crate::search::forward_selection`]) and did not keep it: what that
    /// search found.
    pub followed: Option<Followed>,
    /// Why its fit failed (a model that cannot be evaluated where the fit went): it has no
    /// cost (`cost` infinite) and is not chosen; the others are tried as if it were not there.
    pub failed: Option<String>,
    /// Why the search did not choose it although it may have been best: an earlier search
    /// added it and later effects made it insignificant ([`crate::search::forward_selection`]'s
    /// backward check).
    pub set_aside: Option<String>,
    /// A built-in effect (a lag, a delay, a bias), not one the model file declares
    /// ([`twins`]).
    pub builtin: bool,
    /// The fitted model's frequency response, what tells one effect under two names where the
    /// criterion's costs do not ([`twins`]).
    #[serde(skip)]
    pub response: Option<Response>,
}

/// A candidate's fitted frequency response on the lines: its residuals under the workbench's
/// FRF weighting, in noise standard deviations, and how far (in noise variances) the effect
/// moved them from its step's model.
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    residuals: nalgebra::DVector<f64>,
    moved: f64,
}

impl Response {
    /// The response of the model FRF `fitted` against the step's `base`, under `cost` with
    /// `scale` its noise variance of one residual.
    pub(crate) fn new(
        cost: &WeightedCost,
        base: &[CMatrix],
        fitted: &[CMatrix],
        scale: f64,
    ) -> Self {
        let unit = scale.sqrt();
        let residuals = cost.residuals(fitted) / unit;
        let moved = (&residuals - cost.residuals(base) / unit).norm_squared();
        Self { residuals, moved }
    }

    /// Whether two effects leave one response: the responses lie closer together than
    /// [`TWIN_SHARE`] of what either effect moved (an effect that moves none, an offset, is
    /// told by its costs alone).
    fn same_as(&self, other: &Self) -> bool {
        let apart = (&self.residuals - &other.residuals).norm_squared();
        self.residuals.len() == other.residuals.len()
            && apart < TWIN_SHARE * self.moved.min(other.moved)
    }
}

/// The search a runner-up led to, against the search kept.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Followed {
    /// The effects it added, the runner-up first.
    pub added: Vec<String>,
    /// Its model's BIC minus the kept model's (the changes of the steps summed).
    pub bic: f64,
    /// It ends with a misfit where the kept search explains the data, or it needed more
    /// effects than the kept search, or as many at a BIC worse by [`decisive_bic`] or more:
    /// the data do choose between the two.
    pub ruled_out: bool,
    /// It ends with a misfit where the kept search explains the data.
    pub unexplained: bool,
}

impl Followed {
    /// The search that added `added` with BIC change `bic`, against the kept one that added
    /// `kept` effects with BIC change `kept_bic` from the same step; `unexplained`: it ends
    /// with a misfit where the kept one explains the data.
    pub(crate) fn against(
        added: Vec<String>,
        bic: f64,
        kept: usize,
        kept_bic: f64,
        unexplained: bool,
    ) -> Self {
        let gap = bic - kept_bic;
        Self {
            ruled_out: unexplained || added.len() > kept || gap >= decisive_bic(),
            added,
            bic: gap,
            unexplained,
        }
    }

    /// Whether its search added exactly `kept`, the effects the kept search added from the
    /// same step, in some order: then both reached one model.
    pub fn same_model(&self, kept: &[&str]) -> bool {
        let mut theirs: Vec<&str> = self.added.iter().map(String::as_str).collect();
        let mut kept = kept.to_vec();
        theirs.sort_unstable();
        kept.sort_unstable();
        theirs == kept
    }
}

/// The costs a nested-model test compares: a model and the model with one candidate more,
/// in one criterion's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NestedCosts {
    /// Cost without the candidate.
    pub before: f64,
    /// Cost with it, every parameter refitted.
    pub after: f64,
    /// Residuals in the cost.
    pub residuals: f64,
    /// Free parameters without the candidate.
    pub free_before: usize,
    /// Free parameters with it.
    pub free_after: usize,
    /// Noise variance of one residual in cost units (for AIC and BIC).
    pub scale: f64,
    /// Standard deviation of the cost under noise alone, in cost units.
    pub noise_sd: f64,
    /// How many times more noise than their count the added parameters absorb (1 for
    /// independent residuals); the F statistics are divided by it.
    pub design_effect: f64,
}

impl NestedCosts {
    /// The F statistic of the nested models and its p-value (`(0, 1)` when nothing is added
    /// or nothing is left).
    pub fn f_test(&self) -> (f64, f64) {
        let q = self.free_after.saturating_sub(self.free_before);
        let dof = self.residuals - self.free_after as f64;
        if q > 0 && self.after > 0.0 && dof > 0.0 {
            let f =
                ((self.before - self.after) / q as f64) / (self.after / dof) / self.design_effect;
            (f, f_sf(f, q as f64, dof))
        } else {
            (0.0, 1.0)
        }
    }
}

/// The robustness check of a nested-model test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Robustness<'a> {
    /// The same test without the block of residuals that gained most (a frequency line, a
    /// stretch of data): per-block costs without and with the candidate. The evidence must
    /// not rest on one block, which can be off for reasons no candidate describes.
    WithoutBestBlock(&'a [f64], &'a [f64]),
    /// A p-value the criterion computed itself (the Cubli's test with probe regressors).
    PValue(f64),
}

impl CandidateScore {
    /// Scores a candidate by the nested-model test every criterion shares: the F test, its
    /// robustness check and BIC at the level Bonferroni-corrected over `n_candidates`, and an
    /// effect-size rule. The F test is exact only for a model class that contains the truth;
    /// with thousands of residuals it also finds a mismatch of the class far below the noise,
    /// so an effect is claimed only when it also changes the cost by more than noise alone
    /// varies it.
    pub fn nested(
        effect: &str,
        c: &NestedCosts,
        robustness: Robustness<'_>,
        n_candidates: usize,
        abandoned: bool,
    ) -> Self {
        let n = c.residuals;
        let (p1, q) = (c.free_after, c.free_after.saturating_sub(c.free_before));
        let dv = c.before - c.after;
        let (f_statistic, p_value) = c.f_test();
        let robust_p_value = match robustness {
            Robustness::PValue(p) => p,
            Robustness::WithoutBestBlock(before, after) if q > 0 && before.len() > 1 => {
                let (k, gain) = before
                    .iter()
                    .zip(after)
                    .map(|(b, a)| b - a)
                    .enumerate()
                    .fold(
                        (0, f64::NEG_INFINITY),
                        |acc, (k, d)| if d > acc.1 { (k, d) } else { acc },
                    );
                let n_block = n / before.len() as f64;
                let rest = c.after - after[k];
                let dof = n - n_block - p1 as f64;
                f_sf(
                    ((dv - gain) / q as f64) / (rest / dof) / c.design_effect,
                    q as f64,
                    dof,
                )
            }
            Robustness::WithoutBestBlock(..) => 1.0,
        };
        let delta_aic = -dv / c.scale + 2.0 * q as f64;
        let delta_bic = -dv / c.scale + q as f64 * n.ln();
        let alpha = LEVEL / n_candidates.max(1) as f64;
        let exceeds_noise = dv > c.noise_sd;
        let passes_tests = q > 0 && p_value < alpha && robust_p_value < alpha && delta_bic < 0.0;
        Self {
            effect: effect.to_string(),
            cost: c.after,
            reduction_percent: 100.0 * dv / c.before,
            added_parameters: q,
            f_statistic,
            design_effect: c.design_effect,
            p_value,
            robust_p_value,
            delta_aic,
            delta_bic,
            exceeds_noise,
            passes_tests,
            significant: passes_tests && exceeds_noise,
            abandoned,
            noise_spread: c.noise_sd,
            scale: c.scale,
            followed: None,
            failed: None,
            set_aside: None,
            builtin: false,
            response: None,
        }
    }

    /// A candidate whose fit failed with `why`.
    pub fn failed(effect: &str, why: String) -> Self {
        Self {
            effect: effect.to_string(),
            cost: f64::INFINITY,
            reduction_percent: f64::NAN,
            added_parameters: 0,
            f_statistic: f64::NAN,
            design_effect: 1.0,
            p_value: 1.0,
            robust_p_value: 1.0,
            delta_aic: f64::INFINITY,
            delta_bic: f64::INFINITY,
            exceeds_noise: false,
            passes_tests: false,
            significant: false,
            abandoned: false,
            noise_spread: f64::NAN,
            scale: f64::NAN,
            followed: None,
            failed: Some(why),
            set_aside: None,
            builtin: false,
            response: None,
        }
    }

    /// The cost it removed from its step's model (from `reduction_percent`).
    fn cost_reduction(&self) -> f64 {
        let before = self.cost / (1.0 - self.reduction_percent / 100.0);
        before - self.cost
    }
}

/// The probability that noise makes a cost gap `gap` between two models (see [`rivals`]);
/// `scale` is one residual's noise variance in cost units.
fn rival_p_value(gap: f64, scale: f64) -> f64 {
    if gap <= 0.0 {
        1.0
    } else {
        chi2_sf(gap / (4.0 * scale), 1.0)
    }
}

/// A BIC gap that settles a choice between two models: the better is `1 / LEVEL` times as
/// probable (2 ln 100 = 9.2 at the tests' level).
pub(crate) fn decisive_bic() -> f64 {
    2.0 * (1.0 / LEVEL).ln()
}

/// Whether `other` fits the data of a step as well as the `chosen` candidate: its cost
/// reduction also exceeds the noise, and the gap between the two costs is one noise could
/// make. Two models whose whitened predictions differ by an energy `D` have costs `D` apart
/// when one of them is right, and noise moves that gap by `2 sqrt(D)` (in units of one
/// residual's noise variance), so a gap `dV` is told from zero at z = `sqrt(dV) / 2`: the two
/// are rivals when `chi2_sf(dV / 4, 1)` is at least the tests' level.
pub(crate) fn is_rival(chosen: &CandidateScore, other: &CandidateScore) -> bool {
    other.effect != chosen.effect
        && other.exceeds_noise
        && other.set_aside.is_none()
        && !twins(chosen, other)
        && rival_p_value(other.cost - chosen.cost, chosen.scale) >= LEVEL
}

/// Cost difference, in noise variances of one residual, within which two candidates with as
/// many parameters are one model under two names: ten times the FRF fit's own tolerance, and
/// a 2600th of the gap a test at 1 % can resolve.
pub const TWIN_GAP: f64 = 0.01;

/// Share of an effect's move of the frequency response within which another effect's fit
/// leaves the same response ([`Response::same_as`]).
pub const TWIN_SHARE: f64 = 0.01;

/// Whether `a` and `b` are one effect under the file's name and a built-in one: one of each,
/// as many parameters, and costs within [`TWIN_GAP`], or costs noise could set apart
/// ([`rival_p_value`]) and one frequency response ([`Response::same_as`]). A model file's own
/// first-order lag on an input is the built-in `actuator_lag`; a hopper's gimbal lag fitted
/// to 255.61360 against the built-in's 255.61393, and the discovery called it tentative, "the
/// data do not tell them apart". A built-in effect is a form, not a cause, so the file's name
/// is the reading. Two effects of the file that are one term (a motor's back-EMF and a
/// viscous friction) stay rivals: the data cannot tell which cause it is. The time criterion
/// stops its fits within half a noise variance, and its predictor carries a file's lag state
/// in its noise model where the built-in lag filters the input: a ball-and-beam's motor lag
/// fitted to the built-in's time constant 1.4 noise variances above it, and was left
/// tentative. Their responses told them for one.
pub(crate) fn twins(a: &CandidateScore, b: &CandidateScore) -> bool {
    let gap = (a.cost - b.cost).abs();
    let one_response = match (&a.response, &b.response) {
        (Some(x), Some(y)) => x.same_as(y) && rival_p_value(gap, a.scale) >= LEVEL,
        _ => false,
    };
    a.builtin != b.builtin
        && a.added_parameters == b.added_parameters
        && (gap <= TWIN_GAP * a.scale || one_response)
}

/// Whether the loop follows `other` through a search of its own besides the `chosen` one
/// ([`crate::search::forward_selection`]): it is significant, and a rival or within a tenth
/// of the chosen one's cost reduction. Two candidates that remove nearly the same misfit may
/// part only once a later effect is in (a lag 58 behind a delay on a reduction of 9042, which
/// explained the data with friction where the delay did not).
pub(crate) fn worth_following(chosen: &CandidateScore, other: &CandidateScore) -> bool {
    other.effect != chosen.effect
        && other.significant
        && !twins(chosen, other)
        && (is_rival(chosen, other) || other.cost - chosen.cost <= 0.1 * chosen.cost_reduction())
}

/// An added effect that another candidate of its step fits as well ([`rivals`]): why, and
/// which of the kept model's effects the choice between them leaves unconfirmed.
#[derive(Debug, Clone, PartialEq)]
pub struct Rivalry {
    /// The sentence naming the rivals and their cost gaps.
    pub why: String,
    /// The added effect, and each later one that some rival's own search did not add as well
    /// (every later one when a rival was not followed): what was added after a coin toss holds
    /// only if the other side of it adds it too. Effects added before stay confirmed.
    pub tentative: Vec<String>,
}

/// One [`Rivalry`] per added effect that another candidate of its step fits as well
/// ([`is_rival`]) and that the loop did not rule out by following it through a search of its
/// own ([`Followed::ruled_out`]). The loop's pick between rivals is then a
/// coin toss (a lag of a tenth of a sample and a delay of the same length, two names for one
/// term). `steps` are each step's added effect and the candidates tried on it, the start
/// first.
pub fn rivals<'a>(
    steps: impl IntoIterator<Item = (Option<&'a str>, &'a [CandidateScore])>,
) -> Vec<Rivalry> {
    let steps: Vec<_> = steps.into_iter().collect();
    steps
        .windows(2)
        .enumerate()
        .filter_map(|(i, pair)| {
            let added = pair[1].0?;
            let tried = pair[0].1;
            let chosen = tried.iter().find(|c| c.effect == added)?;
            // A runner-up whose own search reached the kept model in another order is no
            // rival.
            let kept: Vec<&str> = steps[i + 1..].iter().filter_map(|s| s.0).collect();
            let equal: Vec<&CandidateScore> = tried
                .iter()
                .filter(|c| {
                    is_rival(chosen, c)
                        && c.followed
                            .as_ref()
                            .is_none_or(|f| !f.ruled_out && !f.same_model(&kept))
                })
                .collect();
            (!equal.is_empty()).then(|| {
                // A later effect every rival's own search added too holds whichever was picked.
                let tentative = kept
                    .iter()
                    .enumerate()
                    .filter(|&(k, later)| {
                        k == 0
                            || equal.iter().any(|c| {
                                c.followed
                                    .as_ref()
                                    .is_none_or(|f| !f.added.iter().any(|a| a == later))
                            })
                    })
                    .map(|(_, e)| e.to_string())
                    .collect();
                let names: Vec<String> = equal.iter().map(|c| c.effect.clone()).collect();
                let gaps: Vec<String> = equal
                    .iter()
                    .map(|c| {
                        let gap = c.cost - chosen.cost;
                        let followed = c.followed.as_ref().map_or(String::new(), |f| {
                            format!(
                                "; its own search added [{}], BIC {:+.1} against this model",
                                f.added.join(", "),
                                f.bic
                            )
                        });
                        format!(
                            "{gap:+.1}, a gap noise makes with p = {:.2}{followed}",
                            rival_p_value(gap, chosen.scale)
                        )
                    })
                    .collect();
                let why = match names.as_slice() {
                    [one] => format!(
                        "{one} fits these data as well as {added} (cost {}): the data do not \
                         tell them apart",
                        gaps[0],
                    ),
                    [rest @ .., last] => format!(
                        "{} and {last} each fit these data as well as {added} (cost {}): the \
                         data do not tell them apart",
                        rest.join(", "),
                        names
                            .iter()
                            .zip(&gaps)
                            .map(|(n, g)| format!("{n} {g}"))
                            .collect::<Vec<_>>()
                            .join("; "),
                    ),
                    [] => String::new(),
                };
                Rivalry { why, tentative }
            })
        })
        .collect()
}

/// One step of the discovery: a model, its fit and diagnosis, and the candidates tried on it.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// Effect added at this step (`None` for the starting model).
    pub added: Option<String>,
    /// Effects in the model.
    pub effects: Vec<String>,
    /// Weighted cost.
    pub cost: f64,
    /// Cost reduction relative to the starting model, %.
    pub reduction_percent: f64,
    /// Cost divided by what noise alone would give after this fit.
    pub normalized_cost: f64,
    /// Residuals' worth of noise the fit absorbs ([`crate::fit::Information::absorbed`]):
    /// what the expected cost under noise alone is lowered by.
    pub absorbed_noise: f64,
    /// Parameters with standard errors.
    pub params: Vec<ParamEstimate>,
    /// Where the misfit sits.
    pub diagnosis: Diagnosis,
    /// Time-domain fit % (simulation and k-step prediction) with its policy.
    pub time_fit: TimeFit,
    /// Whiteness and input correlation of the simulation residual.
    pub residual_tests: ResidualTests,
    /// Candidates scored on this step's model (empty on the last step if at the noise level).
    pub candidates: Vec<CandidateScore>,
    /// Parameter vector (model order).
    #[serde(skip)]
    pub theta: Vec<f64>,
    /// Model FRF on the lines, as the estimate sees it (a Welch line through its kernel).
    #[serde(skip)]
    pub model_frf: Vec<super::frf::CMatrix>,
}

/// A fitted model of the discovery loop before its record is built.
#[derive(Clone)]
struct Fitted {
    model: Model,
    added: Option<String>,
    r: FitResult,
    /// Its own weighting when the noise is re-estimated from the model's residual; `None`:
    /// the workbench's.
    weighting: Option<WeightedCost>,
    candidates: Vec<CandidateScore>,
}

/// Final verdict on the data.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Verdict {
    /// The remaining cost is what noise alone gives.
    ExplainedToNoiseLevel {
        /// Probability of a cost this large from noise alone.
        p_value: f64,
    },
    /// A significant structured misfit remains that no candidate explains.
    UnexplainedStructuredMisfit {
        /// Probability of a cost this large from noise alone.
        p_value: f64,
        /// Output channels carrying it.
        outputs: Vec<String>,
        /// Frequency band (Hz) carrying it.
        band_hz: Option<(f64, f64)>,
        /// Largest FRF entries, `(output, input, misfit / expected)`.
        worst_entries: Vec<(String, String, f64)>,
    },
}

/// Whether a result put candidate effects to the test, for the closing words of a misfit
/// verdict: only a discovery that tried them may say that none explains the misfit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Candidates {
    /// The discovery loop scored the model's candidates.
    Tried,
    /// The model has candidates but this result (`compare`, `fit`) tested none.
    Untried,
    /// The model declares no candidate effects.
    Absent,
}

impl Candidates {
    /// What a result on `model` that `tried` its candidates (or not) may say of them.
    pub fn of(model: &Model, tried: bool) -> Self {
        match (model.candidates().is_empty(), tried) {
            (true, _) => Self::Absent,
            (false, true) => Self::Tried,
            (false, false) => Self::Untried,
        }
    }
}

impl Verdict {
    /// A sentence for the summary, after a discovery that tried the candidates.
    pub fn sentence(&self) -> String {
        self.sentence_given(Candidates::Tried)
    }

    /// A sentence for the summary; a misfit's closing words say what `candidates` allows.
    pub fn sentence_given(&self, candidates: Candidates) -> String {
        self.sentence_of(candidates, COST_TEST)
    }

    /// [`Verdict::sentence_given`] for a verdict whose p-value is that of `test` (what it
    /// tested, as "for ...").
    fn sentence_of(&self, candidates: Candidates, test: &str) -> String {
        match self {
            Self::ExplainedToNoiseLevel { p_value } => {
                format!(
                    "explained to the noise level ({} {test})",
                    super::stats::p_equals(*p_value)
                )
            }
            Self::UnexplainedStructuredMisfit {
                p_value,
                outputs,
                band_hz,
                worst_entries,
            } => {
                // The FRF criteria name the band of flagged lines and the worst FRF entries;
                // the prediction-error criterion the band where the innovations cohere with
                // the excitation and the (output, excitation) pairs of most coherence.
                let entries: Vec<String> = worst_entries
                    .iter()
                    .map(|(o, i, r)| format!("{i}->{o} ({r:.1}x)"))
                    .collect();
                // One bin is a frequency, not a band ("4.69-4.69 Hz").
                let band = |a: &f64, b: &f64| {
                    if format!("{a:.2}") == format!("{b:.2}") {
                        format!("{a:.2} Hz")
                    } else {
                        format!("{a:.2}-{b:.2} Hz")
                    }
                };
                let place = match (band_hz, entries.is_empty()) {
                    (Some((a, b)), true) => format!(", {}", band(a, b)),
                    (Some((a, b)), false) => {
                        format!(", {}; largest in {}", band(a, b), entries.join(", "))
                    }
                    (None, false) => {
                        format!(", spread over the band; largest in {}", entries.join(", "))
                    }
                    (None, true) => String::new(),
                };
                let closing = match candidates {
                    Candidates::Tried => "no candidate effect explains it",
                    Candidates::Untried => {
                        "no candidate effect was tried (compare and fit test none: discover tries them)"
                    }
                    Candidates::Absent => "the model has no candidate effects to try",
                };
                let which = if outputs.is_empty() {
                    "in the outputs together (none alone is flagged)".to_string()
                } else {
                    format!("in outputs [{}]", outputs.join(", "))
                };
                format!(
                    "unexplained structured misfit ({}) {which}{place}; {closing}",
                    super::stats::p_scientific(*p_value)
                )
            }
        }
    }
}

/// Why added effects are tentative when the final model leaves a structured misfit.
pub const MISFIT_CAVEAT: &str =
    "the final model leaves a structured misfit, which the tests that added them took for noise";

/// What a discovery concluded, whatever its criterion (FRF, prediction error, the Cubli's
/// window regression): held once by each result and written once by every report.
#[derive(Debug, Clone, Serialize)]
pub struct Conclusion {
    /// Effects in the order added, when nothing speaks against them.
    pub found: Vec<String>,
    /// Effects the loop added that are not confirmed: they lower the cost, but the tests that
    /// accepted them take the rest for noise, which a caveat refutes (they may be absorbing
    /// a bias or a remaining misfit).
    pub tentative: Vec<String>,
    /// Why the added effects are tentative, one sentence per reason (empty when found).
    pub caveats: Vec<String>,
    /// A structured misfit remains.
    pub unexplained: bool,
    /// The verdict on the final model.
    pub verdict: Verdict,
    /// Significance level of the tests.
    pub level: f64,
    /// Whether the candidates were tried ([`Conclusion::settle`] assumes so).
    pub candidates: Candidates,
    /// Candidates on the final model that pass the nested-model tests but lower the cost by
    /// less than noise alone varies it, one sentence each ([`Conclusion::with_near_misses`]):
    /// with a misfit left, they are what to try first.
    pub near_misses: Vec<String>,
    /// Candidates that, each fitted alone on the final model, leave the misfit's tests
    /// passing though the selection left them out, each with its new parameters (the time
    /// criterion's; see [`super::prediction`]).
    pub explain_alone: Vec<String>,
    /// What qualifies the verdict itself, whatever was added: the estimate it rests on is
    /// biased under feedback, indistinguishable from zero, or distorted
    /// ([`Conclusion::with_warnings`]). The verdict's sentence ends with those the tentative
    /// effects' reasons do not already give.
    pub warnings: Vec<String>,
    /// What the verdict's p-value tested, as "for ..." ([`Conclusion::with_test`]).
    #[serde(skip)]
    pub test: &'static str,
}

/// A sentence per effect of `model` whose every fitted parameter is held at its documented
/// value ([`ParamEstimate::held`]): the data show the effect but cannot size it apart from the
/// rest, and the other values are then scaled to that documented size. (A cart-pole whose
/// masses, length, motor constant and back-EMF all scale together read "found: cart_coulomb,
/// explained" with the friction held at 0.3 N for 0.4 and the cart's mass 37 % low, the
/// verdict silent about it.)
pub(crate) fn unmeasured_effects(model: &Model, params: &[ParamEstimate]) -> Result<Vec<String>> {
    let mut why = Vec::new();
    for effect in model.enabled() {
        let names = model.effect_parameters(&effect)?;
        // Its own parameters that were fitted or held (not fixed in the model).
        let own: Vec<&ParamEstimate> = params
            .iter()
            .filter(|p| names.contains(&p.name) && (p.held || p.std.is_some()))
            .collect();
        if !own.is_empty() && own.iter().all(|p| p.held) {
            let names: Vec<&str> = own.iter().map(|p| p.name.as_str()).collect();
            why.push(format!(
                "the size of {effect} is not measured: {} held at the documented value (the data cannot separate it from the other parameters), and the other values hold only given it; fix or measure one of the parameters it trades against",
                names.join(", ")
            ));
        }
    }
    Ok(why)
}

/// How many times its documented value (either way) a fitted parameter may lie before the
/// verdict says so ([`far_from_documented`]): an order of magnitude.
pub const FAR_FROM_DOCUMENTED: f64 = 10.0;

/// Standard errors from its documented value within which a fitted parameter is not far
/// from it, whatever the ratio ([`far_from_documented`]).
pub const FAR_ERRORS: f64 = 3.0;

/// A sentence naming the fitted parameters of `model` that lie more than
/// [`FAR_FROM_DOCUMENTED`] times from their documented values (or changed sign), `None` when
/// none does. A fit that explains the data with such values is bent by something the model
/// lacks or misstates: under the FRF criterion a Furuta pendulum's dry friction, linearized at
/// rest, read "explained" with the arm inertia 16 times and the motor constant 13 times their
/// documented values, and nothing said so.
pub fn far_from_documented(model: &Model, params: &[ParamEstimate]) -> Result<Option<String>> {
    let documented = model.parameters()?;
    // A poorly determined parameter wanders along a ridge of the cost (a quadrotor's yaw
    // inertia and rotor drag, of which the data see the ratio): far is no sign of a bend.
    let far: Vec<String> = params
        .iter()
        .filter(|p| !p.held && !p.poorly_determined)
        .filter_map(|p| {
            let doc = documented.iter().find(|d| d.name == p.name)?.value;
            let ratio = p.value / doc;
            // Nor is a value the documented one is within a few errors of (a small
            // coefficient of the other sign, 1.5 errors from it, read as bent).
            let apart = p.std.is_none_or(|s| (p.value - doc).abs() > FAR_ERRORS * s);
            (doc != 0.0
                && apart
                && p.value != 0.0
                && !(1.0 / FAR_FROM_DOCUMENTED..=FAR_FROM_DOCUMENTED).contains(&ratio))
            .then(|| {
                let sign = if ratio < 0.0 { ", the other sign" } else { "" };
                format!("{} {} times it{sign}", p.name, fmt_ratio(ratio))
            })
        })
        .collect();
    Ok((!far.is_empty()).then(|| {
        format!(
            "parameters fitted far from their documented values ({}): a fit that far from the model's documented values is bent by something the model lacks or misstates (a wrong documented value, a missing effect, or under the FRF criterion a non-smooth effect linearized at the operating point); check them before trusting the verdict",
            far.join(", ")
        )
    }))
}

/// `x` as `1/3.2` below one and `3.2` above.
fn fmt_ratio(x: f64) -> String {
    if x > 0.0 && x < 1.0 {
        format!("1/{:.1}", 1.0 / x)
    } else {
        format!("{x:.1}")
    }
}

/// A rate to four significant digits (1000/60 Hz as 16.67).
fn significant(hz: f64) -> String {
    super::load::hz(format!("{hz:.3e}").parse().unwrap_or(hz))
}

/// Clock factors (the logs' clock against the model's) and the mistake each stands for: a time
/// column in another unit, or a declared sample rate a decade off (1 kHz logs declared as
/// 100 Hz once read as seconds against minutes, the nearest factor then tried).
const CLOCK_UNITS: [(f64, &str); 10] = [
    (60.0, "a time unit of minutes against seconds?"),
    (3600.0, "a time unit of hours against seconds?"),
    (1e-3, "a time unit of milliseconds against seconds?"),
    (1e-6, "a time unit of microseconds against seconds?"),
    (1.0 / 60.0, "a time unit of seconds against minutes?"),
    (1.0 / 3600.0, "a time unit of seconds against hours?"),
    (1e3, "a time unit of seconds against milliseconds?"),
    (1e6, "a time unit of seconds against microseconds?"),
    (0.1, "a sample rate 10 times the declared one?"),
    (10.0, "a sample rate a tenth of the declared one?"),
];

/// Factors a channel logged in another unit or sign makes (the logged value against the
/// model's) and the confusion each stands for.
const CHANNEL_UNITS: [(f64, &str); 9] = [
    (-1.0, "wiring, a motor's direction or an axis convention"),
    (180.0 / std::f64::consts::PI, "degrees against radians"),
    (std::f64::consts::PI / 180.0, "radians against degrees"),
    (30.0 / std::f64::consts::PI, "rpm against rad/s"),
    (std::f64::consts::PI / 30.0, "rad/s against rpm"),
    (1e3, "mm against m, or another milli-unit against its unit"),
    (1e-3, "m against mm, or another unit against its milli-unit"),
    (1e6, "um against m, or another micro-unit against its unit"),
    (1e-6, "m against um, or another unit against its micro-unit"),
];

/// How many times lower than on the logs' own clock and units the documented model's cost
/// must be with a rescaling before [`Workbench::rescaled_sentence`] names it.
const CLOCK_GAIN: f64 = 10.0;

/// How many times the cost of noise alone the documented model's cost may be with a rescaling
/// that [`Workbench::rescaled_sentence`] names: the rescaling must explain the logs, up to
/// documented values a little off, not merely fit them less badly. Rescalings that explain
/// logs measured 0.75 to 20 times it (the double pendulum's angles in degrees 18-20, its
/// documented values a little off the independent simulator's, once the record's transient no
/// longer inflates the noise); logs declared at a sixth of their rate, fitted 36-49 times
/// better on a clock scaled by 1/10, cost 600-770 times it. A unit's factor must also be
/// [`picked`].
const NEAR_NOISE: f64 = 100.0;

/// Whether the logs pick the factor `c` out of its neighbours: `cost` is lowest within
/// [`PICK_WITHIN`] of `c` on a geometric grid over three times either way. A unit the logs are
/// in is picked to the grid's step (the double pendulum's angles in degrees: 57.3 exactly, on
/// 3 seeds), while a rescaling that merely fits less badly than none has its own optimum
/// elsewhere (a pendulum's documented values 8 and 10 times off: 1.60 times 57.3, at 87 times
/// the noise; logs declared at a sixth of their rate: 1.69 times the clock's tenth).
fn picked(c: f64, cost: impl Fn(f64) -> f64) -> bool {
    const STEPS: i32 = 40;
    (-STEPS..=STEPS)
        .map(|k| c * 3f64.powf(f64::from(k) / f64::from(STEPS)))
        .map(|x| (cost(x), x))
        .filter(|(v, _)| v.is_finite())
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .is_some_and(|(_, x)| (x / c).ln().abs() <= PICK_WITHIN.ln())
}

/// How near the factor of a unit the logs' own best factor must lie for [`picked`].
const PICK_WITHIN: f64 = 1.1;

/// A rescaling of the logs that the documented model fits better: its cost and the sentence.
type Rescaled = (f64, String);

/// Channels rescaled together: their name, the outputs and the inputs.
type ChannelGroup = (String, Vec<usize>, Vec<usize>);

impl Workbench {
    /// The clock rescaling under which the documented model fits the logs best, among
    /// [`CLOCK_UNITS`]. A reactor logged in minutes against a model in seconds fitted every
    /// rate about 60 times its documented value and found an input delay; only the
    /// parameters' distance hinted at it. `theta` the documented values, `own` their cost on
    /// the logs' clock.
    fn clock_rescaled(&self, theta: &[f64], own: f64) -> Option<Rescaled> {
        let hold = self.fit_options().hold;
        let fs = self.data().sample_rate_hz;
        let cost = |c: f64| -> Option<f64> {
            let map = &self.cost.map;
            let freqs: Vec<f64> = map.grid_hz().iter().map(|f| f / c).collect();
            let g = self.model.frf(theta, &freqs, hold.map(|h| h * c)).ok()?;
            let v = self.cost.cost(&map.seen(&g).lines);
            v.is_finite().then_some(v)
        };
        let (v, c, what) = CLOCK_UNITS
            .iter()
            .filter_map(|&(c, what)| Some((cost(c)?, c, what)))
            .min_by(|a, b| a.0.total_cmp(&b.0))?;
        if !picked(c, |x| cost(x).unwrap_or(f64::INFINITY)) {
            return None;
        }
        Some((
            v,
            format!(
                "{} with their clock scaled by {}, as if sampled at {} Hz rather than {} Hz: {what}",
                self.better(v, own),
                fmt_ratio(c),
                significant(fs / c),
                significant(fs)
            ),
        ))
    }

    /// The channel rescaling under which the documented model fits the logs best: one
    /// output's row of its response (or every output's, or those that each fit better under
    /// one factor), or one input's column (likewise), scaled by one of [`CHANNEL_UNITS`]. A
    /// pitch axis's rate logged in deg/s against a model in rad/s fitted M_alpha at 1.4e5 for
    /// 3.6 and only the parameters' distance hinted at it. `grid` the documented model's
    /// response where the cost evaluates it ([`WeightedCost::map`]), `own` its cost.
    fn unit_rescaled(&self, grid: &[CMatrix], own: f64) -> Option<Rescaled> {
        let data = self.data();
        let (ny, nu) = (data.outputs.len(), data.inputs.len());
        // (channels named, outputs scaled, inputs scaled): each channel alone, then each side.
        let mut groups: Vec<ChannelGroup> = Vec::new();
        for (i, name) in data.outputs.iter().enumerate() {
            groups.push((format!("output {name}"), vec![i], Vec::new()));
        }
        for (j, name) in data.inputs.iter().enumerate() {
            groups.push((format!("input {name}"), Vec::new(), vec![j]));
        }
        if ny > 1 {
            let all = data.outputs.join(", ");
            groups.push((format!("outputs {all}"), (0..ny).collect(), Vec::new()));
        }
        if nu > 1 {
            let all = data.inputs.join(", ");
            groups.push((format!("inputs {all}"), Vec::new(), (0..nu).collect()));
        }
        // A logged output is c times the model's; a logged input c times the model's, so the
        // response per logged input is 1/c times.
        let cost = |rows: &[usize], cols: &[usize], c: f64| -> f64 {
            let scaled: Vec<_> = grid
                .iter()
                .map(|m| {
                    let mut m = m.clone();
                    for &i in rows {
                        m.row_mut(i).scale_mut(c);
                    }
                    for &j in cols {
                        m.column_mut(j).unscale_mut(c);
                    }
                    m
                })
                .collect();
            self.cost.cost(&self.cost.map.seen(&scaled).lines)
        };
        // The channels of one side that each fit better scaled by one factor, scaled together:
        // three gyros of six outputs logged in deg/s, which neither one channel nor the whole
        // side explains.
        let names = |side: &[String], idx: &[usize]| -> String {
            idx.iter()
                .map(|&i| side[i].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        for &(c, _) in &CHANNEL_UNITS {
            let rows: Vec<usize> = (0..ny).filter(|&i| cost(&[i], &[], c) < own).collect();
            if rows.len() > 1 && rows.len() < ny {
                let label = format!("outputs {}", names(&data.outputs, &rows));
                groups.push((label, rows, Vec::new()));
            }
            let cols: Vec<usize> = (0..nu).filter(|&j| cost(&[], &[j], c) < own).collect();
            if cols.len() > 1 && cols.len() < nu {
                let label = format!("inputs {}", names(&data.inputs, &cols));
                groups.push((label, Vec::new(), cols));
            }
        }
        let mut best: Option<(f64, f64, &str, &ChannelGroup)> = None;
        for group in &groups {
            for &(c, what) in &CHANNEL_UNITS {
                let v = cost(&group.1, &group.2, c);
                if v.is_finite() && best.is_none_or(|b| v < b.0) {
                    best = Some((v, c, what, group));
                }
            }
        }
        let (v, c, what, (name, rows, cols)) = best?;
        // A flipped sign is one of two, like a swap; a unit is one factor of a continuum.
        if c > 0.0 && !picked(c, |x| cost(rows, cols, x)) {
            return None;
        }
        let plural = name.contains(", ");
        let question = match (c < 0.0, plural) {
            (true, false) => "is its sign flipped",
            (true, true) => "are their signs flipped",
            (false, false) => "is it logged in the model's unit",
            (false, true) => "are they logged in the model's unit",
        };
        Some((
            v,
            format!(
                "{} with {name} scaled by {}: {question} ({what}?)",
                self.better(v, own),
                fmt_ratio(c),
            ),
        ))
    }

    /// The pair of outputs (or of inputs) under whose swap the documented model fits the logs
    /// best: columns logged in another order than the model names them (a maglev's gap and
    /// coil current given as `[i, z]` read a misfit "largest in u->i" and nothing more).
    /// `grid` the documented model's response where the cost evaluates it, `own` its cost.
    fn swapped(&self, grid: &[CMatrix], own: f64) -> Option<Rescaled> {
        let data = self.data();
        let pairs = |n: usize| (0..n).flat_map(move |a| (a + 1..n).map(move |b| (a, b)));
        let cost = |edit: &dyn Fn(&mut CMatrix)| {
            let edited: Vec<CMatrix> = grid
                .iter()
                .map(|m| {
                    let mut m = m.clone();
                    edit(&mut m);
                    m
                })
                .collect();
            self.cost.cost(&self.cost.map.seen(&edited).lines)
        };
        let outputs = pairs(data.outputs.len()).map(|(a, b)| {
            let names = format!("outputs {} and {}", data.outputs[a], data.outputs[b]);
            (cost(&|m| m.swap_rows(a, b)), names)
        });
        let inputs = pairs(data.inputs.len()).map(|(a, b)| {
            let names = format!("inputs {} and {}", data.inputs[a], data.inputs[b]);
            (cost(&|m| m.swap_columns(a, b)), names)
        });
        let (v, names) = outputs
            .chain(inputs)
            .filter(|(v, _)| v.is_finite())
            .min_by(|a, b| a.0.total_cmp(&b.0))?;
        Some((
            v,
            format!(
                "{} with {names} swapped: are the logs' columns in the order the model names them?",
                self.better(v, own)
            ),
        ))
    }

    /// "the documented model fits the logs N times better (...)", rescaled cost `v` against
    /// `own`, with the cost of noise alone they both stand against.
    fn better(&self, v: f64, own: f64) -> String {
        format!(
            "the documented model fits the logs {} times better (cost {v:.1} against {own:.1}, noise alone {:.1})",
            fmt_ratio(own / v),
            self.noise.mean()
        )
    }

    /// The sentence naming the logs' clock or channels in another unit than the model's, or
    /// two channels swapped: the best of the [clock](Self::clock_rescaled) and the
    /// [channel](Self::unit_rescaled) rescaling and the [swap](Self::swapped) (rival
    /// explanations of one misfit), when it fits the logs [`CLOCK_GAIN`]
    /// times better than none and to within [`NEAR_NOISE`] times the cost of noise alone, and
    /// the logs [pick](picked) a unit's factor.
    /// `theta` the documented values, `grid` their response where the cost evaluates it, `own`
    /// its cost.
    fn rescaled_sentence(&self, theta: &[f64], grid: &[CMatrix], own: f64) -> Option<String> {
        [
            self.clock_rescaled(theta, own),
            self.unit_rescaled(grid, own),
            self.swapped(grid, own),
        ]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .filter(|(v, _)| *v * CLOCK_GAIN < own && *v <= NEAR_NOISE * self.noise.mean())
        .map(|(_, sentence)| sentence)
    }

    /// The [`far_from_documented`] warning on the parameters of the starting model (not those
    /// of the effects the discovery added), with the [sentence](Self::rescaled_sentence)
    /// naming a clock or channels in another unit when the documented model fits the logs
    /// rescaled; that sentence alone after a verdict of misfit (a cart-pole's angle logged in
    /// degrees left a misfit 415 times the noise with every parameter near its documented
    /// value). The flag says whether a rescaling was named: it then explains the misfit.
    pub fn far_warning(
        &self,
        model: &Model,
        params: &[ParamEstimate],
        unexplained: bool,
    ) -> Result<(Option<String>, bool)> {
        // An effect's documented value is where its fit starts, a guess, not a measured
        // property: an axle damping found at 1/40 of it is no sign of a bent fit, whether
        // discovery added the effect or the user did (`fit --with`).
        let guesses = model.effect_parameter_names()?;
        let own: Vec<ParamEstimate> = params
            .iter()
            .filter(|p| !guesses.contains(&p.name))
            .cloned()
            .collect();
        let far = far_from_documented(model, &own)?;
        if far.is_none() && !unexplained {
            return Ok((None, false));
        }
        // The documented model's response and cost on the logs' own clock and units, which
        // the rescalings compare against.
        let theta = self.model.documented()?;
        let rescaled = self
            .model
            .frf(&theta, self.cost.map.grid_hz(), self.fit_options().hold)
            .ok()
            .and_then(|grid| {
                let own = self.cost.cost(&self.cost.map.seen(&grid).lines);
                own.is_finite()
                    .then(|| self.rescaled_sentence(&theta, &grid, own))
                    .flatten()
            });
        let named = rescaled.is_some();
        Ok((
            match (far, rescaled) {
                (Some(far), Some(rescaled)) => Some(format!("{far}; {rescaled}")),
                (far, rescaled) => far.or(rescaled),
            },
            named,
        ))
    }
}

/// What the FRF criterion's verdict tests: its remaining cost against the Monte-Carlo
/// reference of noise alone.
pub const COST_TEST: &str = "for the remaining cost under noise alone";

impl Conclusion {
    /// Settles the effects a discovery added: all tentative with the reasons when a caveat
    /// speaks against them all (an estimate biased under feedback, a misfit left), else
    /// tentative those a [`Rivalry`] leaves unconfirmed, with its reason, and found the rest.
    /// One rule for every criterion. (A vehicle's two thrust gains, which the data cannot tell
    /// apart with its mass free, left its sensor lag and drag tentative too, `found: []`.)
    pub fn settle(
        added: Vec<String>,
        caveats: Vec<String>,
        rivalries: Vec<Rivalry>,
        unexplained: bool,
        verdict: Verdict,
        level: f64,
    ) -> Self {
        let (found, tentative, caveats) = if added.is_empty() {
            (added, Vec::new(), Vec::new())
        } else if !caveats.is_empty() {
            let why = caveats
                .into_iter()
                .chain(rivalries.into_iter().map(|r| r.why));
            (Vec::new(), added, why.collect())
        } else {
            let (tentative, found) = added
                .into_iter()
                .partition(|e| rivalries.iter().any(|r| r.tentative.contains(e)));
            let why = rivalries.into_iter().map(|r| r.why).collect();
            (found, tentative, why)
        };
        Self {
            found,
            tentative,
            caveats,
            unexplained,
            verdict,
            level,
            candidates: Candidates::Tried,
            near_misses: Vec::new(),
            explain_alone: Vec::new(),
            warnings: Vec::new(),
            test: COST_TEST,
        }
    }

    /// The same conclusion with what qualifies its verdict (see [`Conclusion::warnings`]).
    pub fn with_warnings(self, warnings: Vec<String>) -> Self {
        Self { warnings, ..self }
    }

    /// The same conclusion for a verdict whose p-value is that of `test` (by default the FRF
    /// criterion's [`COST_TEST`]).
    pub fn with_test(self, test: &'static str) -> Self {
        Self { test, ..self }
    }

    /// The same conclusion naming the candidates tried on the final model (`last`) that the
    /// effect-size rule alone kept out: significant by the F test, its robustness check and
    /// BIC, but lowering the cost by less than the noise-only spread. With many residuals that
    /// rule is strict, and a real effect can stand below it while the verdict sees a misfit.
    pub fn with_near_misses(self, last: &[CandidateScore]) -> Self {
        let near_misses = last
            .iter()
            .filter(|c| c.passes_tests && !c.exceeds_noise)
            .map(|c| {
                let by = if c.abandoned { "at least " } else { "" };
                format!(
                    "{} passes the tests (p = {:.1e}) but lowers the cost by {by}{:.1}, less than \
                     noise alone varies it ({:.1}); `fit --with {}` fits it alone",
                    c.effect,
                    c.p_value,
                    c.cost_reduction(),
                    c.noise_spread,
                    c.effect
                )
            })
            .collect();
        Self {
            near_misses,
            ..self
        }
    }

    /// The same conclusion for a result that tried the candidates or not (see [`Candidates`]).
    pub fn with_candidates(self, candidates: Candidates) -> Self {
        Self { candidates, ..self }
    }

    /// The verdict's sentence, with the closing words the candidates allow.
    pub fn verdict_sentence(&self) -> String {
        let sentence = self.verdict.sentence_of(self.candidates, self.test);
        let sentence = match &self.verdict {
            Verdict::UnexplainedStructuredMisfit { .. } if !self.near_misses.is_empty() => {
                format!(
                    "{sentence} beyond the noise: {}",
                    self.near_misses.join("; ")
                )
            }
            _ => sentence,
        };
        let sentence = match &self.verdict {
            Verdict::UnexplainedStructuredMisfit { .. } if !self.explain_alone.is_empty() => {
                let (each, apart) = if self.explain_alone.len() > 1 {
                    ("each of ", "; these logs cannot tell them apart")
                } else {
                    ("", "")
                };
                format!(
                    "{sentence}; yet fitted alone, {each}{} leaves the innovations uncorrelated \
                     with the excitation (`fit --with` the effect reads explained{apart}), \
                     though the selection, which scores every candidate under the starting \
                     model's predictor, did not add it: an effect the outputs hardly see at the \
                     operating point (an offset the loop regulates away) barely lowers that \
                     cost, and a fit that predictor bent (a low-pass disturbance it takes for \
                     white noise) stays bent there",
                    self.explain_alone.join("; ")
                )
            }
            _ => sentence,
        };
        let unsaid: Vec<&str> = self
            .warnings
            .iter()
            .filter(|w| self.tentative.is_empty() || !self.caveats.contains(w))
            .map(String::as_str)
            .collect();
        if unsaid.is_empty() {
            return sentence;
        }
        format!("{sentence}; but {}", unsaid.join("; "))
    }

    /// A sentence naming the tentative effects and why; `None` when there are none.
    pub fn tentative_sentence(&self) -> Option<String> {
        (!self.tentative.is_empty()).then(|| {
            format!(
                "[{}] lower the cost but are tentative, not found: {}",
                self.tentative.join(", "),
                self.caveats.join("; ")
            )
        })
    }

    /// The closing lines of a terminal summary: found, tentative and why, verdict.
    pub fn lines(&self) -> String {
        // `compare` and `fit` search nothing: an empty "found" beside their verdict read as
        // if the effects given to `fit --with` had been rejected.
        let mut s = match self.candidates {
            Candidates::Untried => {
                "found: nothing searched (compare and fit fit the model as given, with the \
                 effects named by --with; discover searches the candidates)\n"
                    .to_string()
            }
            _ => format!("found: [{}]\n", self.found.join(", ")),
        };
        if let Some(t) = self.tentative_sentence() {
            let _ = writeln!(s, "tentative: {t}");
        }
        let _ = writeln!(s, "verdict: {}", self.verdict_sentence());
        // Beside an explained verdict a significant candidate is still worth naming: the
        // effect-size rule kept out a real pendulum friction whose absence left a length 6
        // standard errors off, with the verdict "explained".
        if !matches!(self.verdict, Verdict::UnexplainedStructuredMisfit { .. })
            && !self.near_misses.is_empty()
        {
            let _ = writeln!(
                s,
                "near miss (the verdict holds without it): {}",
                self.near_misses.join("; ")
            );
        }
        s
    }
}

/// Result of [`Workbench::discover`].
#[derive(Debug, Clone, Serialize)]
pub struct Discovery {
    /// Steps, starting with the base model.
    pub steps: Vec<Step>,
    /// Found and tentative effects, verdict. Effects are found when the FRF estimator is
    /// unbiased under feedback (or the data are open loop) and the final model leaves no
    /// structured misfit; otherwise they are tentative with those reasons.
    #[serde(flatten)]
    pub conclusion: Conclusion,
    /// Under which noise estimate the costs of the steps are weighted (they compare only
    /// under one weighting; `compare` and `discover` may use different ones).
    pub weighting: String,
}

impl Discovery {
    /// A sentence naming the tentative effects and why; `None` when the loop added nothing
    /// or everything it added is confirmed.
    pub fn tentative_sentence(&self) -> Option<String> {
        self.conclusion.tentative_sentence()
    }
}

/// Re-estimations of the noise after the first re-weighted fit (see `fit_reweighted`).
const REWEIGHTINGS: usize = 1;

/// Values tried for a new parameter: 17 points over its bounds (logarithmic for a positive
/// range spanning decades, or one from zero without an upper bound), plus zero and the
/// documented value when inside. An open bound is taken 100 typical magnitudes away.
pub(crate) fn scan_grid(p: &super::model::Parameter) -> Vec<f64> {
    let n = 17;
    let reach = 100.0 * p.scale();
    let lower = if p.lower.is_finite() {
        p.lower
    } else {
        p.value - reach
    };
    let upper = if p.upper.is_finite() {
        p.upper
    } else {
        p.value + reach
    };
    let log_lower = if p.lower > 0.0 {
        p.lower
    } else {
        1e-3 * p.scale()
    };
    let decades =
        (p.lower > 0.0 && upper / p.lower > 100.0) || (p.lower == 0.0 && !p.upper.is_finite());
    let mut v: Vec<f64> = if decades {
        let (a, b) = (log_lower.ln(), upper.ln());
        (0..n)
            .map(|i| (a + (b - a) * i as f64 / (n - 1) as f64).exp())
            .collect()
    } else {
        (0..n)
            .map(|i| lower + (upper - lower) * i as f64 / (n - 1) as f64)
            .collect()
    };
    v.push(p.value);
    if p.lower <= 0.0 && p.upper >= 0.0 {
        v.push(0.0);
    }
    v
}

impl Workbench {
    /// Fits `model` from `start` and builds its step record.
    pub(crate) fn step(
        &self,
        model: &Model,
        added: Option<String>,
        start: Option<&[f64]>,
        base_cost: Option<f64>,
    ) -> Result<Step> {
        let fitted = self.refined(self.fitted(model, added, start)?)?;
        self.step_from(fitted, base_cost)
    }

    /// The FRF fit of `model` from its documented values as a step reports it: re-weighted,
    /// then refined ([`Self::refined`]).
    pub(crate) fn fit_refined(&self, model: &Model) -> Result<FitResult> {
        Ok(self.refined(self.fitted(model, None, None)?)?.r)
    }

    /// Fits `model` from `start` (see [`Workbench::fit_reweighted`]).
    fn fitted(
        &self,
        model: &Model,
        added: Option<String>,
        start: Option<&[f64]>,
    ) -> Result<Fitted> {
        let (r, weighting) = self.fit_reweighted(model, start)?;
        Ok(Fitted {
            model: model.clone(),
            added,
            r,
            weighting,
            candidates: Vec::new(),
        })
    }

    /// Names the weighting every step's cost is computed under: the noise re-estimated from
    /// the residual of the model with `effects` (instrumental variables), or the estimate's
    /// own noise estimate (the record's bins beside the lines, or the segments' residual).
    fn weighting_sentence(&self, effects: &[String]) -> String {
        if self.reweights() {
            format!(
                "costs weighted by the noise re-estimated from the residual of the model with [{}]",
                effects.join(", ")
            )
        } else {
            "costs weighted by the noise of the non-parametric estimate".to_string()
        }
    }

    /// Whether the weighting's noise is re-estimated from each model's residual: for the
    /// instrumental variables, whose estimate-based noise is distorted at the lowest lines of
    /// a closed loop ([`super::frf::model_noise`]).
    fn reweights(&self) -> bool {
        matches!(
            self.frf.estimator,
            Estimator::InstrumentalVariable | Estimator::H1WelchInstrumental
        )
    }

    /// The weighting of a fitted model's cost.
    fn weighting<'a>(&'a self, fitted: &'a Fitted) -> &'a WeightedCost {
        fitted.weighting.as_ref().unwrap_or(&self.cost)
    }

    /// Fits `model` from `start`; when the workbench re-weights, by iterated re-weighting:
    /// the noise of the weighting from the residual of the start, fit, and when the start was
    /// not itself a fit (documented values, `start = None`) [`REWEIGHTINGS`] more times the
    /// noise from the fitted model's residual and a refit.
    pub(crate) fn fit_reweighted(
        &self,
        model: &Model,
        start: Option<&[f64]>,
    ) -> Result<(FitResult, Option<WeightedCost>)> {
        let opts = self.fit_options();
        if !self.reweights() {
            return Ok((fit(model, &self.cost, start, &opts)?, None));
        }
        let (theta, again): (Vec<f64>, usize) = match start {
            Some(t) => (t.to_vec(), 0),
            None => (model.documented()?, REWEIGHTINGS),
        };
        let g = model.frf_seen(&theta, &self.cost.map, opts.hold)?;
        let mut cost = self.noise_weighting(&g)?;
        let mut r = fit(model, &cost, Some(&theta), &opts)?;
        for _ in 0..again {
            cost = self.noise_weighting(&r.model_frf)?;
            r = fit(model, &cost, Some(&r.theta), &opts)?;
        }
        Ok((r, Some(cost)))
    }

    /// `f` refined to the maximum likelihood when the workbench re-weights: each model's
    /// cost weighted by the noise of its own residual ([`fit_noise_weighted`]), from `f`'s
    /// fit, with the weighting at the refined fit. The re-weighted fit is biased toward the
    /// noise's own ratio where the noise rivals the excitation, so the parameters a fit or a
    /// discovery reports are refined; the selection's tests stay on the re-weighted fits,
    /// whose costs the noise reference and the decisions were calibrated on (refining every
    /// candidate made a clean platform flight read a drag it does not have). Far from the
    /// data the likelihood also falls toward a gain without bound, whose residual's noise
    /// grows as fast as the residual: a refinement that fails or runs onto a new bound keeps
    /// `f`.
    fn refined(&self, f: Fitted) -> Result<Fitted> {
        if !self.reweights() || f.r.gave_up {
            return Ok(f);
        }
        let opts = self.fit_options();
        Ok(
            match fit_noise_weighted(&f.model, &self.frf, Some(&f.r.theta), &opts) {
                // A stop is the run's, not a refit that failed.
                Err(SimError::Cancelled) => return Err(SimError::Cancelled),
                Ok((r, weighting))
                    if !r.gave_up
                        && r.params
                            .iter()
                            .zip(&f.r.params)
                            .all(|(m, h)| !m.at_bound || h.at_bound) =>
                {
                    Fitted {
                        r,
                        weighting: Some(weighting),
                        ..f
                    }
                }
                _ => f,
            },
        )
    }

    /// The cost weighted with the noise estimated from the residual of the model FRF `g`.
    fn noise_weighting(&self, g: &super::frf::ModelFrf) -> Result<WeightedCost> {
        WeightedCost::with_noise(&self.frf, &super::frf::model_noise(&self.frf, g)?)
    }

    /// The record of a fitted model: diagnosis, time-domain fit and residual tests.
    fn step_from(&self, fitted: Fitted, base_cost: Option<f64>) -> Result<Step> {
        let absorbed_noise = fitted.r.information.absorbed();
        let diagnosis = diagnose(
            &self.frf,
            self.weighting(&fitted),
            &self.noise,
            &fitted.r.model_frf.lines,
            absorbed_noise,
        );
        let Fitted {
            model,
            added,
            r,
            candidates,
            ..
        } = fitted;
        let ss = model.state_space(&r.theta)?;
        let (mut time_fit, runs) = time_fit(&self.data, &ss, DEFAULT_HORIZON, DEFAULT_WINDOW)?;
        if let Some(controller) = model.structure().controller() {
            let disc = ss.discretize(1.0 / self.data.sample_rate_hz)?;
            match super::closed_loop::closed_loop_fit(&self.data, &disc, &controller) {
                Ok(fit) => time_fit.closed_loop = Some(fit),
                Err(why) => time_fit.closed_loop_error = Some(why),
            }
        }
        let residuals: Vec<_> = runs.iter().map(|(e, _, _)| e).collect();
        let states: Vec<_> = runs.iter().map(|(_, x, _)| x).collect();
        let inputs: Vec<_> = runs.iter().map(|(_, _, u)| u).collect();
        let mut residual_tests = residual_tests(
            &residuals,
            &inputs,
            &states,
            &self.data.outputs,
            &self.data.inputs,
            DEFAULT_LAGS,
            usize::from(!self.data.is_open_loop()),
        );
        if time_fit.kalman.is_some() {
            residual_tests.residual = "innovations of the stationary Kalman predictor".into();
        }
        let (expected, _) = self.noise.fitted_level(absorbed_noise);
        let base = base_cost.unwrap_or(r.cost);
        Ok(Step {
            added,
            effects: model.enabled(),
            cost: r.cost,
            reduction_percent: 100.0 * (1.0 - r.cost / base),
            normalized_cost: r.cost / expected,
            absorbed_noise,
            params: r.params,
            diagnosis,
            time_fit,
            residual_tests,
            candidates,
            theta: r.theta,
            model_frf: r.model_frf.lines,
        })
    }

    /// Probability under noise alone of the cost of a model with no response at all. Where
    /// it is not small, the excited band carries no measurable response (a sensor that moves
    /// with the plant above a mount resonance, an input drowned in feedback of noise): any
    /// model whose response is small there fits to the noise level, a wrong one included,
    /// so no effect can be confirmed.
    pub fn zero_response_p_value(&self) -> f64 {
        let zero: Vec<super::frf::CMatrix> = self
            .frf
            .lines
            .iter()
            .map(|l| super::frf::CMatrix::zeros(l.g.nrows(), l.g.ncols()))
            .collect();
        let (mean, _) = self.noise.fitted_level(0.0);
        matched_sf(self.cost.cost(&zero), mean, self.noise.sd())
    }

    /// Probability of the step's cost under noise alone.
    pub fn noise_p_value(&self, step: &Step) -> f64 {
        let (mean, _) = self.noise.fitted_level(step.absorbed_noise);
        matched_sf(step.cost, mean, self.noise.sd())
    }

    /// Start vector for `model` from an earlier fit: shared parameters keep their values.
    pub(crate) fn carry_over(&self, from: &Model, theta: &[f64], to: &Model) -> Result<Vec<f64>> {
        let old = from.parameters()?;
        Ok(to
            .parameters()?
            .iter()
            .map(|p| {
                old.iter()
                    .position(|q| q.name == p.name)
                    .map_or(p.value, |i| theta[i])
            })
            .collect())
    }

    /// Scores one candidate effect on top of `model` (fitted as `current`).
    fn score(
        &self,
        model: &Model,
        current: &Fitted,
        effect: &str,
        n_candidates: usize,
    ) -> Result<(Model, FitResult, CandidateScore)> {
        let with = model.with_effect(effect)?;
        let start = self.carry_over(model, &current.r.theta, &with)?;
        // Candidates are fitted and compared under the current step's weighting.
        let cost = self.weighting(current);
        // Two starts: the current estimate with the new parameters at their documented values,
        // and all parameters at their documented values with each new parameter chosen by a
        // coarse scan over its bounds. The current estimate of a misspecified model is
        // distorted to mimic the missing effect, and resonant effects (gyroscopic coupling)
        // have local minima; the second start escapes both.
        let params = with.parameters()?;
        let old: Vec<String> = model.parameters()?.into_iter().map(|p| p.name).collect();
        let mut scanned: Vec<f64> = params.iter().map(|p| p.value).collect();
        let new: Vec<usize> = (0..params.len())
            .filter(|&i| !old.contains(&params[i].name))
            .collect();
        for &i in &new {
            scanned[i] = 0.0f64.clamp(params[i].lower, params[i].upper);
        }
        let hold = self.fit_options().hold;
        for &i in &new {
            let mut best = (f64::INFINITY, scanned[i]);
            for v in scan_grid(&params[i]) {
                let mut t = scanned.clone();
                t[i] = v;
                if let Ok(g) = with.frf_seen(&t, &cost.map, hold) {
                    let c = cost.cost(&g.lines);
                    if c < best.0 {
                        best = (c, v);
                    }
                }
            }
            scanned[i] = best.1;
        }
        let a = fit(&with, cost, Some(&start), &self.fit_options())?;
        let b = fit(&with, cost, Some(&scanned), &self.fit_options())?;
        let r = if b.cost < a.cost { b } else { a };
        let per_line = |g: &[super::frf::CMatrix]| -> Vec<f64> {
            (0..g.len()).map(|k| cost.line_cost(k, &g[k])).collect()
        };
        let (before, after) = (
            per_line(&current.r.model_frf.lines),
            per_line(&r.model_frf.lines),
        );
        // On clean simulated logs momentum drag's six parameters take 1-2% of a noise-level
        // cost with F p ~ 1e-6: the effect-size rule (one standard deviation of the
        // Monte-Carlo noise reference) keeps such a mismatch from being claimed.
        let costs = NestedCosts {
            before: current.r.cost,
            after: r.cost,
            residuals: cost.n_residuals() as f64,
            free_before: current.r.free,
            free_after: r.free,
            scale: self.noise.per_residual(),
            noise_sd: self.noise.sd(),
            design_effect: r.information.design_effect(&current.r.information.free),
        };
        let mut score = CandidateScore::nested(
            effect,
            &costs,
            Robustness::WithoutBestBlock(&before, &after),
            n_candidates,
            false,
        );
        score.response = Some(Response::new(
            cost,
            &current.r.model_frf.lines,
            &r.model_frf.lines,
            costs.scale,
        ));
        Ok((with, r, score))
    }

    /// A one-step record of a fitted model (for `compare` and `fit`): no candidate tried, the
    /// verdict on the remaining cost.
    pub fn record(&self, step: Step) -> Result<Discovery> {
        let verdict = self.verdict(&step);
        let weighting = self.weighting_sentence(&step.effects);
        let unexplained = matches!(verdict, Verdict::UnexplainedStructuredMisfit { .. });
        let warnings = self.warnings(&self.model, &step.params, &step.diagnosis, unexplained)?;
        Ok(Discovery {
            steps: vec![step],
            conclusion: Conclusion::settle(
                Vec::new(),
                Vec::new(),
                Vec::new(),
                unexplained,
                verdict,
                LEVEL,
            )
            .with_candidates(Candidates::of(&self.model, false))
            .with_warnings(warnings),
            weighting,
        })
    }

    /// Reasons not to confirm the effects a discovery added: an FRF estimator biased under
    /// feedback on data not known to be open loop (least squares or H1 Welch without the
    /// logged excitation: on a clean closed loop its low-frequency bias is "explained" by
    /// drag), and a structured misfit left by the final model (the F tests assumed the rest
    /// was noise; an effect may be absorbing part of that misfit), as for the Cubli.
    fn caveats(&self, verdict: &Verdict) -> Vec<String> {
        let mut why = self.data_caveats();
        if matches!(verdict, Verdict::UnexplainedStructuredMisfit { .. }) {
            why.push(MISFIT_CAVEAT.to_string());
        }
        why
    }

    /// What qualifies a verdict on `model` fitted to `params`: the [data
    /// caveats](Self::data_caveats), parameters [far from their documented
    /// values](far_from_documented), and an operating point that is not an equilibrium at the
    /// documented values (the FRF criterion compares the linearization there). The documented
    /// values, not the fitted ones: a fit biased by a missing effect unbalances a point the
    /// user gave right.
    fn warnings(
        &self,
        model: &Model,
        params: &[ParamEstimate],
        diagnosis: &Diagnosis,
        unexplained: bool,
    ) -> Result<Vec<String>> {
        let mut why = self.data_caveats();
        let (far, rescaled) = self.far_warning(model, params, unexplained)?;
        why.extend(far);
        why.extend(super::closed_loop::unstable_loop(
            model, params, &self.data,
        )?);
        why.extend(unmeasured_effects(model, params)?);
        // A rescaling that explains the logs is the reason for the misfit: a path or a line
        // it leaves is its by-product (theta in degrees read "the model has no path
        // Tz->theta ... an effect that couples them is missing" after naming the degrees).
        if unexplained && !rescaled {
            why.extend(Self::dominant_line(diagnosis));
            why.extend(Self::unmodelled_paths(diagnosis));
        }
        let drift = model.drift(&model.documented()?)?;
        if !drift.is_empty() {
            why.push(format!(
                "the operating point is not an equilibrium at the documented values ({}): the FRF criterion compares the linearization there, which is not where the loop runs, and the fitted parameters absorb the difference; give the operating point the loop holds (inputs that balance the model)",
                Drift::describe(&drift)
            ));
        }
        why.extend(super::Level::resting_elsewhere(model, &self.data)?);
        Ok(why)
    }

    /// The caveats that concern the estimate every verdict rests on, whatever was added: an
    /// estimator biased under feedback, a response indistinguishable from zero, nonlinear
    /// distortion within the band.
    fn data_caveats(&self) -> Vec<String> {
        let mut why = Vec::new();
        if self.frf.estimator.biased_under_feedback() && !self.data.is_open_loop() {
            let fix = if self.data.has_excitation() {
                "use the instrumental variable (`--estimator auto`): the excitation is logged"
                    .to_string()
            } else if let Some(gap) = self.data.excitation_gap() {
                gap
            } else {
                format!(
                    "log the excitation (MCAP topic `/{}/excitation`, CSV columns `r_<input>`) for the instrumental variable",
                    self.model.structure().system()
                )
            };
            why.push(format!(
                "the FRF estimator is {} and the data are not known to be open loop; {fix}",
                self.frf.estimator.describe()
            ));
        }
        if self.zero_response_p_value() >= LEVEL {
            why.push(format!(
                "the measured FRF is indistinguishable from zero over the band ({:.2}-{:.2} Hz): the data cannot test a model there",
                self.frf.lines.first().map_or(0.0, |l| l.freq_hz),
                self.frf.lines.last().map_or(0.0, |l| l.freq_hz),
            ));
        }
        // The FRF criterion compares a linear(ized) model with the excited lines, where
        // distortion adds to the error but not to the noise reference.
        if let Some((output, size)) = self
            .frf
            .distortion
            .as_ref()
            .and_then(|d| d.worst_within_band())
            .filter(|&(_, size)| size > super::distortion::UNDERSTATED)
        {
            let single = self
                .frf
                .distortion
                .as_ref()
                .and_then(|d| d.dominant_line())
                .map_or(String::new(), |(o, hz, share)| {
                    format!(
                        "; yet {:.0} % of it lies in {o} at {hz:.2} Hz alone, which a periodic disturbance there gives (a rotor's runout, mains hum: lowering the excitation does not remove it)",
                        100.0 * share
                    )
                });
            why.push(format!(
                "the loop responds at lines the excitation leaves out (nonlinear distortion, {size:.2}x the FRF's noise reference within the band in {output}): the reference understates the FRF's error there, so the tests were too lenient and an added effect may be absorbing the nonlinearity; model it (a [nonlinear] section under the prediction-error criterion) or lower the excitation's amplitude{single}"
            ));
        }
        why
    }

    /// A misfit whose excess over the noise sits at one excited line (at least
    /// [`DOMINANT_SHARE`](super::distortion::DOMINANT_SHARE) of it): named, as a periodic
    /// disturbance at that frequency reads so. (A rotor's runout at its spin frequency, an
    /// excited line, carried 97 % of a magnetic bearing's misfit and bent the stiffness 58 %.)
    fn dominant_line(diagnosis: &Diagnosis) -> Option<String> {
        let excess = |g: &super::diagnose::GroupMisfit| (g.misfit - g.expected).max(0.0);
        let lines = &diagnosis.lines;
        let total: f64 = lines.iter().map(excess).sum();
        let top = lines
            .iter()
            .max_by(|a, b| excess(a).total_cmp(&excess(b)))?;
        let share = excess(top) / total;
        (top.flagged && share >= super::distortion::DOMINANT_SHARE).then(|| {
            format!(
                "{:.0} % of the misfit beyond the noise lies at the line {} alone: a periodic disturbance at that frequency (a rotor's runout, mains hum) or a narrow resonance there gives that",
                100.0 * share,
                top.label
            )
        })
    }

    /// The paths the data show and the model lacks ([`Diagnosis::unmodelled_paths`]), named.
    /// (A magnetic bearing's gyroscopic coupling left its misfit in `ix->ys` and `iy->xs`,
    /// which an uncoupled model's response is zero in, and nothing said so.)
    fn unmodelled_paths(diagnosis: &Diagnosis) -> Option<String> {
        let paths: Vec<String> = diagnosis
            .unmodelled_paths
            .iter()
            .map(|(o, i)| format!("{i}->{o}"))
            .collect();
        (!paths.is_empty()).then(|| {
            format!(
                "the model has no path {} (its response there is zero at every line), where the data show one: an effect that couples them is missing",
                paths.join(", ")
            )
        })
    }

    fn verdict(&self, step: &Step) -> Verdict {
        let p_value = self.noise_p_value(step);
        if p_value >= LEVEL {
            Verdict::ExplainedToNoiseLevel { p_value }
        } else {
            let d = &step.diagnosis;
            Verdict::UnexplainedStructuredMisfit {
                p_value,
                outputs: d.flagged_outputs(),
                band_hz: d.band_hz,
                worst_entries: d.worst_entries.clone(),
            }
        }
    }

    /// With re-weighting, each step was fitted and its candidates tested under the noise of its
    /// own model's residual; a misspecified model's residual carries its model error, which
    /// makes its own cost small and its fit poor where that error is large. For the report
    /// every earlier model is refitted (from its estimate) under one weighting, the last
    /// one's (the best model's noise estimate), as the paper compares models under one FRF
    /// variance: costs, reductions, parameters and diagnosis are those of these fits; the
    /// candidates keep the scores of the step's own tests.
    fn common_weighting(&self, fitted: &mut [Fitted]) -> Result<()> {
        let Some((last, earlier)) = fitted.split_last_mut() else {
            return Ok(());
        };
        let Some(w) = last.weighting.clone() else {
            return Ok(());
        };
        for f in earlier {
            f.r = fit(&f.model, &w, Some(&f.r.theta), &self.fit_options())?;
            f.weighting = Some(w.clone());
        }
        Ok(())
    }

    /// Records of the fitted models, built in parallel (the time-domain evaluation of each
    /// is independent and the most expensive part of a record).
    fn records(&self, fitted: Vec<Fitted>) -> Result<Vec<Step>> {
        let base = fitted.first().map(|f| f.r.cost);
        let jobs: Vec<_> = fitted
            .into_iter()
            .map(|f| move || self.step_from(f, base))
            .collect();
        in_parallel(self.model.parallel(), jobs, "discovery step record")
    }

    /// Runs the discovery loop from the current model.
    pub fn discover(&self) -> Result<Discovery> {
        self.discover_with(&mut |_: &str| {})
    }

    /// [`Workbench::discover`] reporting progress (one message per fitted candidate).
    pub fn discover_with(&self, progress: &mut dyn FnMut(&str)) -> Result<Discovery> {
        let mut d = match self.criterion {
            super::Criterion::Time => self.discover_time(progress, true)?,
            super::Criterion::Frf => self.discover_alone(progress)?,
        };
        if d.conclusion.unexplained {
            match self.criterion {
                super::Criterion::Time => {
                    progress("cross-checking under the FRF criterion");
                    let quantized = super::prediction::quantization_warning(&self.data);
                    let coloured: Vec<String> = d
                        .steps
                        .last()
                        .filter(|_| quantized.is_none())
                        .map(|s| {
                            s.residual_tests
                                .channels
                                .iter()
                                .filter(|c| c.not_white)
                                .map(|c| c.output.clone())
                                .collect()
                        })
                        .unwrap_or_default();
                    d.conclusion
                        .warnings
                        .extend(self.frf_cross_check(&coloured));
                }
                super::Criterion::Frf if self.model.structure().is_nonlinear() => {
                    progress("cross-checking under the time-domain criterion");
                    d.conclusion.warnings.extend(self.time_cross_check());
                }
                super::Criterion::Frf => {}
            }
        }
        // The cross-checks above keep no result of a cancelled run, and the time criterion's
        // search records a cancelled candidate as failed.
        self.cancel.check()?;
        Ok(d)
    }

    /// The discovery under the workbench's criterion alone, without the other's cross-check
    /// (what a power study counts, and what a cross-check runs).
    pub fn discover_alone(&self, progress: &mut dyn FnMut(&str)) -> Result<Discovery> {
        let d = match self.criterion {
            super::Criterion::Time => self.discover_time(progress, false)?,
            super::Criterion::Frf => self.discover_frf(progress)?,
        };
        // A candidate whose fit was cancelled is recorded as failed, and the search goes on.
        self.cancel.check()?;
        Ok(d)
    }

    /// The discovery under the FRF criterion.
    fn discover_frf(&self, progress: &mut dyn FnMut(&str)) -> Result<Discovery> {
        progress("fitting the starting model");
        let start = self.fitted(&self.model, None, None)?;
        // Candidates are tested whether or not the total cost is at the noise level: an
        // effect confined to a few lines and entries (gyroscopic coupling) can stand far above
        // the noise there and still hide in the total over all residuals.
        let (mut done, found) = forward_selection(&FrfSearch(self), start, progress)?;
        if let Some(last) = done.pop() {
            progress("refining the final model to the maximum likelihood");
            done.push(self.refined(last)?);
        }
        self.common_weighting(&mut done)?;
        let last_fit = done.last().map(|f| (f.model.clone(), f.r.params.clone()));
        let steps = self.records(done)?;
        let last = steps
            .last()
            .ok_or_else(|| SimError::invalid("discovery", "no step", "nothing was fitted"))?;
        let verdict = self.verdict(last);
        let caveats = self.caveats(&verdict);
        let rivalries = rivals(
            steps
                .iter()
                .map(|s| (s.added.as_deref(), s.candidates.as_slice())),
        );
        let unexplained = matches!(verdict, Verdict::UnexplainedStructuredMisfit { .. });
        let warnings = match &last_fit {
            Some((model, params)) => self.warnings(model, params, &last.diagnosis, unexplained)?,
            None => self.data_caveats(),
        };
        let conclusion = Conclusion::settle(found, caveats, rivalries, unexplained, verdict, LEVEL)
            .with_candidates(Candidates::of(&self.model, true))
            .with_near_misses(&last.candidates)
            .with_warnings(warnings);
        let weighting = self.weighting_sentence(&last.effects);
        Ok(Discovery {
            steps,
            conclusion,
            weighting,
        })
    }
}

/// The FRF criterion's moves in the forward selection.
struct FrfSearch<'a>(&'a Workbench);

impl Search for FrfSearch<'_> {
    type Fit = Fitted;
    type Context = ();

    fn candidates(&self, at: &Fitted) -> Vec<String> {
        at.model.frf_candidates()
    }

    fn context(&self, _: &Fitted) -> Result<()> {
        Ok(())
    }

    fn try_effect(
        &self,
        at: &Fitted,
        _: &(),
        effect: &str,
        n: usize,
    ) -> Result<(Fitted, CandidateScore)> {
        let (model, r, mut score) = self.0.score(&at.model, at, effect, n)?;
        score.builtin = at.model.is_builtin(effect);
        let fit = Fitted {
            model,
            added: Some(effect.to_string()),
            r,
            weighting: None,
            candidates: Vec::new(),
        };
        Ok((fit, score))
    }

    fn record_scores(&self, at: &mut Fitted, scores: Vec<CandidateScore>) {
        at.candidates = scores;
    }

    /// With re-weighting, the added model is refitted under the noise of its own residual.
    fn added(&self, chosen: Fitted, effect: &str) -> Result<Fitted> {
        if self.0.reweights() {
            self.0.fitted(
                &chosen.model,
                Some(effect.to_string()),
                Some(&chosen.r.theta),
            )
        } else {
            Ok(chosen)
        }
    }

    fn removed(&self, at: &Fitted, effect: &str) -> Result<Fitted> {
        let model = at.model.without_effect(effect);
        let start = self.0.carry_over(&at.model, &at.r.theta, &model)?;
        self.0.fitted(&model, None, Some(&start))
    }

    /// Its cost under its own weighting against the noise reference, as the verdict tests the
    /// final model's.
    fn explained(&self, at: &Fitted) -> Option<bool> {
        let (mean, _) = self.0.noise.fitted_level(at.r.information.absorbed());
        Some(matched_sf(at.r.cost, mean, self.0.noise.sd()) >= LEVEL)
    }

    fn parallel(&self) -> bool {
        self.0.model.parallel()
    }
}

/// Runs independent jobs on scoped threads (on this one, in order, when not `parallel`) and
/// returns their results in order (a job that panics is reported as an error naming `what`).
/// As many threads as the machine has cores take the jobs in turn: a thread per job made six
/// sizing fits of a power study share two cores, each building its workbench three times as
/// long, and a stop waited for all of them (0.6 s against 0.2 s).
pub(crate) fn in_parallel<T, F>(parallel: bool, jobs: Vec<F>, what: &str) -> Result<Vec<T>>
where
    T: Send,
    F: FnOnce() -> Result<T> + Send,
{
    if !parallel {
        return jobs.into_iter().map(|f| f()).collect();
    }
    let count = jobs.len();
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(count);
    let queue = Mutex::new(jobs.into_iter().enumerate());
    let done: Vec<Mutex<Option<Result<T>>>> = (0..count).map(|_| Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let Some((i, job)) = locked(&queue).next() else {
                    break;
                };
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job))
                    .unwrap_or_else(|_| {
                        Err(SimError::invalid(
                            what,
                            "panicked",
                            "a worker thread failed",
                        ))
                    });
                *locked(&done[i]) = Some(result);
            });
        }
    });
    done.into_iter()
        .map(|slot| {
            slot.into_inner()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .unwrap_or_else(|| Err(SimError::invalid(what, "job", "was not run")))
        })
        .collect()
}

/// The mutex's value, also after a panic elsewhere (every job's result is written whole).
fn locked<V>(m: &Mutex<V>) -> std::sync::MutexGuard<'_, V> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::{
        rival_p_value, unmeasured_effects, CandidateScore, Candidates, Conclusion, ParamEstimate,
        Rivalry, Verdict,
    };
    use proptest::prelude::*;

    /// The sentences of [`super::rivals`].
    fn rivals<'a>(
        steps: impl IntoIterator<Item = (Option<&'a str>, &'a [CandidateScore])>,
    ) -> Vec<String> {
        super::rivals(steps).into_iter().map(|r| r.why).collect()
    }

    /// A misfit whose excess over the noise sits at one flagged line (95 of 100) is named with
    /// its share; spread over three lines, or at a line not flagged, it is not.
    #[test]
    fn a_misfit_at_one_line_is_named() {
        use crate::diagnose::{Diagnosis, GroupMisfit};
        let diagnosis = |misfits: &[(f64, bool)]| Diagnosis {
            lines: misfits
                .iter()
                .enumerate()
                .map(|(k, &(misfit, flagged))| GroupMisfit {
                    label: format!("{:.2} Hz", k as f64),
                    misfit,
                    expected: 10.0,
                    p_value: if flagged { 0.0 } else { 0.5 },
                    flagged,
                })
                .collect(),
            outputs: Vec::new(),
            worst_entries: Vec::new(),
            band_hz: None,
            fit_percent: Vec::new(),
            unmodelled_paths: Vec::new(),
        };
        let one = diagnosis(&[(12.0, false), (105.0, true), (13.0, false), (8.0, false)]);
        let said = crate::Workbench::dominant_line(&one).unwrap();
        assert!(
            said.starts_with("95 % of the misfit beyond the noise lies at the line 1.00 Hz alone"),
            "{said}"
        );
        let spread = diagnosis(&[(50.0, true), (60.0, true), (50.0, true)]);
        assert!(crate::Workbench::dominant_line(&spread).is_none());
        let unflagged = diagnosis(&[(10.0, false), (105.0, false)]);
        assert!(crate::Workbench::dominant_line(&unflagged).is_none());
    }

    /// A scored candidate: `cost` from `before`, F-test p-value `p` (its tests pass below 1 %
    /// over two candidates), the noise-only spread of a cost of 129 200 unit-variance
    /// residuals (508.3).
    fn scored(effect: &str, before: f64, cost: f64, p: f64) -> CandidateScore {
        let spread = (2.0f64 * 129_200.0).sqrt();
        CandidateScore {
            effect: effect.into(),
            cost,
            reduction_percent: 100.0 * (before - cost) / before,
            added_parameters: 1,
            f_statistic: 0.0,
            design_effect: 1.0,
            p_value: p,
            robust_p_value: p,
            delta_aic: -10.0,
            delta_bic: -5.0,
            exceeds_noise: before - cost > spread,
            passes_tests: p < 0.01 / 2.0,
            significant: p < 0.01 / 2.0 && before - cost > spread,
            abandoned: false,
            noise_spread: spread,
            scale: 1.0,
            followed: None,
            failed: None,
            set_aside: None,
            builtin: false,
            response: None,
        }
    }

    /// A misfit verdict names the candidate that passed every test but the effect size, with
    /// its cost reduction and the spread, and not one that failed the F test; an explained
    /// verdict names none.
    #[test]
    fn a_misfit_verdict_names_the_candidates_only_the_effect_size_kept_out() {
        let misfit = Verdict::UnexplainedStructuredMisfit {
            p_value: 1.1e-3,
            outputs: vec!["theta".into()],
            band_hz: None,
            worst_entries: Vec::new(),
        };
        let last = [
            scored("pendulum_friction", 130_000.0, 129_879.0, 4e-28),
            scored("sensor_bias", 130_000.0, 129_990.0, 0.2),
        ];
        let c = Conclusion::settle(
            Vec::new(),
            Vec::new(),
            Vec::new(),
            true,
            misfit.clone(),
            0.01,
        )
        .with_near_misses(&last);
        let s = c.verdict_sentence();
        assert!(
            s.contains("no candidate effect explains it beyond the noise: pendulum_friction passes the tests (p = 4.0e-28) but lowers the cost by 121.0, less than noise alone varies it (508.3)"),
            "{s}"
        );
        assert!(!s.contains("sensor_bias"), "{s}");
        let explained = Verdict::ExplainedToNoiseLevel { p_value: 0.4 };
        let c = Conclusion::settle(Vec::new(), Vec::new(), Vec::new(), false, explained, 0.01)
            .with_near_misses(&last);
        assert!(!c.verdict_sentence().contains("pendulum_friction"));
        // The summary's lines still name it, on a line of its own.
        let lines = c.lines();
        assert!(
            lines.contains("near miss (the verdict holds without it): pendulum_friction passes the tests (p = 4.0e-28)")
                && !lines.contains("sensor_bias"),
            "{lines}"
        );
        let c = Conclusion::settle(Vec::new(), Vec::new(), Vec::new(), true, misfit, 0.01)
            .with_near_misses(&last);
        assert!(!c.lines().contains("near miss ("), "{}", c.lines());
    }

    /// Rivals: equal costs are, a gap noise cannot make (z = sqrt(dV)/2 beyond 2.58) is not;
    /// a candidate whose reduction stays within the noise is never one, nor one whose own
    /// search ended decisively worse.
    #[test]
    fn rivals_are_candidates_whose_cost_gap_noise_could_make() {
        assert_eq!(rival_p_value(0.0, 1.0), 1.0);
        // chi2_sf(z^2, 1) at z = 2.576 is 1 %: dV = 4 z^2 = 26.5.
        assert!((rival_p_value(4.0 * 2.5758f64.powi(2), 1.0) - 0.01).abs() < 1e-4);
        assert!((rival_p_value(2.0 * 4.0 * 2.5758f64.powi(2), 2.0) - 0.01).abs() < 1e-4);
        let tried = vec![
            scored("lag", 32_331.0, 30_098.8, 1e-30),
            scored("delay", 32_331.0, 30_102.2, 1e-30),
            scored("far", 32_331.0, 30_140.0, 1e-30),
            scored("small", 32_331.0, 32_300.0, 1e-3),
        ];
        let start = (None, tried.as_slice());
        let then = (Some("lag"), &[][..]);
        let why = rivals([start, then]);
        assert_eq!(why.len(), 1, "{why:?}");
        assert!(
            why[0].starts_with(
                "delay fits these data as well as lag (cost +3.4, a gap noise makes with p = 0.36)"
            ),
            "{why:?}"
        );
        assert!(
            !why[0].contains("far") && !why[0].contains("small"),
            "{why:?}"
        );
        // Nothing added, nothing to rival.
        assert!(rivals([start]).is_empty());
        // A twin (the file's effect and a built-in one, the same cost to a hundredth of a
        // noise variance, as many parameters: a gimbal lag and `actuator_lag`) is no rival;
        // further apart, with another parameter count, or both the file's (two causes of one
        // term), it is.
        let builtin = |cost: f64| CandidateScore {
            builtin: true,
            ..scored("actuator_lag", 32_331.0, cost, 1e-30)
        };
        for (cost, rival) in [(30_098.8 + 0.005, false), (30_098.8 + 0.02, true)] {
            let twin = [tried[0].clone(), builtin(cost)];
            assert_eq!(
                !rivals([(None, &twin[..]), then]).is_empty(),
                rival,
                "{cost}"
            );
        }
        let both_files = [
            tried[0].clone(),
            scored("gimbal", 32_331.0, 30_098.8, 1e-30),
        ];
        assert_eq!(rivals([(None, &both_files[..]), then]).len(), 1);
        let mut more = builtin(30_098.8);
        more.added_parameters += 1;
        assert!(!super::twins(&tried[0], &more) && super::twins(&tried[0], &builtin(30_098.8)));
        // Costs a noise variance and more apart (the time criterion's twins) are one effect
        // when the fitted responses are one: closer than a hundredth of what each moved. Apart
        // by more, or with responses the effects did not move (offsets), they stay rivals.
        let response = |at: f64, moved: f64| super::Response {
            residuals: nalgebra::DVector::from_vec(vec![at, 0.0]),
            moved,
        };
        let with = |mut c: CandidateScore, r: super::Response| {
            c.response = Some(r);
            c
        };
        let file = with(tried[0].clone(), response(0.0, 100.0));
        for (at, moved, cost, twin) in [
            (0.9, 100.0, 30_100.2, true),
            (1.1, 100.0, 30_100.2, false),
            (0.9, 80.0, 30_100.2, false),
            (0.0, 0.0, 30_100.2, false),
            (0.0, 100.0, 30_098.8 + 30.0, false),
        ] {
            let file = match moved {
                0.0 => with(tried[0].clone(), response(0.0, 0.0)),
                _ => file.clone(),
            };
            let other = with(builtin(cost), response(at, moved));
            assert_eq!(super::twins(&file, &other), twin, "{at} {moved} {cost}");
        }
        // Two rivals are named each with its gap.
        let mut two = tried.clone();
        two.push(scored("bias", 32_331.0, 30_100.0, 1e-30));
        let why = rivals([(None, two.as_slice()), then]);
        assert!(
            why[0].starts_with(
                "delay and bias each fit these data as well as lag (cost delay +3.4, a gap noise \
                 makes with p = 0.36; bias +1.2, a gap noise makes with p = "
            ),
            "{why:?}"
        );
        // A rival the loop followed through a search of its own stays one while that search
        // added as many effects and ended within 2 ln 100 = 9.2 in BIC of the reported one,
        // and says what it found; one that needed more effects, or fell further behind, is
        // ruled out.
        let delay = |added: &[&str], bic: f64, kept: usize| {
            let added = added.iter().map(|e| e.to_string()).collect();
            Some(super::Followed::against(added, bic, kept, 0.0, false))
        };
        let mut followed = tried.clone();
        followed[1].followed = delay(&["delay"], 3.0, 1);
        let why = rivals([(None, followed.as_slice()), then]);
        assert_eq!(why.len(), 1, "{why:?}");
        assert!(
            why[0].contains("p = 0.36; its own search added [delay], BIC +3.0 against this model"),
            "{why:?}"
        );
        followed[1].followed = delay(&["delay"], 9.3, 1);
        assert!(rivals([(None, followed.as_slice()), then]).is_empty());
        followed[1].followed = delay(&["delay", "lag"], -4.0, 1);
        assert!(rivals([(None, followed.as_slice()), then]).is_empty());
        // A search that reached the kept model's effects in another order is no rival: the
        // kept search added lag then delay, the followed one delay then lag, at an equal BIC.
        followed[1].followed = delay(&["delay", "lag"], 0.0, 2);
        let last = (Some("delay"), &[][..]);
        let lag_then = (Some("lag"), &[][..]);
        assert!(rivals([(None, followed.as_slice()), lag_then, last]).is_empty());
        // Another second effect is still a rival.
        followed[1].followed = delay(&["delay", "far"], 0.0, 2);
        assert_eq!(
            rivals([(None, followed.as_slice()), lag_then, last]).len(),
            1
        );
        // What a rivalry leaves unconfirmed: the added effect, and a later one unless every
        // rival's own search added it too; an effect added before the coin toss stays found.
        let first = [scored("drag", 50_000.0, 32_331.0, 1e-30)];
        let friction = (Some("friction"), &[][..]);
        for (theirs, tentative) in [
            (Some(&["delay", "friction"][..]), &["lag"][..]),
            (Some(&["delay", "far"][..]), &["lag", "friction"][..]),
            (None, &["lag", "friction"][..]),
        ] {
            followed[1].followed = theirs.and_then(|t| delay(t, 0.0, 2));
            let steps = [
                (None, &first[..]),
                (Some("drag"), followed.as_slice()),
                lag_then,
                friction,
            ];
            let r = super::rivals(steps);
            assert_eq!(r.len(), 1, "{r:?}");
            assert_eq!(r[0].tentative, tentative, "{theirs:?}");
            let added = ["drag", "lag", "friction"].map(String::from).to_vec();
            let verdict = Verdict::ExplainedToNoiseLevel { p_value: 0.5 };
            let c = Conclusion::settle(added, Vec::new(), r, false, verdict, 0.01);
            assert_eq!(c.tentative, tentative);
            assert!(c.found.starts_with(&["drag".to_string()]), "{:?}", c.found);
        }
    }

    /// A misfit no single output carries says so instead of "in outputs []"; the closing words
    /// follow what was tried.
    #[test]
    fn a_misfit_sentence_names_its_outputs_or_says_none_alone() {
        let misfit = |outputs: Vec<String>| Verdict::UnexplainedStructuredMisfit {
            p_value: 3.6e-3,
            outputs,
            band_hz: None,
            worst_entries: Vec::new(),
        };
        let together = misfit(Vec::new()).sentence();
        assert!(
            together.contains("in the outputs together (none alone is flagged)")
                && !together.contains("[]"),
            "{together}"
        );
        let named = misfit(vec!["x".into(), "theta".into()]);
        assert!(named
            .sentence()
            .contains("in outputs [x, theta]; no candidate effect explains it"));
        assert!(named.sentence_given(Candidates::Untried).ends_with(
            "no candidate effect was tried (compare and fit test none: discover tries them)"
        ));
        assert!(named
            .sentence_given(Candidates::Absent)
            .ends_with("the model has no candidate effects to try"));
    }

    proptest! {
        /// The jobs' results come back in the jobs' order, the same as run one after another,
        /// whatever their count, failures and panics (a panic is its job's error, named).
        #[test]
        fn parallel_jobs_return_in_order(outcomes in proptest::collection::vec(0u8..3, 0..20)) {
            let jobs = |outcomes: &[u8]| -> Vec<Box<dyn FnOnce() -> crate::Result<usize> + Send>> {
                outcomes
                    .iter()
                    .enumerate()
                    .map(|(i, o)| {
                        let o = *o;
                        Box::new(move || match o {
                            0 => Ok(i * i),
                            1 => Err(crate::SimError::invalid("job", i, "failed")),
                            _ => panic!("job {i}"),
                        }) as Box<dyn FnOnce() -> crate::Result<usize> + Send>
                    })
                    .collect()
            };
            let on_threads = super::in_parallel(true, jobs(&outcomes), "a test");
            // Each job's result as run one after another (a panic as the error naming it).
            let expected: Vec<String> = outcomes
                .iter()
                .enumerate()
                .map(|(i, o)| match o {
                    0 => format!("{}", i * i),
                    1 => crate::SimError::invalid("job", i, "failed").to_string(),
                    _ => crate::SimError::invalid("a test", "panicked", "a worker thread failed")
                        .to_string(),
                })
                .collect();
            let got: Vec<String> = match on_threads {
                Ok(v) => v.iter().map(|x| x.to_string()).collect(),
                Err(e) => vec![e.to_string()],
            };
            // The results collect into one `Result`: the first error in the jobs' order.
            let want: Vec<String> = match outcomes.iter().position(|o| *o != 0) {
                None => expected,
                Some(k) => vec![expected[k].clone()],
            };
            prop_assert_eq!(got, want);
        }
    }

    proptest! {
        /// A unit is picked when the cost's own minimum lies within 10 % of it, up to half the
        /// grid's step, and not when it lies farther: a cost whose minimum is at `c r`, for
        /// any factor `c` of either sign over twelve decades.
        #[test]
        fn a_factor_is_picked_when_the_cost_is_lowest_near_it(
            c in (-6.0f64..6.0).prop_map(|e| 10f64.powf(e)),
            sign in prop::bool::ANY,
            log_r in -1.2f64..1.2,
        ) {
            use super::{picked, PICK_WITHIN};
            let c = if sign { c } else { -c };
            let at = (c * log_r.exp()).abs().ln();
            let got = picked(c, |x| (x.abs().ln() - at).powi(2));
            let half_step = 3f64.ln() / 40.0 / 2.0;
            if log_r.abs() <= PICK_WITHIN.ln() - half_step {
                prop_assert!(got);
            }
            if log_r.abs() >= PICK_WITHIN.ln() + half_step {
                prop_assert!(!got);
            }
        }

        /// Every added effect ends in exactly one list, in its order; a caveat makes them all
        /// tentative, a rivalry those it names; the reasons are kept exactly when something is
        /// tentative.
        #[test]
        fn settle_splits_the_added_effects_by_the_caveats_and_rivalries(
            added in proptest::collection::btree_set("[a-z_]{1,12}", 0..5),
            caveats in proptest::collection::vec("[a-z ]{1,20}", 0..3),
            named in proptest::collection::vec(proptest::collection::vec(0usize..6, 1..3), 0..3),
            unexplained: bool,
        ) {
            let added: Vec<String> = added.into_iter().collect();
            let rivalries: Vec<Rivalry> = named
                .iter()
                .enumerate()
                .map(|(i, picks)| Rivalry {
                    why: format!("rivalry {i}"),
                    tentative: picks.iter().filter_map(|&k| added.get(k).cloned()).collect(),
                })
                .collect();
            let verdict = Verdict::ExplainedToNoiseLevel { p_value: 0.5 };
            let c = Conclusion::settle(
                added.clone(),
                caveats.clone(),
                rivalries.clone(),
                unexplained,
                verdict,
                0.01,
            );
            let rival = |e: &String| rivalries.iter().any(|r| r.tentative.contains(e));
            let (tentative, found): (Vec<String>, Vec<String>) = if caveats.is_empty() {
                added.iter().cloned().partition(rival)
            } else {
                (added.clone(), Vec::new())
            };
            prop_assert_eq!(&c.tentative, &tentative);
            prop_assert_eq!(&c.found, &found);
            if added.is_empty() {
                prop_assert!(c.caveats.is_empty());
            } else if !caveats.is_empty() {
                prop_assert!(c.caveats.starts_with(&caveats));
                prop_assert_eq!(c.caveats.len(), caveats.len() + rivalries.len());
            } else {
                prop_assert_eq!(c.caveats.len(), rivalries.len());
            }
            prop_assert_eq!(c.unexplained, unexplained);
        }
    }

    /// A first-order loop logged at 100 Hz, `y' = -a y + b u` with `b` fixed (so no fitted
    /// rate absorbs a rescaled clock) under `u = r - y`, declared at 10 Hz and at 1 kHz: the
    /// sample rate a decade off is named in both directions and no time or channel unit is
    /// (1 kHz logs declared as 100 Hz once read as seconds against minutes and degrees against
    /// radians); declared right, or at a sixth (a factor none stands for), nothing is named. 4
    /// seeds each.
    #[test]
    fn a_sample_rate_a_decade_off_is_named() {
        use crate::{Dataset, EstimatorChoice, Experiment, ModelFile, Periodic, Workbench};
        use nalgebra::DMatrix;
        use rand::{Rng, SeedableRng};
        use rand_chacha::ChaCha8Rng;
        use rand_distr::StandardNormal;
        use std::sync::Arc;

        const MODEL: &str = r#"
name = "lag"
states = ["y"]
inputs = ["u"]
outputs = ["y"]
[parameters]
a = { value = 5.0, min = 0.01, max = 1000.0 }
b = { value = 5.0, fixed = true }
[linear]
A = [["-a"]]
B = [["b"]]
C = [[1]]
"#;
        const FS: f64 = 100.0;
        let (period, periods, transient) = (200, 5, 100);
        let logs = |declared_hz: f64, seed: u64| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let phi = (-5.0 / FS).exp();
            let gamma = 1.0 - phi; // b (1 - phi) / a with a = b
            let samples = transient + period * periods;
            let experiments = (0..2)
                .map(|e| {
                    let phases: Vec<f64> = (0..30)
                        .map(|_| rng.random::<f64>() * std::f64::consts::TAU)
                        .collect();
                    let r = DMatrix::from_fn(samples, 1, |k, _| {
                        let t = (k % period) as f64 / period as f64;
                        phases
                            .iter()
                            .enumerate()
                            .map(|(l, ph)| (std::f64::consts::TAU * (l + 1) as f64 * t + ph).cos())
                            .sum::<f64>()
                            * 0.2
                    });
                    let (mut u, mut y) = (DMatrix::zeros(samples, 1), DMatrix::zeros(samples, 1));
                    let mut x = 0.0;
                    for k in 0..samples {
                        y[(k, 0)] = x + 0.01 * rng.sample::<f64, _>(StandardNormal);
                        u[(k, 0)] = r[(k, 0)] - y[(k, 0)];
                        x = phi * x + gamma * u[(k, 0)];
                    }
                    Experiment {
                        name: format!("experiment {e}"),
                        u,
                        y,
                        r: Some(r),
                        periodic: Some(Periodic {
                            period,
                            periods,
                            transient,
                        }),
                    }
                })
                .collect();
            Dataset {
                sample_rate_hz: declared_hz,
                inputs: vec!["u".into()],
                outputs: vec!["y".into()],
                experiments,
            }
        };
        let structure =
            Arc::new(ModelFile::parse(MODEL, std::path::Path::new("lag.toml")).unwrap());
        let warnings = |declared_hz: f64, seed: u64| {
            let wb = Workbench::new(
                structure.clone(),
                logs(declared_hz, seed),
                EstimatorChoice::Auto,
            )
            .unwrap();
            wb.compared().unwrap().conclusion.warnings.join("; ")
        };
        for seed in 0..4 {
            for (declared, named) in [
                (10.0, "with their clock scaled by 1/10.0, as if sampled at 100 Hz rather than 10 Hz: a sample rate 10 times the declared one?"),
                (1000.0, "with their clock scaled by 10.0, as if sampled at 100 Hz rather than 1000 Hz: a sample rate a tenth of the declared one?"),
            ] {
                let said = warnings(declared, seed);
                assert!(said.contains(named), "seed {seed}, {declared} Hz: {said}");
                assert!(
                    !said.contains("a time unit of") && !said.contains("logged in the model's unit"),
                    "seed {seed}, {declared} Hz: {said}"
                );
            }
            for declared in [FS, FS / 6.0] {
                let said = warnings(declared, seed);
                assert!(
                    !said.contains("documented model fits"),
                    "seed {seed}, {declared} Hz: {said}"
                );
            }
        }
    }

    /// An effect whose parameters are all held is named as unmeasured; one with a fitted
    /// parameter, or a model without effects, is not (the pendulum example's joint friction).
    #[test]
    fn an_effect_held_whole_is_named_unmeasured() {
        use crate::{Model, ModelFile};
        use std::sync::Arc;
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/models/pendulum.toml");
        let base = Model::new(Arc::new(ModelFile::from_path(&path).unwrap()));
        let model = base.with_effect("joint_friction").unwrap();
        let estimates = |held_b: bool| -> Vec<ParamEstimate> {
            model
                .parameters()
                .unwrap()
                .into_iter()
                .map(|p| {
                    let held = p.name == "b" && held_b;
                    ParamEstimate {
                        std: (!held).then_some(0.1),
                        name: p.name,
                        value: p.value,
                        unit: p.unit,
                        held,
                        at_bound: false,
                        poorly_determined: false,
                    }
                })
                .collect()
        };
        let why = unmeasured_effects(&model, &estimates(true)).unwrap();
        assert_eq!(why.len(), 1, "{why:?}");
        assert!(
            why[0].starts_with("the size of joint_friction is not measured: b held"),
            "{}",
            why[0]
        );
        assert!(unmeasured_effects(&model, &estimates(false))
            .unwrap()
            .is_empty());
        let plain: Vec<ParamEstimate> = estimates(false)
            .into_iter()
            .filter(|p| p.name != "b")
            .collect();
        assert!(unmeasured_effects(&base, &plain).unwrap().is_empty());
    }

    /// Residuals that correlate as neighbouring Welch lines do (0.46, 0.14 and 0.03 one to
    /// three lines apart): a parameter fitted to noise alone takes about twice its share of
    /// the cost, so the plain F test of an added smooth regressor rejects far more often than
    /// its level. Divided by the design effect the statistic has the F distribution again:
    /// over 2000 noise draws its mean is 1 within 0.1 (standard error 0.03) and the 5 % test
    /// rejects 3-7 % of them (the plain one above 10 %). The design effect is also the closed
    /// form `x'Ωx / x'x` of the added column with the base's projected out, to 1e-9.
    #[test]
    fn f_test_divided_by_the_design_effect_holds_its_level_under_correlated_noise() {
        use super::NestedCosts;
        use crate::error::Result;
        use crate::fit::{solve, FitOptions, LeastSquares};
        use crate::model::Parameter;
        use nalgebra::{DMatrix, DVector};
        use rand::SeedableRng;
        use rand_chacha::ChaCha8Rng;
        use rand_distr::{Distribution, StandardNormal};

        struct Linear<'a> {
            x: DMatrix<f64>,
            y: &'a DVector<f64>,
            omega: &'a DMatrix<f64>,
        }
        impl LeastSquares for Linear<'_> {
            fn residuals(&self, theta: &[f64]) -> Result<DVector<f64>> {
                Ok(&self.x * DVector::from_column_slice(theta) - self.y)
            }
            fn jacobian(&self, _: &[f64], _: &DVector<f64>) -> Result<DMatrix<f64>> {
                Ok(self.x.clone())
            }
            fn correlated_gram(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
                j.transpose() * self.omega * j
            }
        }

        const N: usize = 300;
        let rho = [1.0, 0.46, 0.14, 0.03];
        let omega = DMatrix::from_fn(N, N, |i, j| rho.get(i.abs_diff(j)).copied().unwrap_or(0.0));
        let l = omega.clone().cholesky().expect("a correlation").l();
        let t = |k: usize| k as f64 / N as f64;
        let x = DMatrix::from_fn(N, 4, |k, c| match c {
            0 => 1.0,
            1 => (7.0 * t(k)).sin(),
            2 => (7.0 * t(k)).cos(),
            _ => (-3.0 * t(k)).exp(),
        });
        let params: Vec<Parameter> = ["a", "b", "c", "d"]
            .iter()
            .map(|n| Parameter::new(*n, 1.0, -1e6, 1e6, ""))
            .collect();
        // Closed form: the added column with the base's projected out.
        let base_x = x.columns(0, 3).into_owned();
        let proj =
            &base_x * (base_x.transpose() * &base_x).try_inverse().unwrap() * base_x.transpose();
        let added = (DMatrix::identity(N, N) - proj) * x.column(3);
        let closed_form = (added.transpose() * &omega * &added)[0] / added.norm_squared();
        assert!(closed_form > 1.5, "{closed_form}");

        let opts = FitOptions::default();
        let (mut sum_f, mut rejected, mut rejected_plain, draws) = (0.0, 0, 0, 2000);
        for seed in 0..draws {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let z = DVector::from_fn(N, |_, _| StandardNormal.sample(&mut rng));
            let y = &l * z;
            let fit = |cols: usize| {
                let criterion = Linear {
                    x: x.columns(0, cols).into_owned(),
                    y: &y,
                    omega: &omega,
                };
                solve(&criterion, &params[..cols], None, &opts).unwrap()
            };
            let (before, after) = (fit(3), fit(4));
            let design_effect = after.information.design_effect(&before.information.free);
            assert!(
                (design_effect - closed_form).abs() < 1e-9 * closed_form,
                "{design_effect} against {closed_form}"
            );
            let costs = NestedCosts {
                before: before.cost,
                after: after.cost,
                residuals: N as f64,
                free_before: before.free,
                free_after: after.free,
                scale: 1.0,
                noise_sd: 1.0,
                design_effect,
            };
            let (f, p) = costs.f_test();
            let plain = NestedCosts {
                design_effect: 1.0,
                ..costs
            };
            sum_f += f;
            rejected += usize::from(p < 0.05);
            rejected_plain += usize::from(plain.f_test().1 < 0.05);
        }
        let mean_f = sum_f / draws as f64;
        let rate = rejected as f64 / draws as f64;
        let rate_plain = rejected_plain as f64 / draws as f64;
        eprintln!(
            "design effect {closed_form:.3}: mean F {mean_f:.3}, rejected {rate:.3} (plain {rate_plain:.3})"
        );
        assert!((mean_f - 1.0).abs() < 0.1, "mean F {mean_f}");
        assert!((0.03..0.07).contains(&rate), "rejected {rate}");
        assert!(rate_plain > 0.1, "plain test rejected {rate_plain}");
    }
}
