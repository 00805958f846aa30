//! `stabilis model check FILE`: a model file at its documented values: the matrices, the
//! eigenvalues (which are unstable, which lie on the imaginary axis), the effects discovery will try, and which parameters the
//! outputs cannot separate.
use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::{Complex, DMatrix};
use serde_json::json;

use super::Output;
use crate::error::Result;
use workbench::identifiability;
use workbench::{Drift, Model, ModelFile, ModelStructure};

/// Verbs on model files.
#[derive(Debug, Clone, PartialEq, clap::Subcommand)]
pub enum Command {
    /// Reads a model file and reports its matrices, eigenvalues and identifiability.
    Check(CheckArgs),
}

/// Options of `stabilis model check`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct CheckArgs {
    /// The model file (TOML).
    pub file: PathBuf,
}

impl Command {
    /// Runs the verb.
    pub fn run(&self) -> Result<Output> {
        match self {
            Self::Check(args) => args.run(),
        }
    }
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect())
        .collect()
}

fn render(name: &str, m: &DMatrix<f64>) -> String {
    let mut out = format!("{name} =\n");
    for i in 0..m.nrows() {
        let row: Vec<String> = m.row(i).iter().map(|v| format!("{v:>12.5e}")).collect();
        out.push_str(&format!("  [{}]\n", row.join(" ")));
    }
    out
}

/// Real parts within `1e-9 max(1, |A|)` (Frobenius norm) of zero are taken as zero: rounding
/// leaves the eigenvalues of a double integrator at +-1e-17, not 0.
const EIGENVALUE_TOLERANCE: f64 = 1e-9;

/// The tolerance on real parts and the eigenvalues `eig` of `a` that are unstable (real part
/// above it) and on the imaginary axis (within it).
fn classify(a: &DMatrix<f64>, eig: &[Complex<f64>]) -> (f64, Vec<Complex<f64>>, Vec<Complex<f64>>) {
    let tolerance = EIGENVALUE_TOLERANCE * a.norm().max(1.0);
    let unstable = eig.iter().copied().filter(|l| l.re > tolerance).collect();
    let marginal = eig
        .iter()
        .copied()
        .filter(|l| l.re.abs() <= tolerance)
        .collect();
    (tolerance, unstable, marginal)
}

impl CheckArgs {
    /// Reads and analyses the file.
    pub fn run(&self) -> Result<Output> {
        let file = Arc::new(ModelFile::from_path(&self.file)?);
        let ss = file.documented_state_space(&[])?;
        let model = Model::new(file.clone());
        let params = model.parameters()?;
        let theta: Vec<f64> = params.iter().map(|p| p.value).collect();
        let id = identifiability::analyse(&model, &theta)?;
        let drift = model.drift(&theta)?;
        let silent = model.silent_outputs(&theta)?;
        let eig = ss.a.complex_eigenvalues();
        let (tolerance, unstable, marginal) = classify(&ss.a, eig.as_slice());
        let show = |ls: &[Complex<f64>]| -> String {
            ls.iter()
                .map(|l| format!("{:.5} {:+.5}i", l.re, l.im))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let pairs = |ls: &[Complex<f64>]| ls.iter().map(|l| [l.re, l.im]).collect::<Vec<_>>();
        let mut human = format!(
            "{} ({}): states {}, inputs {}, outputs {}\n",
            file.system(),
            self.file.display(),
            file.states().join(", "),
            file.inputs().join(", "),
            file.outputs().join(", ")
        );
        human.push_str("parameters (documented value [min, max] unit; held ones say why):\n");
        for p in &params {
            human.push_str(&format!(
                "  {} = {} [{}, {}] {}\n",
                p.name, p.value, p.lower, p.upper, p.unit
            ));
        }
        for (name, value, why) in file.fixed() {
            human.push_str(&format!("  {name} = {value} (held: {why})\n"));
        }
        for (name, m) in [("A", &ss.a), ("B", &ss.b), ("C", &ss.c), ("D", &ss.d)] {
            human.push_str(&render(name, m));
        }
        let eig_text: Vec<String> = eig
            .iter()
            .map(|l| format!("{:.5} {:+.5}i", l.re, l.im))
            .collect();
        if !drift.is_empty() {
            human.push_str(&format!(
                "the operating point is not an equilibrium at the documented values: {}; the \
                 linearization above is not where a loop holds the plant, and an FRF fit's \
                 parameters absorb the difference: give the inputs that balance the model \
                 (a derivative counts above {:.0} % of its row's linear terms)\n",
                Drift::describe(&drift),
                100.0 * workbench::model::DRIFT_TOLERANCE
            ));
        }
        if !silent.is_empty() {
            human.push_str(&format!(
                "output {} depends on no state and no input (its row of C and D is zero): the \
                 model holds it constant, and discover, compare and fit refuse it\n",
                silent.join(", ")
            ));
        }
        human.push_str(&format!("eigenvalues of A: {}\n", eig_text.join(", ")));
        human.push_str(&if unstable.is_empty() {
            "no unstable eigenvalue\n".to_string()
        } else {
            format!(
                "unstable (real part > {tolerance:.1e}): {}\n",
                show(&unstable)
            )
        });
        if !marginal.is_empty() {
            human.push_str(&format!(
                "on the imaginary axis (|real part| <= {tolerance:.1e}, marginally stable at best): {}\n",
                show(&marginal)
            ));
        }
        human.push_str(&format!(
            "effects discovery tries: {}\n",
            model
                .candidates()
                .iter()
                .map(|e| {
                    let states = file.effect_states(e);
                    let adds = if states.is_empty() {
                        String::new()
                    } else {
                        format!("; adds states {}", states.join(", "))
                    };
                    format!("{e} ({}{adds})", model.describe(e))
                })
                .collect::<Vec<_>>()
                .join("; ")
        ));
        if !id.no_effect.is_empty() {
            human.push_str(&format!(
                "no effect on the outputs: {}\n",
                id.no_effect.join(", ")
            ));
        }
        for g in &id.unseparated {
            let unseen: Vec<String> = id
                .combinations
                .iter()
                .filter(|c| c.weights.iter().map(|(n, _)| n).eq(g.iter()))
                .map(|c| {
                    let weights: Vec<String> = c
                        .weights
                        .iter()
                        .map(|(n, w)| format!("{n} {w:+.3}"))
                        .collect();
                    weights.join(", ")
                })
                .collect();
            let which = match unseen.len() {
                1 => "the unseen one".to_string(),
                k => format!("{k} unseen ones"),
            };
            human.push_str(&format!(
                "the outputs cannot separate {}: only combinations of them are identifiable \
                 ({which}, on unit-norm Jacobian columns: {})\n",
                g.join(", "),
                unseen.join("; ")
            ));
        }
        let held: Vec<&str> = id
            .holds
            .iter()
            .filter(|h| id.unseparated.iter().any(|g| g.contains(h)))
            .map(|h| h.as_str())
            .collect();
        if !held.is_empty() {
            // The fit's rule on this Jacobian; on data a fit weighs the combination by the
            // data's Jacobian and may hold another of its parameters.
            let (its, value) = if held.len() == 1 {
                ("its", "value")
            } else {
                ("their", "values")
            };
            human.push_str(&format!(
                "a fit holds {} at {its} documented {value} and reports the others given it (of \
                 the parameters weighing at least a quarter of the most in an unseen combination, \
                 the last in model order); these weights are the FRF's at the documented values: \
                 a fit on data weighs by the data's Jacobian and may hold another of them\n",
                held.join(", ")
            ));
        }
        if id.no_effect.is_empty() && id.unseparated.is_empty() {
            human.push_str("every free parameter is locally identifiable from the outputs\n");
        }
        let linearized = if file.is_nonlinear() {
            " linearized at the operating point (the FRF criterion; the time criterion sees the \
             nonlinear form, which may tell them apart)"
        } else {
            ""
        };
        let aliases = identifiability::aliases(&model)?;
        let rivals = identifiability::rival_pairs(&model)?;
        for a in &aliases {
            let against = if a.with.is_empty() && file.is_nonlinear() {
                // A constant offset or a term of second order changes no linearization.
                "leaves the linearization at the operating point unchanged (a constant offset, or a term of second order)".to_string()
            } else if a.with.is_empty() {
                "acts on no output".to_string()
            } else {
                format!("trades against {}", a.with.join(", "))
            };
            human.push_str(&format!(
                "effect {}: {} {against}: the outputs cannot tell it from the model{linearized}, \
                 so discovery can add it only in their place, at its documented value\n",
                a.effect,
                a.parameters.join(", "),
            ));
        }
        for (first, second) in &rivals {
            human.push_str(&format!(
                "effects {first} and {second}: the outputs cannot tell them apart{linearized}; \
                 discovery may add one, naming the other its rival\n"
            ));
        }
        let json = json!({
            "system": file.system(),
            "file": self.file.display().to_string(),
            "states": file.states(),
            "inputs": file.inputs(),
            "outputs": file.outputs(),
            "parameters": params,
            "A": rows(&ss.a), "B": rows(&ss.b), "C": rows(&ss.c), "D": rows(&ss.d),
            "eigenvalues": eig.iter().map(|l| [l.re, l.im]).collect::<Vec<_>>(),
            "unstable": pairs(&unstable),
            "marginal": pairs(&marginal),
            "eigenvalue_tolerance": tolerance,
            "candidates": model.candidates(),
            "effect_states": file
                .effects()
                .iter()
                .map(|e| (e.clone(), json!(file.effect_states(e))))
                .collect::<serde_json::Map<_, _>>(),
            "identifiability": id,
            "aliases": aliases,
            "rival_pairs": rivals,
            "drift": drift,
            "silent_outputs": silent,
        });
        Ok(Output { human, json })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_zero_eigenvalues_of_a_double_integrator_lie_on_the_imaginary_axis() {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, 0.0]);
        // What rounding leaves of them.
        let eig = [Complex::new(2.2e-17, 0.0), Complex::new(-2.2e-17, 0.0)];
        let (tolerance, unstable, marginal) = classify(&a, &eig);
        assert_eq!(tolerance, 1e-9);
        assert!(unstable.is_empty());
        assert_eq!(marginal.len(), 2);
        // Relative to the matrix: a small real part of a large matrix is zero too.
        let big = &a * 1e6;
        let (_, unstable, marginal) = classify(&big, &[Complex::new(1e-5, 3.0)]);
        assert!(unstable.is_empty() && marginal.len() == 1);
        let (_, unstable, _) = classify(&a, &[Complex::new(1e-6, 0.0)]);
        assert_eq!(unstable.len(), 1);
    }
}
