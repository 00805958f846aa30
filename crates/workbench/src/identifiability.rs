//! Which parameters the outputs cannot separate: the directions in parameter space along
//! which the frequency response does not change (to first order), from the singular values
//! of its Jacobian over a frequency grid that spans the model's time scales, and which of them
//! a fit would hold at its documented value (the fit's own rule, [`crate::fit::holds`]).
use nalgebra::DMatrix;
use serde::Serialize;

use super::fit::{holds, FitOptions};
use super::model::Model;
use crate::error::{Result, SimError};

/// Singular values below this fraction of the largest count as zero.
pub const RELATIVE_RANK_TOLERANCE: f64 = 1e-7;

/// A parameter counts as part of a direction when its component exceeds this fraction of the
/// largest: every parameter the combination moves is named (on a two-wheeled robot the body
/// inertia weighs 0.045 against the masses' 0.70 on unit-norm columns, and a fit on data may
/// hold it), while rounding leaves the others near 1e-9.
const INVOLVED: f64 = 1e-3;

/// One combination of parameters the outputs do not see.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Combination {
    /// Each parameter that moves in it with its component (unit-norm Jacobian columns, the
    /// largest positive), model order.
    pub weights: Vec<(String, f64)>,
}

/// What the outputs can tell apart.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Identifiability {
    /// Frequencies of the analysis, Hz.
    pub freqs_hz: Vec<f64>,
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Parameters that do not change the response at all.
    pub no_effect: Vec<String>,
    /// Groups of parameters of which the outputs see fewer combinations than there are
    /// parameters (each the support of a direction without effect).
    pub unseparated: Vec<Vec<String>>,
    /// The directions without effect themselves, each with the group of `unseparated` it
    /// moves (a group of five parameters of which the outputs see three combinations has two).
    pub combinations: Vec<Combination>,
    /// The parameters a fit holds at their documented values, in the order it holds them, if
    /// its Jacobian were this one ([`crate::fit::holds`] at the fit's rank tolerance): one per
    /// unseen combination, and any without effect. On data a fit weighs the combination by
    /// the data's Jacobian, so it may hold another parameter of the same combination.
    pub holds: Vec<String>,
}

/// A logarithmic grid of 48 frequencies from a tenth of the slowest to ten times the fastest
/// eigenvalue of the documented model (0.01-100 rad/s for a model of integrators only).
fn grid(model: &Model, theta: &[f64]) -> Result<Vec<f64>> {
    let a = model.state_space(theta)?.a;
    let mags: Vec<f64> = rigid_body::lti::eigenvalues(&a)?
        .iter()
        .map(|l| l.norm())
        .filter(|m| *m > 1e-9)
        .collect();
    let lo = mags.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = mags.iter().cloned().fold(0.0, f64::max);
    let (lo, hi) = if mags.is_empty() {
        (0.01, 100.0)
    } else {
        (lo / 10.0, hi * 10.0)
    };
    let n = 48;
    Ok((0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64) / (2.0 * std::f64::consts::PI))
        .collect())
}

/// Analyses `model` at `theta` (its parameters in [`Model::parameters`] order).
pub fn analyse(model: &Model, theta: &[f64]) -> Result<Identifiability> {
    let params = model.parameters()?;
    let freqs_hz = grid(model, theta)?;
    let (_, jac) = model.frf_with_jacobian(theta, &freqs_hz, None)?;
    let np = params.len();
    let entries = jac.first().and_then(|j| j.first()).map_or(0, |g| g.len());
    let mut m = DMatrix::zeros(2 * entries * freqs_hz.len(), np);
    for (k, per_param) in jac.iter().enumerate() {
        for (i, dg) in per_param.iter().enumerate() {
            let s = params[i].scale();
            for (e, v) in dg.iter().enumerate() {
                let row = 2 * (k * entries + e);
                m[(row, i)] = v.re * s;
                m[(row + 1, i)] = v.im * s;
            }
        }
    }
    if let Some(i) = (0..np).find(|&i| m.column(i).iter().any(|v| !v.is_finite())) {
        return Err(SimError::invalid(
            "identifiability",
            &params[i].name,
            "the FRF's derivative by it is not finite at the documented values (a pole on the frequency grid, or a model that overflows)",
        ));
    }
    let norms: Vec<f64> = (0..np).map(|i| m.column(i).norm()).collect();
    let biggest = norms.iter().cloned().fold(0.0, f64::max);
    let no_effect: Vec<String> = (0..np)
        .filter(|&i| norms[i] <= RELATIVE_RANK_TOLERANCE * biggest)
        .map(|i| params[i].name.clone())
        .collect();
    // Directions among the parameters that do act, on unit-norm columns so that the
    // threshold compares like with like.
    let acting: Vec<usize> = (0..np)
        .filter(|&i| norms[i] > RELATIVE_RANK_TOLERANCE * biggest)
        .collect();
    let mut unseparated = Vec::new();
    let mut combinations = Vec::new();
    let mut singular_values = Vec::new();
    if !acting.is_empty() {
        let mut n = DMatrix::zeros(m.nrows(), acting.len());
        for (c, &i) in acting.iter().enumerate() {
            n.set_column(c, &(m.column(i) / norms[i]));
        }
        let svd = n.svd(false, true);
        let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
        order.sort_by(|a, b| svd.singular_values[*b].total_cmp(&svd.singular_values[*a]));
        singular_values = order.iter().map(|&k| svd.singular_values[k]).collect();
        let top = singular_values.first().copied().unwrap_or(0.0);
        if let Some(vt) = &svd.v_t {
            for &k in &order {
                if svd.singular_values[k] <= RELATIVE_RANK_TOLERANCE * top {
                    let row = vt.row(k);
                    let most = row.amax();
                    let sign = if row.iter().any(|v| *v >= most) {
                        1.0
                    } else {
                        -1.0
                    };
                    let weights: Vec<(String, f64)> = (0..acting.len())
                        .filter(|&c| vt[(k, c)].abs() > INVOLVED * most)
                        .map(|c| (params[acting[c]].name.clone(), sign * vt[(k, c)]))
                        .collect();
                    let group: Vec<String> = weights.iter().map(|(n, _)| n.clone()).collect();
                    if !unseparated.contains(&group) {
                        unseparated.push(group);
                    }
                    combinations.push(Combination { weights });
                }
            }
        }
    }
    let holds = holds(&m, FitOptions::default().rank_tolerance)
        .into_iter()
        .map(|i| params[i].name.clone())
        .collect();
    Ok(Identifiability {
        freqs_hz,
        singular_values,
        no_effect,
        unseparated,
        combinations,
        holds,
    })
}

/// A candidate effect whose parameters the outputs cannot tell from the model it would join.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Alias {
    /// The effect.
    pub effect: String,
    /// Its parameters that the outputs do not see apart (or at all).
    pub parameters: Vec<String>,
    /// The model's parameters they trade against (empty when they do not act on the outputs).
    pub with: Vec<String>,
}

/// The candidates of `model` the FRF can test ([`Model::frf_candidates`]) whose parameters,
/// added at the documented values, act on the outputs not at all or only in a combination
/// with the model's own that the model alone does not already leave unseen: discovery can
/// then add them only in place of those (a viscous friction on a cart whose back-EMF term is
/// the same `-c xdot`). A candidate whose analysis fails (a derivative not finite at the
/// documented values) is left out: the check of the model itself reports such failures.
pub fn aliases(model: &Model) -> Result<Vec<Alias>> {
    let base_id = analyse(model, &model.documented()?)?;
    let mut found = Vec::new();
    for effect in model.frf_candidates() {
        let Ok(with) = model.with_effect(&effect) else {
            continue;
        };
        let Ok(id) = with.documented().and_then(|theta| analyse(&with, &theta)) else {
            continue;
        };
        let own = with.effect_parameters(&effect)?;
        let mut parameters: Vec<String> = own
            .iter()
            .filter(|p| id.no_effect.contains(p))
            .cloned()
            .collect();
        let mut partners: Vec<String> = Vec::new();
        for group in id
            .unseparated
            .iter()
            .filter(|g| !base_id.unseparated.contains(g) && g.iter().any(|n| own.contains(n)))
        {
            for name in group {
                let list = if own.contains(name) {
                    &mut parameters
                } else {
                    &mut partners
                };
                if !list.contains(name) {
                    list.push(name.clone());
                }
            }
        }
        if !parameters.is_empty() {
            found.push(Alias {
                effect,
                parameters,
                with: partners,
            });
        }
    }
    Ok(found)
}

/// Pairs of candidates the outputs cannot tell apart: with the first in the model, the
/// second's parameters trade against the first's ([`aliases`]). A smoothed dry friction
/// linearized at rest is a viscous one: a discovery that adds either names the other its
/// rival.
pub fn rival_pairs(model: &Model) -> Result<Vec<(String, String)>> {
    let candidates = model.frf_candidates();
    let mut pairs = Vec::new();
    for (i, first) in candidates.iter().enumerate() {
        let Ok(with) = model.with_effect(first) else {
            continue;
        };
        let own = with.effect_parameters(first)?;
        for alias in aliases(&with)? {
            if candidates[i + 1..].contains(&alias.effect)
                && alias.with.iter().any(|n| own.contains(n))
            {
                pairs.push((first.clone(), alias.effect));
            }
        }
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use super::*;
    use crate::ModelFile;

    /// A cart whose damping `c` the file already has: effects adding another `-b v / m` are
    /// aliases of c, a spring to ground is not, and neither are the generic input lag and
    /// delay. Without c in the file, the two extra dampings are rivals of each other instead.
    #[test]
    fn an_effect_that_repeats_a_term_of_the_model_is_its_alias() {
        let text = r#"
name = "cart"
states = ["x", "v"]
inputs = ["F"]
outputs = ["x"]
[parameters]
m = { value = 1.0, min = 0.1, max = 10.0 }
c = { value = 0.5, min = 0.0, max = 10.0 }
[linear]
A = [[0, 1], [0, "-c/m"]]
B = [[0], ["1/m"]]
C = [[1, 0]]
[effects.belt_damping]
description = "the belt's viscous damping"
parameters = { b = { value = 0.2, min = 0.0, max = 10.0 } }
A = { "v,v" = "-b/m" }
[effects.bearing_damping]
description = "the bearings' viscous damping"
parameters = { d = { value = 0.1, min = 0.0, max = 10.0 } }
A = { "v,v" = "-d/m" }
[effects.spring]
description = "a spring to ground"
parameters = { k = { value = 2.0, min = 0.0, max = 10.0 } }
A = { "v,x" = "-k/m" }
"#;
        let model = |text: &str| {
            Model::new(Arc::new(
                ModelFile::parse(text, Path::new("cart.toml")).unwrap(),
            ))
        };
        let damped = model(text);
        let alias = |effect: &str, p: &str| Alias {
            effect: effect.into(),
            parameters: vec![p.into()],
            with: vec!["c".into()],
        };
        assert_eq!(
            aliases(&damped).unwrap(),
            vec![alias("belt_damping", "b"), alias("bearing_damping", "d")]
        );
        let undamped = model(
            &text
                .replace(r#"[0, "-c/m"]"#, "[0, 0]")
                .replace("c = { value = 0.5, min = 0.0, max = 10.0 }\n", ""),
        );
        assert!(aliases(&undamped).unwrap().is_empty());
        assert_eq!(
            rival_pairs(&undamped).unwrap(),
            vec![("belt_damping".to_string(), "bearing_damping".to_string())]
        );
    }

    /// `G = (1/Jp) / (s^2 - m g l / Jp)` with `Jp = J + m l^2`: the response fixes two
    /// combinations of m, l, J, so the three are one unseparated group; a parameter that enters
    /// no matrix has no effect.
    #[test]
    fn the_pendulum_separates_two_of_its_three_parameters() {
        let text = r#"
name = "pendulum"
states = ["theta", "omega"]
inputs = ["T"]
outputs = ["theta"]
[parameters]
m = { value = 0.5, min = 0.01 }
l = 0.4
J = { value = 0.02, min = 0.0 }
g = { value = 9.81, fixed = true }
unused = 3.0
[definitions]
Jp = "J + m*l^2"
[linear]
A = [[0, 1], ["m*g*l/Jp", 0]]
B = [[0], ["1/Jp"]]
C = [[1, 0]]
"#;
        let file = ModelFile::parse(text, Path::new("p.toml")).unwrap();
        let model = Model::new(Arc::new(file));
        let id = analyse(&model, &model.documented().unwrap()).unwrap();
        assert_eq!(id.no_effect, ["unused"]);
        assert_eq!(id.unseparated, vec![vec!["m", "l", "J"]]);
        // A fit holds the parameter without effect and one of the combination, by the fit's
        // own rule on this Jacobian.
        assert_eq!(id.holds.len(), 2);
        assert_eq!(id.holds[0], "unused");
        assert!(id.unseparated[0].contains(&id.holds[1]), "{:?}", id.holds);
        assert_eq!(id.singular_values.len(), 3);
        assert!(id.singular_values[1] > 1e-3 * id.singular_values[0]);
    }

    /// A two-wheeled robot linearized upright: the response sees `Mx + m`, `m l`, `J + m l^2`
    /// and `r`, so one combination of Mx, m, l and J is unseen. The check names all four (J
    /// weighs 0.045 against the masses' 0.70: a threshold of 0.05 left it out, while the fit
    /// on data held it) and the parameter a fit holds by the fit's own rule (m here, of Mx and
    /// m, which weigh at least a quarter of the most; r takes no part).
    #[test]
    fn every_parameter_of_an_unseen_combination_is_named_with_the_one_a_fit_holds() {
        let text = r#"
name = "segway"
states = ["x", "xdot", "theta", "thetadot"]
inputs = ["T"]
outputs = ["x", "theta"]
[parameters]
Mx = { value = 0.6, min = 0.05, max = 5.0 }
m = { value = 1.5, min = 0.1, max = 10.0 }
l = { value = 0.12, min = 0.01, max = 1.0 }
J = { value = 0.02, min = 0.0, max = 0.5 }
r = { value = 0.05, min = 0.01, max = 0.5 }
g = { value = 9.81, fixed = true }
[definitions]
a = "Mx + m"
c = "m*l"
d = "J + m*l^2"
Delta = "a*d - c^2"
[linear]
A = [[0, 1, 0, 0], [0, 0, "-c^2*g/Delta", 0], [0, 0, 0, 1], [0, 0, "a*c*g/Delta", 0]]
B = [[0], ["(d/r + c)/Delta"], [0], ["-(a + c/r)/Delta"]]
C = [[1, 0, 0, 0], [0, 0, 1, 0]]
"#;
        let file = ModelFile::parse(text, Path::new("segway.toml")).unwrap();
        let model = Model::new(Arc::new(file));
        let id = analyse(&model, &model.documented().unwrap()).unwrap();
        assert_eq!(id.unseparated, vec![vec!["Mx", "m", "l", "J"]]);
        let w = &id.combinations[0].weights;
        assert_eq!(w.len(), 4);
        // Along the combination Mx and m move against each other, J with m.
        assert!(w[0].1 * w[1].1 < 0.0 && w[1].1 * w[3].1 > 0.0, "{w:?}");
        assert!(w[3].1.abs() < 0.05 && w[3].1.abs() > 0.03, "{w:?}");
        assert_eq!(id.holds, ["m"]);

        // A wheel inertia seen only through `Mx + Iw/r^2` (r measured) adds a second unseen
        // combination of the same five parameters: both are reported (one was), and a fit
        // holds two.
        let text = text
            .replace(
                "r = { value = 0.05, min = 0.01, max = 0.5 }",
                "Iw = { value = 0.002, min = 0.0, max = 0.1 }\nr = { value = 0.05, fixed = true }",
            )
            .replace("a = \"Mx + m\"", "a = \"Mx + Iw/r^2 + m\"");
        let file = ModelFile::parse(&text, Path::new("segway.toml")).unwrap();
        let model = Model::new(Arc::new(file));
        let id = analyse(&model, &model.documented().unwrap()).unwrap();
        assert_eq!(id.combinations.len(), 2, "{id:?}");
        assert_eq!(id.holds.len(), 2, "{id:?}");
        for c in &id.combinations {
            let group: Vec<&String> = c.weights.iter().map(|(n, _)| n).collect();
            assert!(id
                .unseparated
                .iter()
                .any(|g| g.iter().eq(group.iter().copied())));
        }
    }
}
