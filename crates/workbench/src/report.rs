//! Outputs of a discovery: the terminal table, the JSON document and the offline HTML report
//! with inline SVG plots (no scripts, no external files).
use std::fmt::Write as _;
use std::path::Path;

use serde_json::{json, Value};

use super::discover::{CandidateScore, Conclusion, Discovery, Step, Verdict};
use super::fit::ParamEstimate;
use super::frf::CMatrix;
use super::model::Parameter;
use super::Workbench;
use crate::error::{Result, SimError};
use crate::output;

/// Selects parameters for a named list of the summary.
type Pick = fn(&ParamEstimate) -> bool;

/// Closes a named list of the summary (its names given).
type Close = fn(&[&str]) -> String;

/// The terminal summary of `discover`, `compare` and `fit`: one row per step with cost,
/// reduction and fit % per output, then the fitted parameters of the final model (value ±
/// standard error, unit, documented value; held and fixed ones marked) and the conclusion.
pub fn table(wb: &Workbench, d: &Discovery) -> String {
    summary(wb, d, true)
}

/// `+q params` of a candidate, and why when `q` is not its own count: an effect can let the
/// data separate parameters of the model that were held without it (a quadrotor's rotational
/// damping separates its yaw inertia from its rotor drag), and have parameters of its own held.
fn added_parameters(wb: &Workbench, c: &CandidateScore) -> String {
    let own = wb
        .model()
        .with_effect(&c.effect)
        .and_then(|m| m.effect_parameters(&c.effect))
        .map(|p| p.len())
        .unwrap_or(c.added_parameters);
    params_phrase(c.added_parameters, own)
}

/// `+q params` of an effect with `own` parameters of its own.
fn params_phrase(q: usize, own: usize) -> String {
    let why = match q.cmp(&own) {
        std::cmp::Ordering::Greater => {
            format!(
                " (its {own} and {} of the model's it lets the data separate)",
                q - own
            )
        }
        std::cmp::Ordering::Less if q > 0 => format!(" (of its {own}, {} held)", own - q),
        _ => String::new(),
    };
    format!("+{q} params{why}")
}

/// `n` and the noun, in the plural unless `n` is 1 (`1 experiment`, `4 experiments`).
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("{n} {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

fn summary(wb: &Workbench, d: &Discovery, parameters: bool) -> String {
    let mut s = String::new();
    let outputs = &wb.frf().outputs;
    let _ = writeln!(
        s,
        "FRF: {} lines {}-{} Hz, {}, estimator: {}",
        wb.frf().lines.len(),
        fmt_num(wb.frf().lines.first().map_or(0.0, |l| l.freq_hz)),
        fmt_num(wb.frf().lines.last().map_or(0.0, |l| l.freq_hz)),
        count(wb.data().experiments.len(), "experiment"),
        wb.frf().describe()
    );
    // Why the FRF is a Welch estimate, and how to get the periodic one, matters to the FRF
    // criterion; the time criterion only locates a misfit with it.
    if let Some(why) = wb
        .welch_reason()
        .filter(|_| wb.criterion() == crate::Criterion::Frf)
    {
        let _ = writeln!(s, "Welch estimate: {why}");
    }
    if let Some(distortion) = &wb.frf().distortion {
        let _ = writeln!(s, "linearity: {}", distortion.sentence());
    }
    if let Some(q) = wb.hold() {
        let _ = writeln!(
            s,
            "input hold: the inputs change every {q} samples of the logs, so they are read at \
             the inputs' rate, {} Hz, the first sample of each hold (the time criterion's one-step \
             prediction at the logs' rate would be nearly all sensor noise)",
            fmt_num(wb.data().sample_rate_hz)
        );
    }
    // The FRF criterion's cost is judged against the FRF's noise reference; the time
    // criterion's (a prediction error in absolute units) by its innovations' tests.
    let normalized = if wb.criterion() == crate::Criterion::Time {
        let _ = writeln!(
            s,
            "noise level: cost is the prediction error in absolute units, cost/resid. its mean \
             per residual; the residual tests below judge the noise level. The start's own \
             weighting makes its cost/resid. 1 by construction, and a candidate's test counts \
             its reduction on every residual: a few per cent can be decisive (see the candidates' p and dBIC)"
        );
        "cost/resid."
    } else {
        let _ = writeln!(
            s,
            "noise level: expected cost {:.0} for the true model ({} real residuals)",
            wb.noise().mean(),
            wb.noise().n_residuals
        );
        "cost/noise"
    };
    let _ = write!(
        s,
        "{:<5} {:<16} {:>12} {:>9} {:>8}",
        "step", "effect added", "cost", "reduct.%", normalized
    );
    for o in outputs {
        let _ = write!(s, " {:>7}", format!("fit%{o}"));
    }
    s.push('\n');
    for (i, st) in d.steps.iter().enumerate() {
        let _ = write!(
            s,
            "{:<5} {:<16} {:>12.1} {:>9.2} {:>8.2}",
            i,
            step_label(st),
            st.cost,
            shown_percent(st.reduction_percent),
            st.normalized_cost
        );
        for (_, f) in step_fit(st) {
            let _ = write!(s, " {f:>7.1}");
        }
        s.push('\n');
    }
    if let Some(p) = d
        .steps
        .first()
        .and_then(|st| st.time_fit.prediction_error.as_ref())
    {
        let _ = writeln!(
            s,
            "fit%: the extended Kalman predictor's {}-step prediction (EKF {}-step below), the \
             criterion's own model; the linearization's fits, which a non-smooth effect such as \
             dry friction distorts, are in the table below",
            p.horizon_samples, p.horizon_samples
        );
    }
    let _ = writeln!(s, "weighting: {}", d.weighting);
    time_domain_table(&mut s, d, wb.model().structure().is_nonlinear());
    // Runners-up the loop followed through a search of their own, and what those found.
    for (i, pair) in d.steps.windows(2).enumerate() {
        let added = pair[1].added.as_deref().unwrap_or("");
        let kept: Vec<&str> = d.steps[i + 1..]
            .iter()
            .filter_map(|s| s.added.as_deref())
            .collect();
        for c in &pair[0].candidates {
            if let Some(f) = &c.followed {
                let verdict = if f.same_model(&kept) {
                    "the same model in another order".to_string()
                } else if f.unexplained {
                    "ruled out: it ends with a misfit where this one explains the data".to_string()
                } else if f.ruled_out && f.added.len() > kept.len() {
                    format!(
                        "ruled out: it needs {} effects where this one needs {} (fewer effects come first, whatever the BIC)",
                        f.added.len(),
                        kept.len()
                    )
                } else if f.ruled_out {
                    "ruled out: its BIC is decisively worse".to_string()
                } else {
                    "the data do not choose".to_string()
                };
                let _ = writeln!(
                    s,
                    "  followed: {} in place of {added} at step {}: its search added [{}], BIC \
                     {:+.1} against this one; {verdict}",
                    c.effect,
                    i + 1,
                    f.added.join(", "),
                    f.bic,
                );
            }
        }
    }
    // Effects an earlier search added that later ones made redundant, once each.
    let mut aside: Vec<&str> = Vec::new();
    for c in d.steps.iter().flat_map(|st| &st.candidates) {
        if let Some(why) = &c.set_aside {
            if !aside.contains(&c.effect.as_str()) {
                aside.push(&c.effect);
                let _ = writeln!(s, "  set aside: {}: {why}", c.effect);
            }
        }
    }
    let last = d.steps.last();
    if let Some(st) = last {
        for c in &st.candidates {
            if let Some(why) = &c.failed {
                let _ = writeln!(s, "  not added: {:<15} its fit failed: {why}", c.effect);
                continue;
            }
            if c.abandoned {
                // Its cost is where the fit stopped, not a fitted one: no reduction to show.
                let seen = if c.added_parameters == 0 {
                    " (at this fit the data cannot tell its parameters from the model's)"
                } else {
                    ""
                };
                // The fit gives up on the effect size alone, so a stopped candidate may
                // already pass the tests (a near miss the verdict names): say so.
                let tests = if c.passes_tests {
                    format!(
                        ", although it passes the tests there (p = {:.2e})",
                        c.p_value
                    )
                } else {
                    String::new()
                };
                let _ = writeln!(
                    s,
                    "  not added: {:<15} fit stopped: the linear model of its cost showed it \
                     cannot lower the cost by more than noise alone varies it{tests}  {}{seen}",
                    c.effect,
                    added_parameters(wb, c),
                );
                continue;
            }
            if c.added_parameters == 0 {
                // Every parameter held at its documented value: the cost is of that value,
                // not of a fit, and no test applies (a smoothed dry friction linearized at
                // rest beside a viscous one read "reduction -141045.76%").
                let _ = writeln!(
                    s,
                    "  not added: {:<15} not testable at this fit: the data cannot tell its \
                     parameters from the model's, so they were held at their documented values \
                     (+0 params; cost {:+.2}% there)",
                    c.effect,
                    shown_percent(-c.reduction_percent),
                );
                continue;
            }
            // What it failed besides the F test and BIC shown: the robustness check (a small p
            // resting on one line alone) and the effect size.
            let noise = if c.exceeds_noise {
                ""
            } else {
                "  within the noise spread"
            };
            let _ = writeln!(
                s,
                "  not added: {:<15} reduction {:>6.2}%  {}  p = {:.2e}  robust p = {:.2e}  dBIC {:+.1}{noise}",
                c.effect,
                shown_percent(c.reduction_percent),
                added_parameters(wb, c),
                c.p_value,
                c.robust_p_value,
                c.delta_bic,
            );
        }
        // The held ones fix the unseen combinations: the other values are conditional on them.
        let lists: [(&str, Pick, Close); 2] = [
            (
                "held at documented values (not separable by the data)",
                |p| p.held,
                given,
            ),
            (
                "poorly determined (std > |value|, or std a lower bound only)",
                |p| p.poorly_determined,
                |_| String::new(),
            ),
        ];
        for (what, pick, close) in lists {
            let names: Vec<&str> = st
                .params
                .iter()
                .filter(|p| pick(p))
                .map(|p| p.name.as_str())
                .collect();
            if !names.is_empty() {
                let _ = writeln!(s, "{what}: {}{}", names.join(", "), close(&names));
            }
        }
    }
    if parameters {
        s.push_str(&parameter_lines(wb, d));
    } else {
        for (name, value, why) in wb.model().structure().fixed() {
            let _ = writeln!(s, "fixed {name} = {value} ({why})");
        }
    }
    s.push_str(&d.conclusion.lines());
    s
}

/// Closes the list of the parameters held at their documented values: the other values and
/// their standard errors hold given them there (a fit fixes an unseen combination by holding
/// one of its parameters; another choice would move the others along the combination).
fn given(held: &[&str]) -> String {
    match held {
        [] => String::new(),
        [one] => format!(
            "; the other values and their standard errors hold given {one} at its documented value"
        ),
        more => format!(
            "; the other values and their standard errors hold given {} at their documented values",
            more.join(", ")
        ),
    }
}

/// The parameters of the last step (the final model), one per line: value ± standard error
/// and unit, the documented value, and why a parameter was not estimated (held, fixed) or is
/// doubtful.
fn parameter_lines(wb: &Workbench, d: &Discovery) -> String {
    let Some(last) = d.steps.last() else {
        return String::new();
    };
    let documented = documented(wb, d);
    // An effect's parameters start from a guess, which is not documented.
    let guesses = with_effects(wb, &last.effects)
        .and_then(|m| m.effect_parameter_names())
        .unwrap_or_default();
    let fixed = wb.model().structure().fixed();
    let width = last
        .params
        .iter()
        .map(|p| p.name.len())
        .chain(fixed.iter().map(|(n, _, _)| n.len()))
        .max()
        .unwrap_or(0);
    let mut s = String::from(
        "parameters (value ± standard error, unit; documented value, or where an effect's fit started) of the final model:\n",
    );
    for p in &last.params {
        // Dimensionless ("1" or none) shows no unit.
        let unit = match p.unit.as_str() {
            "" | "1" => String::new(),
            u => format!(" {u}"),
        };
        let value = match (p.held, p.std) {
            (true, _) => format!(
                "{}{unit}  held at its documented value (not separable by the data)",
                fmt_num(p.value)
            ),
            (false, Some(sd)) => format!("{} ± {}{unit}", fmt_num(p.value), fmt_num(sd)),
            (false, None) => format!("{}{unit}  (no standard error)", fmt_num(p.value)),
        };
        let mut notes: Vec<String> = Vec::new();
        if !p.held {
            if let Some(doc) = documented.iter().find(|q| q.name == p.name) {
                let what = if guesses.contains(&p.name) {
                    "its fit started at"
                } else {
                    "documented"
                };
                notes.push(format!("{what} {}", fmt_num(doc.value)));
            }
        }
        if p.at_bound {
            notes.push("at a bound".into());
        }
        if p.poorly_determined {
            notes.push("poorly determined".into());
        }
        let notes = if notes.is_empty() {
            String::new()
        } else {
            format!("  ({})", notes.join(", "))
        };
        let _ = writeln!(s, "  {:<width$} = {value}{notes}", p.name);
    }
    for (name, value, why) in fixed {
        let _ = writeln!(s, "  {name:<width$} = {}  fixed ({why})", fmt_num(value));
    }
    s
}

/// What a step's model is: the effect it added, "(start)" for the base model, or the effects
/// a one-step `fit --with` enabled.
fn step_label(st: &Step) -> String {
    match (&st.added, st.effects.is_empty()) {
        (Some(e), _) => e.clone(),
        (None, true) => "(start)".into(),
        (None, false) => format!("with {}", st.effects.join("+")),
    }
}

/// The fit % per output the step table shows: under the time criterion the extended Kalman
/// predictor's k-step prediction, the nonlinear model the criterion fits (the linearization's
/// periodic fit fell from 56 % to 4 % when a Furuta pendulum's model gained the arm's dry
/// friction, whose slope at rest is steep, while this one rose from 97 % to 99 %); else the
/// periodic steady state on the excited lines.
fn step_fit(st: &crate::discover::Step) -> &[(String, f64)] {
    match &st.time_fit.prediction_error {
        Some(p) => &p.k_step,
        None => &st.diagnosis.fit_percent,
    }
}

/// Time-domain fit % per step (simulation and k-step prediction) with the stated policy, and
/// the residual tests of the last step.
fn time_domain_table(s: &mut String, d: &Discovery, nonlinear: bool) {
    let Some(first) = d.steps.first() else {
        return;
    };
    let _ = writeln!(s, "time domain: {}", first.time_fit.policy);
    if let Some(k) = &first.time_fit.kalman {
        let _ = writeln!(s, "Kalman: {}", k.policy);
    }
    if let Some(c) = &first.time_fit.closed_loop {
        let _ = writeln!(s, "closed loop: {}", c.policy);
    }
    let _ = write!(s, "{:<5} {:<16}", "step", "fit % of");
    for (o, _) in &first.time_fit.prediction {
        let _ = write!(s, " {o:>7}");
    }
    s.push('\n');
    for (i, st) in d.steps.iter().enumerate() {
        let tf = &st.time_fit;
        let k = tf.horizon_samples;
        let kalman = tf.kalman.as_ref();
        let nonlinear = tf.prediction_error.as_ref();
        let mut rows = vec![
            ("simulation".to_string(), tf.simulation.as_ref()),
            (format!("{k}-step pred."), Some(&tf.prediction)),
            ("1-step pred.".to_string(), Some(&tf.one_step)),
            (format!("Kalman {k}-step"), kalman.map(|f| &f.prediction)),
            ("Kalman 1-step".to_string(), kalman.map(|f| &f.one_step)),
            (
                "closed loop".to_string(),
                tf.closed_loop.as_ref().map(|f| &f.fit),
            ),
        ];
        if let Some(pe) = nonlinear {
            rows.push(("EKF 1-step".to_string(), Some(&pe.one_step)));
            rows.push((format!("EKF {}-step", pe.horizon_samples), Some(&pe.k_step)));
        }
        let controller = tf.closed_loop.is_some() || tf.closed_loop_error.is_some();
        for (what, fits) in rows {
            if what == "closed loop" && !controller {
                continue;
            }
            let _ = write!(s, "{i:<5} {what:<16}");
            match fits {
                Some(fits) => {
                    for (_, f) in fits {
                        let _ = write!(s, " {f:>7.1}");
                    }
                }
                None if what == "closed loop" => {
                    let why = tf.closed_loop_error.as_deref().unwrap_or("");
                    let _ = write!(s, " not re-simulated: {why}");
                }
                None if what.starts_with("Kalman") => {
                    let _ = write!(
                        s,
                        " no predictor: {}",
                        tf.kalman_error.as_deref().unwrap_or("not designed")
                    );
                }
                None => {
                    let _ = write!(
                        s,
                        " not scored: model not asymptotically stable (spectral radius {:.4}), the free run drifts or diverges",
                        tf.spectral_radius
                    );
                }
            }
            s.push('\n');
        }
    }
    if let Some(st) = d.steps.last() {
        let r = &st.residual_tests;
        let _ = writeln!(
            s,
            "residual tests (last step; {}; {} lags, 99% band +-{:.4}, {} samples):",
            r.residual,
            r.lags,
            r.channels.first().map_or(0.0, |c| c.whiteness.band),
            r.samples
        );
        for c in &r.channels {
            let _ = writeln!(
                s,
                "  {:<4} {} (peak {:+.3} at lag {}, p = {:.1e}); correlated with past inputs: [{}]; strongest lag-0 correlation: input {} {:+.3}, state {} {:+.3}",
                c.output,
                if c.not_white { "not white" } else { "white" },
                c.whiteness.peak,
                c.whiteness.peak_lag,
                c.whiteness.p_value,
                c.correlated_inputs.join(", "),
                c.input_correlation.as_ref().map_or("-", |(n, _)| n.as_str()),
                c.input_correlation.as_ref().map_or(0.0, |(_, v)| *v),
                c.state_correlation.map_or(0, |(i, _)| i),
                c.state_correlation.map_or(0.0, |(_, v)| v),
            );
        }
        let coloured: Vec<&str> = r
            .channels
            .iter()
            .filter(|c| c.not_white)
            .map(|c| c.output.as_str())
            .collect();
        if !coloured.is_empty()
            && matches!(d.conclusion.verdict, Verdict::ExplainedToNoiseLevel { .. })
        {
            // What the verdict and the parameters rest on is the criterion's own.
            let rests = if d.conclusion.test == crate::discover::COST_TEST {
                "The verdict rests on the FRF's remaining cost against noise alone and the parameters on the FRF fit, neither of which assumes white innovations; the predictor's fit % and these tests do"
            } else {
                "The verdict rests on the correlation with the excitation (or past inputs), which a right model passes whatever the noise model; but in closed loop a noise model that does not fit biases the fitted parameters a little, and the standard errors assume white innovations and may be too small"
            };
            let _ = writeln!(
                s,
                "  (not white in [{}] beside the verdict \"explained\": the disturbances' spectrum is not the one the predictor's noise model assumes. {rests})",
                coloured.join(", ")
            );
        }
        if let Some(c) = &r.coherence {
            let _ = writeln!(
                s,
                "coherence with {} ({} segments of {} samples, {} Hz bins, {} tested):",
                c.against,
                c.segments,
                c.segment,
                fmt_num(c.resolution_hz),
                c.bins_tested
            );
            if nonlinear {
                let _ = writeln!(
                    s,
                    "  (a nonlinear model's predictor error also follows the trajectory, so this locates a misfit and does not judge one; the verdict rests on the lag tests)"
                );
            }
            for o in &c.outputs {
                let flagged = match (o.flagged_hz.first(), o.flagged_hz.last()) {
                    (Some(a), _) if o.flagged_hz.len() == 1 => {
                        format!("flagged on 1 bin, {} Hz", fmt_num(*a))
                    }
                    (Some(a), Some(b)) => format!(
                        "flagged on {} bin(s), {}-{} Hz",
                        o.flagged_hz.len(),
                        fmt_num(*a),
                        fmt_num(*b)
                    ),
                    _ => "no bin flagged".into(),
                };
                let peak = o.peak.map_or(String::new(), |(hz, c, p)| {
                    format!("; largest {c:.3} at {} Hz (p = {p:.1e})", fmt_num(hz))
                });
                let _ = writeln!(s, "  {:<4} {flagged}{peak}", o.output);
            }
        }
    }
}

/// The JSON document: `steps` (added, cost, params, ...), `found`, `unexplained`, and more.
pub fn json(wb: &Workbench, d: &Discovery) -> Value {
    let steps: Vec<Value> = d
        .steps
        .iter()
        .map(|s| {
            let mut step = step_fields(
                &s.added,
                &s.effects,
                s.cost,
                s.reduction_percent,
                &s.params,
                &s.candidates,
            );
            for (k, v) in [
                ("normalized_cost", json!(s.normalized_cost)),
                ("absorbed_noise", json!(s.absorbed_noise)),
                (
                    "fit_percent",
                    step_fit(s)
                        .iter()
                        .map(|(n, f)| (n.clone(), json!(f)))
                        .collect::<serde_json::Map<_, _>>()
                        .into(),
                ),
                ("time_fit", json!(s.time_fit)),
                ("residual_tests", json!(s.residual_tests)),
                ("diagnosis", json!(s.diagnosis)),
            ] {
                step.insert(k.to_string(), v);
            }
            Value::Object(step)
        })
        .collect();
    let fixed: Vec<Value> = wb
        .model()
        .structure()
        .fixed()
        .into_iter()
        .map(|(n, v, why)| json!({"name": n, "value": v, "why": why}))
        .collect();
    let mut doc = conclusion_fields(wb.model().structure().system(), steps, &d.conclusion);
    for (k, v) in [
        ("estimator", json!(wb.frf().estimator)),
        ("welch_reason", json!(wb.welch_reason())),
        ("input_hold_samples", json!(wb.hold())),
        ("frequencies_hz", json!(wb.frf().freqs_hz())),
        ("distortion", json!(wb.frf().distortion)),
        ("zero_response_p_value", json!(wb.zero_response_p_value())),
        ("weighting", json!(d.weighting)),
        ("fixed", json!(fixed)),
    ] {
        doc.insert(k.to_string(), v);
    }
    let (residuals, noise) = cost_reference(wb, d);
    doc.insert("residuals".into(), json!(residuals));
    if let Some(noise) = noise {
        doc.insert("noise_expected_cost".into(), json!(noise));
    }
    Value::Object(doc)
}

/// What the steps' costs are sums of, and what noise alone would make them: the FRF
/// criterion's real residuals on the lines and its Monte-Carlo noise reference; the time
/// criterion's whitened one-step prediction errors (scored samples times outputs, the samples
/// its residual tests pool) and no noise reference (its weighting is estimated from the same
/// errors, so the cost per residual is about one by construction: the residual tests judge
/// it).
fn cost_reference(wb: &Workbench, d: &Discovery) -> (usize, Option<f64>) {
    match wb.criterion() {
        crate::Criterion::Frf => (wb.noise().n_residuals, Some(wb.noise().mean())),
        crate::Criterion::Time => (
            d.steps.first().map_or(0, |st| st.residual_tests.samples) * wb.data().outputs.len(),
            None,
        ),
    }
}

/// The JSON fields of a step every criterion writes: what the model holds, its cost, its
/// parameters (`params`, `std`, `held`, `poorly_determined`) and the candidates tried on it.
pub fn step_fields(
    added: &Option<String>,
    effects: &[String],
    cost: f64,
    reduction_percent: f64,
    params: &[ParamEstimate],
    candidates: &[CandidateScore],
) -> serde_json::Map<String, Value> {
    let by_name = |f: &dyn Fn(&ParamEstimate) -> Value| -> serde_json::Map<String, Value> {
        params.iter().map(|p| (p.name.clone(), f(p))).collect()
    };
    let names = |pick: Pick| -> Vec<String> {
        params
            .iter()
            .filter(|p| pick(p))
            .map(|p| p.name.clone())
            .collect()
    };
    let mut m = serde_json::Map::new();
    for (k, v) in [
        ("added", json!(added)),
        ("effects", json!(effects)),
        ("cost", json!(cost)),
        ("reduction_percent", json!(reduction_percent)),
        ("params", by_name(&|p| json!(p.value)).into()),
        ("std", by_name(&|p| json!(p.std)).into()),
        ("held", json!(names(|p| p.held))),
        ("poorly_determined", json!(names(|p| p.poorly_determined))),
        ("candidates", candidates_json(candidates)),
    ] {
        m.insert(k.to_string(), v);
    }
    m
}

/// A percentage as printed with two decimals: one that rounds to zero prints as 0.00, not
/// -0.00 (a candidate whose fit ends a hair above the base's cost changed nothing).
fn shown_percent(x: f64) -> f64 {
    if x.abs() < 0.005 {
        0.0
    } else {
        x
    }
}

/// The candidates of a step; an abandoned one's `reduction_percent` is null: its fit stopped
/// where it could no longer become significant, and its cost there is only an upper bound, so
/// no reduction is known (the terminal summary shows none either). Its `cost` and scores stay.
fn candidates_json(candidates: &[CandidateScore]) -> Value {
    Value::Array(
        candidates
            .iter()
            .map(|c| {
                let mut v = json!(c);
                if c.abandoned {
                    v["reduction_percent"] = Value::Null;
                }
                v
            })
            .collect(),
    )
}

/// The JSON document's fields every criterion writes: the system, the steps and the
/// conclusion (`found`, `tentative`, `tentative_why`, `unexplained`, `verdict`,
/// `verdict_text`, `near_misses`, `explain_alone`, `warnings`, `level`).
pub fn conclusion_fields(
    system: &str,
    steps: Vec<Value>,
    c: &Conclusion,
) -> serde_json::Map<String, Value> {
    let mut m = serde_json::Map::new();
    for (k, v) in [
        ("system", json!(system)),
        ("steps", Value::Array(steps)),
        ("found", json!(c.found)),
        ("tentative", json!(c.tentative)),
        ("tentative_why", json!(c.caveats)),
        ("unexplained", json!(c.unexplained)),
        ("verdict", json!(c.verdict)),
        ("verdict_text", json!(c.verdict_sentence())),
        ("near_misses", json!(c.near_misses)),
        ("explain_alone", json!(c.explain_alone)),
        ("warnings", json!(c.warnings)),
        ("level", json!(c.level)),
    ] {
        m.insert(k.to_string(), v);
    }
    m
}

/// Writes `value` to `path` through a temporary file renamed at the end (see
/// [`crate::output`]: an existing file that is not JSON is refused).
pub fn write_json(path: &Path, value: &Value) -> Result<()> {
    let text = serde_json::to_string_pretty(&output::stamped(value))
        .map_err(|e| SimError::invalid("json", "serialisation", e.to_string()))?;
    output::write_atomically(path, output::Kind::Json, &[], |tmp| {
        std::fs::write(tmp, text).map_err(|e| SimError::io(tmp, e))
    })
}

/// Writes the HTML report into `dir`: built in a temporary sibling directory and renamed into
/// place only when complete, so a failure never leaves a half report. A `dir` that holds
/// anything this program did not write is refused (see [`crate::output`]).
pub fn write_report(dir: &Path, wb: &Workbench, d: &Discovery) -> Result<()> {
    publish(dir, &html(wb, d), &json(wb, d))
}

/// Name of the JSON document in a report directory, whichever verb wrote it (`discover`,
/// `compare`, `fit`): the same document as `--json`.
pub const REPORT_JSON: &str = "report.json";

/// Writes `index.html` and [`REPORT_JSON`] into a new directory `dir`.
pub fn publish(dir: &Path, html: &str, json: &Value) -> Result<()> {
    output::write_dir_atomically(dir, &[], |tmp| {
        let index = tmp.join("index.html");
        std::fs::write(&index, html).map_err(|e| SimError::io(&index, e))?;
        write_json(&tmp.join(REPORT_JSON), json)
    })
}

pub(crate) const COLORS: [&str; 6] = [
    "#d62728", "#ff7f0e", "#2ca02c", "#1f77b4", "#9467bd", "#8c564b",
];

/// A plotted series.
#[derive(Debug)]
pub struct Series<'a> {
    pub(crate) name: String,
    pub(crate) color: &'a str,
    pub(crate) points: Vec<(f64, f64)>,
    pub(crate) markers: bool,
    pub(crate) band: Option<Vec<(f64, f64, f64)>>,
}

/// The x axis of a chart.
#[derive(Debug, Clone, Copy)]
pub struct XAxis<'a> {
    label: &'a str,
    log: bool,
}

impl<'a> XAxis<'a> {
    /// A linear axis with this label.
    pub fn linear(label: &'a str) -> Self {
        Self { label, log: false }
    }
}

const FREQUENCY: XAxis<'static> = XAxis {
    label: "frequency (Hz)",
    log: true,
};

const TIME: XAxis<'static> = XAxis {
    label: "time (s)",
    log: false,
};

const LAG: XAxis<'static> = XAxis {
    label: "lag (samples)",
    log: false,
};

/// One series per step, coloured by step.
pub fn per_step<S>(
    steps: &[S],
    label: impl Fn(usize, &S) -> String,
    markers: bool,
    points: impl Fn(&S) -> Vec<(f64, f64)>,
) -> Vec<Series<'static>> {
    steps
        .iter()
        .enumerate()
        .map(|(k, st)| Series {
            name: label(k, st),
            color: COLORS[k % COLORS.len()],
            points: points(st),
            markers,
            band: None,
        })
        .collect()
}

/// An SVG chart with a logarithmic or linear x axis and a linear y axis.
pub fn chart(title: &str, x_axis: XAxis<'_>, y_label: &str, series: &[Series<'_>]) -> String {
    let (w, h, l, r, t, b) = (520.0, 300.0, 60.0, 150.0, 28.0, 40.0);
    let xs = series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let (xmin, xmax) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let ys = series.iter().flat_map(|s| {
        s.points.iter().map(|p| p.1).chain(
            s.band
                .iter()
                .flat_map(|b| b.iter().flat_map(|q| [q.1, q.2])),
        )
    });
    let (mut ymin, mut ymax) = ys
        .filter(|y| y.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
    if !(ymin.is_finite() && ymax.is_finite() && xmin.is_finite() && xmax.is_finite())
        || (x_axis.log && xmin <= 0.0)
    {
        return format!("<p>{}: nothing to plot</p>", escape(title));
    }
    if ymax - ymin < 1e-9 {
        ymin -= 1.0;
        ymax += 1.0;
    }
    let pad = 0.05 * (ymax - ymin);
    let (ymin, ymax) = (ymin - pad, ymax + pad);
    let warp = |x: f64| if x_axis.log { x.log10() } else { x };
    let margin = if x_axis.log {
        0.05
    } else {
        0.02 * (xmax - xmin).max(1e-9)
    };
    let (lx0, lx1) = (warp(xmin) - margin, warp(xmax) + margin);
    let px = |x: f64| l + (warp(x) - lx0) / (lx1 - lx0) * (w - l - r);
    let py = |y: f64| t + (ymax - y.clamp(ymin, ymax)) / (ymax - ymin) * (h - t - b);
    let mut s = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="11">"#
    );
    let _ = write!(
        s,
        r##"<rect x="{l}" y="{t}" width="{}" height="{}" fill="none" stroke="#999"/>"##,
        w - l - r,
        h - t - b
    );
    let _ = write!(
        s,
        r#"<text x="{l}" y="16" font-size="13">{}</text>"#,
        escape(title)
    );
    let (ystep, yticks) = nice_ticks(ymin, ymax);
    for y in yticks {
        let _ = write!(
            s,
            r#"<text x="{}" y="{:.1}" text-anchor="end">{}</text>"#,
            l - 4.0,
            py(y) + 4.0,
            fmt_tick(y, ystep)
        );
    }
    let ticks: Vec<f64> = if x_axis.log {
        [0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0]
            .into_iter()
            .filter(|x| *x >= xmin * 0.8 && *x <= xmax * 1.25)
            .collect()
    } else {
        nice_ticks(xmin, xmax).1
    };
    for x in ticks {
        let label = if x_axis.log {
            format!("{x}")
        } else {
            fmt_tick(x, nice_ticks(xmin, xmax).0)
        };
        let _ = write!(
            s,
            r#"<text x="{:.1}" y="{}" text-anchor="middle">{label}</text>"#,
            px(x),
            h - b + 14.0,
        );
    }
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        l + (w - l - r) / 2.0,
        h - 6.0,
        escape(x_axis.label)
    );
    let _ = write!(
        s,
        r#"<text x="12" y="{}" transform="rotate(-90 12 {})" text-anchor="middle">{}</text>"#,
        h / 2.0,
        h / 2.0,
        escape(y_label)
    );
    for (i, se) in series.iter().enumerate() {
        if let Some(band) = &se.band {
            let mut poly: Vec<String> = band
                .iter()
                .map(|(x, lo, _)| format!("{:.1},{:.1}", px(*x), py(*lo)))
                .collect();
            poly.extend(
                band.iter()
                    .rev()
                    .map(|(x, _, hi)| format!("{:.1},{:.1}", px(*x), py(*hi))),
            );
            let _ = write!(
                s,
                r#"<polygon points="{}" fill="{}" fill-opacity="0.2" stroke="none"/>"#,
                poly.join(" "),
                se.color
            );
        }
        if se.markers {
            for (x, y) in &se.points {
                let _ = write!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="2.5" fill="{}"/>"#,
                    px(*x),
                    py(*y),
                    se.color
                );
            }
        } else {
            let pts: Vec<String> = se
                .points
                .iter()
                .map(|(x, y)| format!("{:.1},{:.1}", px(*x), py(*y)))
                .collect();
            let _ = write!(
                s,
                r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="1.5"/>"#,
                pts.join(" "),
                se.color
            );
        }
        let ly = t + 12.0 + 15.0 * i as f64;
        let _ = write!(
            s,
            r#"<rect x="{}" y="{}" width="10" height="3" fill="{}"/><text x="{}" y="{}">{}</text>"#,
            w - r + 8.0,
            ly - 4.0,
            se.color,
            w - r + 22.0,
            ly,
            escape(&se.name)
        );
    }
    s.push_str("</svg>");
    s
}

/// Ticks at multiples of 1, 2 or 5 times a power of ten, four to ten over `[lo, hi]`, and
/// their spacing.
fn nice_ticks(lo: f64, hi: f64) -> (f64, Vec<f64>) {
    let raw = ((hi - lo) / 5.0).max(1e-300);
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (step, (first..=last).map(|i| i as f64 * step).collect())
}

/// A tick label with the decimals its spacing needs (plain, or in exponent form for very
/// large or small steps).
fn fmt_tick(v: f64, step: f64) -> String {
    if step.is_nan() || step <= 0.0 {
        return fmt_num(v);
    }
    if v.abs() < 1e-6 * step {
        return "0".into();
    }
    if !(1e-3..1e4).contains(&step) {
        let digits = ((v.abs().log10().floor() - step.log10().floor()).max(0.0)) as usize;
        return format!("{v:.digits$e}");
    }
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    format!("{v:.decimals$}")
}

/// Four significant digits (exponent form below 1e-3 and from 1e5 on): the one number
/// format of the summaries and reports.
pub(crate) fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if v.abs() >= 1e5 || v.abs() < 1e-3 {
        return format!("{v:.3e}");
    }
    let decimals = (3.0 - v.abs().log10().floor()).clamp(0.0, 6.0) as usize;
    format!("{v:.decimals$}")
}

/// Escapes `&`, `<` and `>` for HTML text.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// FRF entries to plot: the three with the largest misfit of the starting model, plus the
/// largest of the final one if different.
fn channels(d: &Discovery, wb: &Workbench) -> Vec<(usize, usize)> {
    let pick = |st: &Step| -> Vec<(usize, usize)> {
        st.diagnosis
            .worst_entries
            .iter()
            .filter_map(|(o, i, _)| {
                Some((
                    wb.frf().outputs.iter().position(|x| x == o)?,
                    wb.frf().inputs.iter().position(|x| x == i)?,
                ))
            })
            .collect()
    };
    let mut out = d.steps.first().map(pick).unwrap_or_default();
    if let Some(last) = d.steps.last() {
        for c in pick(last).into_iter().take(1) {
            if !out.contains(&c) {
                out.push(c);
            }
        }
    }
    out
}

fn html(wb: &Workbench, d: &Discovery) -> String {
    let frf = wb.frf();
    let f = frf.freqs_hz();
    let mut body = String::new();
    let (residuals, noise) = cost_reference(wb, d);
    let reference = match noise {
        Some(n) => format!("Expected cost of the true model from noise alone: {n:.0}."),
        None => format!("Costs are sums of {residuals} whitened one-step prediction errors; the residual tests below judge the noise level."),
    };
    let _ = write!(
        body,
        "<h1>stabilis workbench: {}</h1><p>Estimator: {}. {} excited lines, {}. {reference}</p>",
        escape(wb.model().structure().system()),
        frf.describe(),
        f.len(),
        count(wb.data().experiments.len(), "experiment"),
    );
    // The parameters have their own table below.
    let _ = write!(
        body,
        "<h2>Summary</h2><pre>{}</pre>",
        escape(&summary(wb, d, false))
    );
    let bars: Vec<(String, f64)> = d
        .steps
        .iter()
        .map(|s| (s.added.clone().unwrap_or_else(|| "start".into()), s.cost))
        .collect();
    body.push_str(&cost_bars(&bars, noise));
    body.push_str(&parameter_table(wb, d));
    body.push_str(&time_series(wb, d));
    body.push_str(&autocorrelation(d));
    // Residuals per line and step.
    let series = per_step(
        &d.steps,
        |_, s: &Step| s.added.clone().unwrap_or_else(|| "start".into()),
        false,
        |s| {
            s.diagnosis
                .lines
                .iter()
                .zip(&f)
                .map(|(g, x)| (*x, (g.misfit / g.expected).max(1e-3).log10()))
                .collect()
        },
    );
    let _ = write!(body, "<h2>Residuals</h2><p>Weighted misfit per line divided by what noise alone gives (log10; 0 = noise level).</p>{}", chart("misfit / noise per line", FREQUENCY, "log10 ratio", &series));
    body.push_str(&distortion_plot(wb));
    // FRF per channel and step.
    body.push_str("<h2>Frequency response, measured and model</h2><p>Dots: measured FRF; shaded: one standard deviation; lines: model after each step, as the fit compares it (for a Welch estimate seen through the window's kernel).</p>");
    for (o, i) in channels(d, wb) {
        let name = format!("{} -> {}", frf.inputs[i], frf.outputs[o]);
        let entry = |g: &CMatrix| g[(o, i)];
        let meas: Vec<_> = frf.lines.iter().map(|l| entry(&l.g)).collect();
        let std: Vec<f64> = wb.cost().std.iter().map(|s| s[(o, i)]).collect();
        let db = |z: nalgebra::Complex<f64>| 20.0 * z.norm().max(1e-12).log10();
        // The measured entry with its one-standard-deviation band, as (value, low, high).
        let measured = |val: &dyn Fn(nalgebra::Complex<f64>, f64) -> (f64, f64, f64)| {
            let pts: Vec<(f64, (f64, f64, f64))> = meas
                .iter()
                .zip(&f)
                .zip(&std)
                .map(|((z, x), s)| (*x, val(*z, *s)))
                .collect();
            Series {
                name: "measured".into(),
                color: "#000000",
                points: pts.iter().map(|(x, (v, _, _))| (*x, *v)).collect(),
                markers: true,
                band: Some(pts.iter().map(|(x, (_, lo, hi))| (*x, *lo, *hi)).collect()),
            }
        };
        let mut mag = vec![measured(&|z, s| {
            (
                db(z),
                20.0 * (z.norm() - s).max(z.norm() * 0.01).log10(),
                20.0 * (z.norm() + s).log10(),
            )
        })];
        let mut phase = vec![measured(&|z, s| {
            let dphi = (s / z.norm().max(1e-12)).min(1.0).asin().to_degrees();
            let deg = z.arg().to_degrees();
            (deg, deg - dphi, deg + dphi)
        })];
        for (k, st) in d.steps.iter().enumerate() {
            let label = st.added.clone().unwrap_or_else(|| "start".into());
            let color = COLORS[k % COLORS.len()];
            mag.push(Series {
                name: label.clone(),
                color,
                points: st
                    .model_frf
                    .iter()
                    .zip(&f)
                    .map(|(g, x)| (*x, db(entry(g))))
                    .collect(),
                markers: false,
                band: None,
            });
            phase.push(Series {
                name: label,
                color,
                points: st
                    .model_frf
                    .iter()
                    .zip(&f)
                    .map(|(g, x)| (*x, entry(g).arg().to_degrees()))
                    .collect(),
                markers: false,
                band: None,
            });
        }
        let _ = write!(
            body,
            "<div>{}{}</div>",
            chart(&format!("{name}: magnitude"), FREQUENCY, "dB", &mag),
            chart(&format!("{name}: phase"), FREQUENCY, "degrees", &phase)
        );
    }
    page(&body)
}

/// The detection lines' ratios per output with the flag threshold, when the test ran.
fn distortion_plot(wb: &Workbench) -> String {
    let Some(d) = &wb.frf().distortion else {
        return String::new();
    };
    let mut series: Vec<Series<'_>> = d
        .outputs
        .iter()
        .enumerate()
        .map(|(k, o)| Series {
            name: o.output.clone(),
            color: COLORS[k % COLORS.len()],
            points: o
                .lines
                .iter()
                .map(|l| (l.hz, l.ratio.max(1e-3).log10()))
                .collect(),
            markers: true,
            band: None,
        })
        .collect();
    let span = d.outputs[0].lines.iter().map(|l| l.hz);
    let (lo, hi) = span.fold((f64::INFINITY, 0.0_f64), |(a, b), x| (a.min(x), b.max(x)));
    series.push(Series {
        name: "flag threshold".into(),
        color: "#000000",
        points: vec![(lo, d.flag_above.log10()), (hi, d.flag_above.log10())],
        markers: false,
        band: None,
    });
    format!(
        "<h2>Linearity</h2><p>{}</p>{}",
        escape(&d.sentence()),
        chart(
            "output at the lines the excitation leaves out, over the noise beside them",
            FREQUENCY,
            "log10 ratio",
            &series
        )
    )
}

/// The documented parameters of the last step's model.
fn documented(wb: &Workbench, d: &Discovery) -> Vec<Parameter> {
    d.steps
        .last()
        .and_then(|st| with_effects(wb, &st.effects).ok())
        .and_then(|m| m.parameters().ok())
        .unwrap_or_default()
}

/// The workbench's model with `effects` enabled: its candidates are the ones sized to the data
/// and offered by the user, so their documented values and bounds are the ones fitted.
fn with_effects(wb: &Workbench, effects: &[String]) -> Result<crate::Model> {
    effects
        .iter()
        .try_fold(wb.model().clone(), |m, e| m.with_effect(e))
}

/// Parameters per step: documented value, then value ± standard error per step (held ones
/// marked), so that `fit` reports show nominal against fitted.
fn parameter_table(wb: &Workbench, d: &Discovery) -> String {
    let documented = documented(wb, d);
    let steps: Vec<(Option<&str>, &[ParamEstimate])> = d
        .steps
        .iter()
        .map(|st| (st.added.as_deref(), st.params.as_slice()))
        .collect();
    let mut out = parameters_html(&documented, &steps);
    for (name, value, why) in wb.model().structure().fixed() {
        let _ = write!(
            out,
            "<p>{} = {} held: {}</p>",
            escape(&name),
            fmt_num(value),
            escape(&why)
        );
    }
    out
}

/// The parameter table of any criterion's steps: documented value, then value ± standard
/// error per step (`(effect added, parameters)`; held ones marked), so that `fit` reports show
/// nominal against fitted.
pub fn parameters_html(
    documented: &[Parameter],
    steps: &[(Option<&str>, &[ParamEstimate])],
) -> String {
    let mut names: Vec<String> = Vec::new();
    for (_, params) in steps {
        for p in params.iter() {
            if !names.contains(&p.name) {
                names.push(p.name.clone());
            }
        }
    }
    let mut out = String::from(
        "<h2>Parameters</h2><table><tr><th>parameter</th><th>unit</th><th>documented</th>",
    );
    for (added, _) in steps {
        let _ = write!(
            out,
            "<th>{}</th>",
            escape(added.unwrap_or("fitted, no effect added"))
        );
    }
    out.push_str("</tr>");
    for name in &names {
        let doc = documented.iter().find(|p| &p.name == name);
        let _ = write!(
            out,
            "<tr><td>{}</td><td>{}</td><td>{}</td>",
            escape(name),
            escape(doc.map_or("", |p| p.unit.as_str())),
            doc.map_or_else(|| "-".to_string(), |p| fmt_num(p.value))
        );
        for (_, params) in steps {
            let cell = match params.iter().find(|p| &p.name == name) {
                None => "-".to_string(),
                Some(p) if p.held => format!("{} (held)", fmt_num(p.value)),
                Some(p) => match p.std {
                    Some(sd) => format!("{} &plusmn; {}", fmt_num(p.value), fmt_num(sd)),
                    None => fmt_num(p.value),
                },
            };
            let _ = write!(out, "<td>{cell}</td>");
        }
        out.push_str("</tr>");
    }
    out.push_str("</table>");
    out
}

/// Samples of the measured-against-predicted time series.
const SERIES_SAMPLES: usize = 600;

/// Measured outputs against the Kalman predictor's k-step predictions of the first and the
/// last model (first experiment, first samples).
fn time_series(wb: &Workbench, d: &Discovery) -> String {
    let (Some(first), Some(last)) = (d.steps.first(), d.steps.last()) else {
        return String::new();
    };
    let k = last.time_fit.horizon_samples;
    let data = wb.data();
    let t = 1.0 / data.sample_rate_hz;
    let mut out = format!(
        "<h2>Time domain</h2><p>Measured outputs (deviations from the record mean) and the {k}-step prediction ({:.3} s) of the stationary Kalman predictor, experiment 1. Fit % per output and step is in the summary.</p>",
        k as f64 * t
    );
    let mut predicted = Vec::new();
    for st in [first, last] {
        let series = with_effects(wb, &st.effects)
            .and_then(|m| m.state_space(&st.theta))
            .and_then(|ss| super::timedomain::kalman_series(data, &ss, k, 0, SERIES_SAMPLES));
        match series {
            Ok(s) => predicted.push((st.added.clone().unwrap_or_else(|| "start".into()), s)),
            Err(e) => {
                let _ = write!(out, "<p>no prediction: {}</p>", escape(&e.to_string()));
                return out;
            }
        }
    }
    for (o, name) in data.outputs.iter().enumerate() {
        let (y, _) = &predicted[0].1;
        let mut series = vec![Series {
            name: "measured".into(),
            color: "#000000",
            points: (0..y.nrows()).map(|i| (i as f64 * t, y[(i, o)])).collect(),
            markers: false,
            band: None,
        }];
        for (j, (label, (_, yk))) in predicted.iter().enumerate() {
            if j == 1 && d.steps.len() == 1 {
                break;
            }
            series.push(Series {
                name: format!("{label}, {k}-step"),
                color: COLORS[(if j == 0 { 0 } else { d.steps.len() - 1 }) % COLORS.len()],
                points: (k..yk.nrows())
                    .map(|i| (i as f64 * t, yk[(i, o)]))
                    .collect(),
                markers: false,
                band: None,
            });
        }
        out.push_str(&chart(
            &format!("{name}: measured and predicted"),
            TIME,
            name,
            &series,
        ));
    }
    out
}

/// Autocorrelation of the last step's residual per output with its 99% band.
fn autocorrelation(d: &Discovery) -> String {
    let Some(st) = d.steps.last() else {
        return String::new();
    };
    let r = &st.residual_tests;
    let mut out = format!(
        "<h2>Residual autocorrelation</h2><p>{} of the last model, lags 1-{}; dashed: the 99% band for white noise (&plusmn;{:.4}).</p>",
        escape(&r.residual),
        r.lags,
        r.channels.first().map_or(0.0, |c| c.whiteness.band)
    );
    for c in &r.channels {
        let band = c.whiteness.band;
        let lags = 1..c.whiteness.correlation.len();
        let series = [
            Series {
                name: if c.not_white {
                    "not white".into()
                } else {
                    "white".into()
                },
                color: COLORS[0],
                points: lags
                    .clone()
                    .map(|l| (l as f64, c.whiteness.correlation[l]))
                    .collect(),
                markers: true,
                band: None,
            },
            Series {
                name: "+99% band".into(),
                color: "#999999",
                points: lags.clone().map(|l| (l as f64, band)).collect(),
                markers: false,
                band: None,
            },
            Series {
                name: "-99% band".into(),
                color: "#999999",
                points: lags.map(|l| (l as f64, -band)).collect(),
                markers: false,
                band: None,
            },
        ];
        out.push_str(&chart(
            &format!("{}: autocorrelation", c.output),
            LAG,
            "correlation",
            &series,
        ));
    }
    if let Some(c) = &r.coherence {
        let _ = write!(
            out,
            "<h2>Where the residual follows the excitation</h2><p>Squared coherence of the last model's residual with {} per frequency ({} segments of {} samples); dashed: the level above which a bin is flagged (1% over all bins and outputs).</p>",
            escape(&c.against),
            c.segments,
            c.segment
        );
        for o in &c.outputs {
            let series = [
                Series {
                    name: o.output.clone(),
                    color: COLORS[0],
                    points: o.bins.clone(),
                    markers: true,
                    band: None,
                },
                Series {
                    name: "flagged above".into(),
                    color: "#999999",
                    points: c.flag_above.clone(),
                    markers: false,
                    band: None,
                },
            ];
            out.push_str(&chart(
                &format!("{}: coherence", o.output),
                XAxis::linear("frequency (Hz)"),
                "squared coherence",
                &series,
            ));
        }
    }
    out
}

/// The HTML page around `body` (inline style, no scripts).
pub fn page(body: &str) -> String {
    format!("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>stabilis workbench</title><style>body{{font-family:sans-serif;max-width:1100px;margin:auto}} svg{{margin:4px}} pre{{background:#f4f4f4;padding:8px;overflow-x:auto}} td,th{{padding:2px 8px;text-align:right}}</style></head><body>{body}</body></html>")
}

/// "Error per step": one bar per step, height log10 of the weighted cost, with the level
/// noise alone gives as a dashed line when the criterion has one (the time criterion has not).
pub fn cost_bars(steps: &[(String, f64)], noise: Option<f64>) -> String {
    let mut body = String::from("<h2>Error per step</h2><svg xmlns=\"http://www.w3.org/2000/svg\" width=\"520\" height=\"220\" font-family=\"sans-serif\" font-size=\"11\">");
    let logs: Vec<f64> = steps.iter().map(|(_, c)| c.max(1e-300).log10()).collect();
    let noise = noise.map(|n| n.max(1e-300).log10());
    let max = logs
        .iter()
        .copied()
        .fold(noise.unwrap_or(1.0).max(1.0), f64::max)
        .ceil();
    let width = (440.0 / steps.len().max(1) as f64).min(90.0);
    for (i, ((label, cost), c)) in steps.iter().zip(&logs).enumerate() {
        let bh = 170.0 * c.max(0.0) / max;
        let x = 60.0 + width * i as f64;
        let _ = write!(
            body,
            r##"<rect x="{x}" y="{:.1}" width="{:.1}" height="{bh:.1}" fill="#1f77b4"/><text x="{}" y="212" text-anchor="middle">{}</text><text x="{}" y="{:.1}" text-anchor="middle">{}</text>"##,
            190.0 - bh,
            width * 2.0 / 3.0,
            x + width / 3.0,
            escape(label),
            x + width / 3.0,
            186.0 - bh,
            fmt_num(*cost)
        );
    }
    if let Some(noise) = noise {
        let ny = 190.0 - 170.0 * noise.max(0.0) / max;
        let _ = write!(
            body,
            r##"<line x1="50" x2="510" y1="{ny:.1}" y2="{ny:.1}" stroke="#d62728" stroke-dasharray="4"/><text x="510" y="{:.1}" text-anchor="end" fill="#d62728">noise level</text>"##,
            ny - 4.0
        );
    }
    body.push_str("</svg><p>Bar height: log10 of the weighted cost.</p>");
    body
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_labels_carry_the_digits_they_need() {
        let (step, ticks) = nice_ticks(-0.047, 0.042);
        assert_eq!(step, 0.02);
        let labels: Vec<String> = ticks.iter().map(|t| fmt_tick(*t, step)).collect();
        assert_eq!(labels, ["-0.04", "-0.02", "0", "0.02", "0.04"]);
        assert_eq!(nice_ticks(0.0, 5.99).1, [0.0, 2.0, 4.0]);
        assert_eq!(fmt_num(0.030113), "0.03011");
        assert_eq!(fmt_num(123592.1), "1.236e5");
        assert_eq!(fmt_num(-4.98e-5), "-4.980e-5");
    }

    /// A candidate's parameter count says why it differs from the effect's own.
    #[test]
    fn added_parameters_say_why_they_differ_from_the_effects_own() {
        assert_eq!(params_phrase(1, 1), "+1 params");
        assert_eq!(
            params_phrase(2, 1),
            "+2 params (its 1 and 1 of the model's it lets the data separate)"
        );
        assert_eq!(params_phrase(4, 6), "+4 params (of its 6, 2 held)");
    }

    proptest::proptest! {
        /// A printed percentage is never "-0.00", and otherwise reads as the value does.
        #[test]
        fn a_printed_percentage_is_never_negative_zero(x in -1.0f64..1.0) {
            let shown = format!("{:.2}", shown_percent(x));
            proptest::prop_assert_ne!(shown.as_str(), "-0.00");
            proptest::prop_assert!((shown.parse::<f64>().unwrap() - x).abs() <= 0.005 + 1e-12);
        }
    }
}
