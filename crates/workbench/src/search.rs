//! Forward selection, the loop every criterion's discovery runs: from the current model, fit
//! every remaining candidate effect, add the one the criterion admits, repeat until none is.
//! The FRF cost, the prediction error and the Cubli's window regression differ in how they fit
//! and score a candidate ([`Search`]), never in the loop.
use crate::discover::{in_parallel, worth_following, CandidateScore, Followed};
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
/// `progress` hears one message per candidate tried, per effect added and per rival followed.
///
/// Greedy selection commits to the best candidate of each step, and two that remove nearly
/// the same misfit may part only later: a delay and a lag tell little apart until friction is
/// in the model, where only the true one explains the data. So when a step's chosen candidate
/// has a runner-up worth following ([`worth_following`]: significant, and a rival or within a
/// tenth of its cost reduction), the runner-up is followed too, through a search of its own
/// (which follows no further ones). The search that added fewer effects is kept, of two
/// that added as many the one of lower BIC (the step's and the later steps' changes summed):
/// each search admits an effect only by the criterion's tests, and BIC alone would let one
/// through that the effect-size rule kept out. The loser's score keeps what its search found
/// ([`CandidateScore::followed`]).
pub fn forward_selection<S: Search>(
    search: &S,
    start: S::Fit,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<S::Fit>, Vec<String>)> {
    let path = select(search, start, progress, true)?;
    Ok((path.steps, path.added))
}

/// The steps of one search, the effects it added and the BIC change they made in all.
struct Path<F> {
    steps: Vec<F>,
    added: Vec<String>,
    bic: f64,
}

/// The search from `current`; `follow`: whether it follows rivals.
fn select<S: Search>(
    search: &S,
    mut current: S::Fit,
    progress: &mut dyn FnMut(&str),
    follow: bool,
) -> Result<Path<S::Fit>> {
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
    let tried = in_parallel(search.parallel(), jobs, "candidate fit")?;
    for (_, score) in &tried {
        progress(&format!("tried {}", score.effect));
    }
    let chosen = search.choose(&mut current, &tried);
    let (fits, mut scores): (Vec<_>, Vec<_>) = tried.into_iter().unzip();
    let Some(i) = chosen else {
        search.record_scores(&mut current, scores);
        return Ok(Path {
            steps: vec![current],
            added: Vec::new(),
            bic: 0.0,
        });
    };
    if i >= scores.len() {
        return Err(SimError::invalid(
            "discovery",
            i,
            format!("chose a candidate of {} tried", scores.len()),
        ));
    }
    // The runner-up of lowest cost, if one is worth following.
    let rival = follow
        .then(|| {
            (0..scores.len())
                .filter(|&j| worth_following(&scores[i], &scores[j]))
                .min_by(|&a, &b| scores[a].cost.total_cmp(&scores[b].cost))
        })
        .flatten();
    let mut fits: Vec<Option<S::Fit>> = fits.into_iter().map(Some).collect();
    let mut branch = |k: usize, follow: bool, progress: &mut dyn FnMut(&str)| {
        let fit = fits[k].take().ok_or_else(|| {
            SimError::invalid("discovery", k, "a candidate's fit was taken twice")
        })?;
        let effect = scores[k].effect.clone();
        progress(&format!("adding {effect}"));
        let rest = select(search, search.added(fit, &effect)?, progress, follow)?;
        Ok::<_, SimError>((k, rest.bic + scores[k].delta_bic, rest))
    };
    let mut best = branch(i, follow, progress)?;
    if let Some(j) = rival {
        progress(&format!(
            "following {} in place of {}",
            scores[j].effect, scores[i].effect
        ));
        let other = branch(j, false, progress)?;
        // Fewer effects first, then the lower BIC.
        let (winner, loser) = if (other.2.added.len(), other.1) < (best.2.added.len(), best.1) {
            (other, best)
        } else {
            (best, other)
        };
        let mut found = vec![scores[loser.0].effect.clone()];
        found.extend(loser.2.added);
        scores[loser.0].followed = Some(Followed::against(
            found,
            loser.1,
            winner.2.added.len() + 1,
            winner.1,
        ));
        best = winner;
    }
    let (k, bic, rest) = best;
    let effect = scores[k].effect.clone();
    search.record_scores(&mut current, scores);
    let mut steps = vec![current];
    steps.extend(rest.steps);
    let mut added = vec![effect];
    added.extend(rest.added);
    Ok(Path { steps, added, bic })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A criterion scripted by the effects in the model: its cost, and whether adding an
    /// effect that lowers it by a gain is significant. Each added effect costs 5 in BIC and one
    /// residual's noise variance is 1 (so rivals are within 26.5).
    struct Scripted {
        effects: Vec<&'static str>,
        cost: Box<CostOf>,
        significant: Box<SignificantAt>,
    }

    /// The cost of a model with these effects.
    type CostOf = dyn Fn(&[String]) -> f64 + Sync;
    /// Whether adding an effect that lowers the cost by a gain is significant.
    type SignificantAt = dyn Fn(&str, f64) -> bool + Sync;

    impl Scripted {
        /// Effects with fixed cost reductions from 100, each significant or not.
        fn gains(gains: Vec<(&'static str, f64, bool)>) -> Self {
            let table = gains.clone();
            Self {
                effects: gains.iter().map(|g| g.0).collect(),
                cost: Box::new(move |effects: &[String]| {
                    100.0
                        - effects
                            .iter()
                            .filter_map(|e| table.iter().find(|g| g.0 == e))
                            .map(|g| g.1)
                            .sum::<f64>()
                }),
                significant: Box::new(move |effect: &str, _| {
                    gains.iter().any(|g| g.0 == effect && g.2)
                }),
            }
        }

        /// Costs by the set of effects, which interact (as a lag and a delay do with
        /// friction); an effect is significant when it removes more than 20.
        fn sets(costs: Vec<(&'static [&'static str], f64)>) -> Self {
            Self {
                effects: vec!["delay", "lag", "friction"],
                cost: Box::new(move |effects: &[String]| {
                    let mut key: Vec<&str> = effects.iter().map(String::as_str).collect();
                    key.sort_unstable();
                    costs
                        .iter()
                        .find(|(set, _)| {
                            let mut set = set.to_vec();
                            set.sort_unstable();
                            set == key
                        })
                        .map_or(f64::NAN, |(_, c)| *c)
                }),
                significant: Box::new(|_, gain| gain > 20.0),
            }
        }
    }

    impl Search for Scripted {
        type Fit = (Vec<String>, f64, Vec<CandidateScore>);
        type Context = ();

        fn candidates(&self, at: &Self::Fit) -> Vec<String> {
            self.effects
                .iter()
                .filter(|n| !at.0.iter().any(|e| e == *n))
                .map(|n| n.to_string())
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
            let mut effects = at.0.clone();
            effects.push(effect.to_string());
            let cost = (self.cost)(&effects);
            let gain = at.1 - cost;
            let significant = (self.significant)(effect, gain);
            let score = CandidateScore {
                effect: effect.to_string(),
                cost,
                reduction_percent: 100.0 * gain / at.1,
                added_parameters: 1,
                f_statistic: 0.0,
                p_value: 1.0,
                robust_p_value: 1.0,
                delta_aic: 0.0,
                delta_bic: 5.0 - gain,
                exceeds_noise: significant,
                passes_tests: significant,
                significant,
                abandoned: false,
                noise_spread: 1.0,
                scale: 1.0,
                followed: None,
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
        let table = Scripted::gains(vec![
            ("a", 10.0, true),
            ("b", 30.0, true),
            ("c", 1.0, false),
        ]);
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
        let table = Scripted::gains(vec![("a", 10.0, true), ("b", 30.0, false)]);
        let (_, added) =
            forward_selection(&table, (Vec::new(), 100.0, Vec::new()), &mut |_: &str| {}).unwrap();
        assert!(added.is_empty());
    }

    /// The greedy pick (delay, by 1) and its rival (lag) part once friction is in: the lag's
    /// search stops at lag and friction (cost 400), the delay's needs the lag too (398), so
    /// the lag's is kept and the delay is ruled out. Of two searches that add as many
    /// effects, the lower BIC is kept, and the loser stays a rival within 9.2; a search with
    /// more effects loses even at a lower BIC; a runner-up that is neither a rival nor within
    /// a tenth of the chosen one's reduction is not followed.
    #[test]
    fn a_runner_up_is_followed_and_the_search_of_fewer_effects_then_lower_bic_kept() {
        let costs = |delay_friction: f64, gap: f64| {
            Scripted::sets(vec![
                (&[], 1000.0),
                (&["delay"], 700.0),
                (&["lag"], 700.0 + gap),
                (&["friction"], 950.0),
                (&["delay", "lag"], 690.0),
                (&["delay", "friction"], delay_friction),
                (&["lag", "friction"], 400.0),
                (&["delay", "lag", "friction"], 398.0),
            ])
        };
        let start = || (Vec::new(), 1000.0, Vec::new());
        let mut heard = Vec::new();
        let (steps, added) = forward_selection(&costs(650.0, 1.0), start(), &mut |m: &str| {
            heard.push(m.to_string())
        })
        .unwrap();
        assert_eq!(added, ["lag", "friction"]);
        assert_eq!(steps.len(), 3);
        assert_eq!(steps[2].1, 400.0);
        let followed = |steps: &[(Vec<String>, f64, Vec<CandidateScore>)], effect: &str| {
            let c = steps[0].2.iter().find(|c| c.effect == effect).unwrap();
            let f = c.followed.clone().unwrap();
            (f.added, f.bic, f.ruled_out)
        };
        let names = |n: &[&str]| n.iter().map(|e| e.to_string()).collect::<Vec<_>>();
        assert_eq!(
            followed(&steps, "delay"),
            (names(&["delay", "friction", "lag"]), 3.0, true)
        );
        assert!(steps[0]
            .2
            .iter()
            .all(|c| c.effect == "delay" || c.followed.is_none()));
        assert!(heard.contains(&"following lag in place of delay".to_string()));
        // Friction explains as much after the delay: two effects each, the delay's search
        // 1 lower in BIC is kept, and the lag stays a rival.
        let (steps, added) =
            forward_selection(&costs(399.0, 1.0), start(), &mut |_: &str| {}).unwrap();
        assert_eq!(added, ["delay", "friction"]);
        assert_eq!(
            followed(&steps, "lag"),
            (names(&["lag", "friction"]), 1.0, false)
        );
        // 28 behind, the lag is no rival (26.5) but within a tenth of the delay's reduction
        // (30): followed, and kept.
        let (_, added) =
            forward_selection(&costs(650.0, 28.0), start(), &mut |_: &str| {}).unwrap();
        assert_eq!(added, ["lag", "friction"]);
        // 40 behind, neither: not followed, the greedy search stands with its superfluous
        // delay.
        let mut heard = Vec::new();
        let (steps, added) = forward_selection(&costs(650.0, 40.0), start(), &mut |m: &str| {
            heard.push(m.to_string())
        })
        .unwrap();
        assert_eq!(added, ["delay", "friction", "lag"]);
        assert!(steps
            .iter()
            .flat_map(|s| &s.2)
            .all(|c| c.followed.is_none()));
        assert!(
            !heard.iter().any(|m| m.starts_with("following")),
            "{heard:?}"
        );
        // The lag alone, then the delay 15 below it is not significant (20); after the
        // delay, the lag 25 below is: the delay's search reaches a BIC 10 lower with two
        // effects, and the lag's one effect is kept.
        let one = Scripted::sets(vec![
            (&[], 1000.0),
            (&["lag"], 700.0),
            (&["delay"], 710.0),
            (&["friction"], 990.0),
            (&["delay", "lag"], 685.0),
            (&["lag", "friction"], 699.0),
            (&["delay", "friction"], 709.0),
            (&["delay", "lag", "friction"], 684.0),
        ]);
        let (steps, added) = forward_selection(&one, start(), &mut |_: &str| {}).unwrap();
        assert_eq!(added, ["lag"]);
        assert_eq!(
            followed(&steps, "delay"),
            (names(&["delay", "lag"]), -10.0, true)
        );
    }
}
