//! `stabilis model check FILE`: a model file at its documented values: the matrices, the
//! eigenvalues (which are unstable), the effects discovery will try, and which parameters the
//! outputs cannot separate.
use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::DMatrix;
use serde_json::json;

use super::Output;
use crate::error::Result;
use workbench::identifiability;
use workbench::{Model, ModelFile, ModelStructure};

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

impl CheckArgs {
    /// Reads and analyses the file.
    pub fn run(&self) -> Result<Output> {
        let file = Arc::new(ModelFile::from_path(&self.file)?);
        let ss = file.documented_state_space(&[])?;
        let model = Model::new(file.clone());
        let params = model.parameters()?;
        let theta: Vec<f64> = params.iter().map(|p| p.value).collect();
        let id = identifiability::analyse(&model, &theta)?;
        let eig = ss.a.complex_eigenvalues();
        let unstable: Vec<String> = eig
            .iter()
            .filter(|l| l.re > 0.0)
            .map(|l| format!("{:.5} {:+.5}i", l.re, l.im))
            .collect();
        let mut human = format!(
            "{} ({}): states {}, inputs {}, outputs {}\n",
            file.system(),
            self.file.display(),
            file.states().join(", "),
            file.inputs().join(", "),
            file.outputs().join(", ")
        );
        human.push_str("free parameters (documented value [min, max] unit):\n");
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
        human.push_str(&format!("eigenvalues of A: {}\n", eig_text.join(", ")));
        human.push_str(&if unstable.is_empty() {
            "no unstable eigenvalue\n".to_string()
        } else {
            format!("unstable (real part > 0): {}\n", unstable.join(", "))
        });
        human.push_str(&format!(
            "effects discovery tries: {}\n",
            model
                .candidates()
                .iter()
                .map(|e| format!("{e} ({})", model.describe(e)))
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
            human.push_str(&format!(
                "the outputs cannot separate {}: only combinations of them are identifiable\n",
                g.join(", ")
            ));
        }
        if id.no_effect.is_empty() && id.unseparated.is_empty() {
            human.push_str("every free parameter is locally identifiable from the outputs\n");
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
            "unstable": eig.iter().filter(|l| l.re > 0.0).map(|l| [l.re, l.im]).collect::<Vec<_>>(),
            "candidates": model.candidates(),
            "identifiability": id,
        });
        Ok(Output { human, json })
    }
}
