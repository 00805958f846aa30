//! Forward selection, the loop every criterion's discovery runs: from the current model, fit
//! every remaining candidate effect, add the one the criterion admits, repeat until none is.
//! The FRF cost, the prediction error and the Cubli's window regression differ in how they fit
//! and score a candidate ([`Search`]), never in the loop.
use crate::discover::{in_parallel, CandidateScore};
use crate::error::{Result, SimError};

/// What a criterion gives the forward selection.
pub trait Search: Sync {
    /// A fitted model (with the scores of the candidates tried on it, once recorded).
    type Fit: Send + Sync;
    /// What the candidates of one step share (the current model's residuals, say).
    type Context: Sync;

    /// Candidate effects not yet in the model of `at`.
    fn candidates(&self, at: &Self::Fit) -> Vec<String>;

    /// The context of the step from `at`.
    fn context(&self, at: &Self::Fit) -> Result<Self::Context>;

    /// Fits the model of `at` with `effect` added and scores it against `at`; `n` candidates
    /// are tried on this step (for the Bonferroni correction).
    fn try_effect(
        &self,
        at: &Self::Fit,
        context: &Self::Context,
        effect: &str,
        n: usize,
    ) -> Result<(Self::Fit, CandidateScore)>;

    /// Which tried candidate to add, if any. By default the one of lowest cost (the first of
    /// equals), when it is significant: a less good candidate that is significant while the
    /// best is not would be chosen for its test, not for its fit.
    fn choose(&self, _at: &mut Self::Fit, tried: &[(Self::Fit, CandidateScore)]) -> Option<usize> {
        // Only a strictly lower cost displaces the earlier candidate (an equal or NaN one
        // does not).
        let best = (0..tried.len()).fold(None, |best: Option<usize>, i| match best {
            Some(b) if tried[i].1.cost < tried[b].1.cost => Some(i),
            Some(b) => Some(b),
            None => Some(i),
        })?;
        tried[best].1.significant.then_some(best)
    }

    /// Keeps the scores of the candidates tried on `at`.
    fn record_scores(&self, at: &mut Self::Fit, scores: Vec<CandidateScore>);

    /// The fit to go on from once the chosen candidate is added (by default its own fit).
    fn added(&self, chosen: Self::Fit, _effect: &str) -> Result<Self::Fit> {
        Ok(chosen)
    }

    /// Whether the candidates of a step are fitted on threads.
    fn parallel(&self) -> bool;
}

/// Runs the forward selection from `start`: the fits of every step (the start first, each
/// with the scores of the candidates tried on it) and the effects in the order added.
/// `progress` hears one message per candidate tried and per effect added.
pub fn forward_selection<S: Search>(
    search: &S,
    start: S::Fit,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<S::Fit>, Vec<String>)> {
    let mut current = start;
    let mut done = Vec::new();
    let mut added = Vec::new();
    loop {
        let names = search.candidates(&current);
        let n = names.len();
        let context = search.context(&current)?;
        let jobs: Vec<_> = names
            .iter()
            .map(|name| {
                let (at, context) = (&current, &context);
                move || search.try_effect(at, context, name, n)
            })
            .collect();
        let mut tried = in_parallel(search.parallel(), jobs, "candidate fit")?;
        for (_, score) in &tried {
            progress(&format!("tried {}", score.effect));
        }
        let chosen = search.choose(&mut current, &tried);
        search.record_scores(&mut current, tried.iter().map(|(_, s)| s.clone()).collect());
        let Some(i) = chosen else { break };
        if i >= tried.len() {
            return Err(SimError::invalid(
                "discovery",
                i,
                format!("chose a candidate of {} tried", tried.len()),
            ));
        }
        let (fit, score) = tried.swap_remove(i);
        progress(&format!("adding {}", score.effect));
        let next = search.added(fit, &score.effect)?;
        added.push(score.effect);
        done.push(std::mem::replace(&mut current, next));
    }
    done.push(current);
    Ok((done, added))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Effects with fixed cost reductions: each step adds the best remaining one while its
    /// reduction is significant.
    struct Table {
        gains: Vec<(&'static str, f64, bool)>,
    }

    impl Search for Table {
        type Fit = (Vec<String>, f64, Vec<CandidateScore>);
        type Context = ();

        fn candidates(&self, at: &Self::Fit) -> Vec<String> {
            self.gains
                .iter()
                .filter(|(n, _, _)| !at.0.iter().any(|e| e == n))
                .map(|(n, _, _)| n.to_string())
                .collect()
        }

        fn context(&self, _: &Self::Fit) -> Result<()> {
            Ok(())
        }

        fn try_effect(
            &self,
            at: &Self::Fit,
            _: &(),
            effect: &str,
            _: usize,
        ) -> Result<(Self::Fit, CandidateScore)> {
            let &(_, gain, significant) = self
                .gains
                .iter()
                .find(|(n, _, _)| *n == effect)
                .ok_or_else(|| SimError::invalid("effect", effect, "unknown"))?;
            let mut effects = at.0.clone();
            effects.push(effect.to_string());
            let cost = at.1 - gain;
            let score = CandidateScore {
                effect: effect.to_string(),
                cost,
                reduction_percent: 100.0 * gain / at.1,
                added_parameters: 1,
                f_statistic: 0.0,
                p_value: 1.0,
                robust_p_value: 1.0,
                delta_aic: 0.0,
                delta_bic: 0.0,
                exceeds_noise: significant,
                passes_tests: significant,
                significant,
                abandoned: false,
                noise_spread: 1.0,
                scale: 1.0,
            };
            Ok(((effects, cost, Vec::new()), score))
        }

        fn record_scores(&self, at: &mut Self::Fit, scores: Vec<CandidateScore>) {
            at.2 = scores;
        }

        fn parallel(&self) -> bool {
            true
        }
    }

    #[test]
    fn adds_the_best_significant_candidates_in_order_and_stops_at_an_insignificant_best() {
        let table = Table {
            gains: vec![("a", 10.0, true), ("b", 30.0, true), ("c", 1.0, false)],
        };
        let mut heard = Vec::new();
        let (steps, added) =
            forward_selection(&table, (Vec::new(), 100.0, Vec::new()), &mut |m: &str| {
                heard.push(m.to_string())
            })
            .unwrap();
        assert_eq!(added, ["b", "a"]);
        assert_eq!(steps.len(), 3);
        assert_eq!(steps[2].1, 60.0);
        // Every step keeps the scores of what it tried: 3, then 2, then 1 candidates.
        let tried: Vec<usize> = steps.iter().map(|s| s.2.len()).collect();
        assert_eq!(tried, [3, 2, 1]);
        assert!(heard.contains(&"adding b".to_string()));
        // The lowest cost decides, not the test: an insignificant best stops the loop.
        let table = Table {
            gains: vec![("a", 10.0, true), ("b", 30.0, false)],
        };
        let (_, added) =
            forward_selection(&table, (Vec::new(), 100.0, Vec::new()), &mut |_: &str| {}).unwrap();
        assert!(added.is_empty());
    }
}
