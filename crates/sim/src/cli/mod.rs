//! The `stabilis` command line. Verbs are variants of [`Command`], each defined in its own file
//! of this directory with `Args` and `fn run(&self) -> Result<Output>`; systems of
//! `stabilis sim <system>` are variants of [`SimSystem`], defined in `crate::scenarios`.
//! `--json` is global: every verb returns an [`Output`] holding both renderings.
use clap::{Parser, Subcommand};

use crate::error::{Result, SimError};
use crate::output;
use crate::progress::Progress;
use crate::scenarios::{self, Recording, Scenario};

pub mod info;
pub mod model;
pub mod power;
pub mod tilt;
pub mod workbench;

/// Stabilizing unstable systems: simulate, log, inspect.
#[derive(Debug, Parser)]
#[command(name = "stabilis", version, about)]
pub struct Cli {
    /// Print machine-readable JSON on stdout instead of the human summary; with a FILE
    /// (`--json out.json`), write it there and print the summary.
    #[arg(long, global = true, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<std::path::PathBuf>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The verbs.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a system in closed loop and log the run to MCAP.
    #[command(subcommand)]
    Sim(SimSystem),
    /// Summarise a log: topics, message counts, time span, metadata.
    Info(info::Args),
    /// Estimate tilt, angular velocity and angular acceleration from accelerometers only
    /// (`/imu/accel` and the `imu` metadata record).
    Tilt(tilt::Args),
    /// Find the physical effects a model misses: compare with measured FRFs, add the most
    /// significant candidate effect, refit, repeat until the rest is noise.
    Discover(workbench::DiscoverArgs),
    /// Fit a model (optionally `--with` effects) to measurements and show where it fails
    /// (`diagnose` is the same verb).
    #[command(visible_alias = "diagnose")]
    Compare(workbench::FitArgs),
    /// Fit a model with the effects given by `--with EFFECT[,EFFECT]`.
    Fit(workbench::FitArgs),
    /// Checks a model file: matrices, eigenvalues, identifiability.
    #[command(subcommand)]
    Model(model::Command),
    /// Monte-Carlo detection power: how often the discovery finds an effect of each size in
    /// simulated campaigns like the logged ones, and how often it finds one that is not there.
    Power(power::Args),
}

/// The systems `stabilis sim` can run.
#[derive(Debug, Clone, PartialEq, Subcommand)]
pub enum SimSystem {
    /// Planar reaction-wheel inverted pendulum balanced by a discrete LQR.
    WheelPendulum(scenarios::wheel_pendulum::Args),
    /// Reaction-wheel cube on its corner: balance, disturbance, jump-up (MCAP `/cubli/*`).
    Cubli(scenarios::cubli::Args),
    /// Ducted-fan flying platform under the cascaded hover controller (hover, disturbance,
    /// step, and the 18 identification experiments).
    FlyingPlatform(scenarios::flying_platform::Args),
    /// Vehicle platoon with distributed event-based state estimation over a lossy network
    /// (gains and thresholds synthesised by LMIs; MCAP `/platoon/*`).
    Platoon(scenarios::platoon::Args),
    /// Quadruple integrator under parametrized infinite-horizon MPC or discrete-time MPC
    /// (MCAP `/quad_integrator/*`).
    QuadIntegrator(scenarios::quad_integrator::Args),
}

impl SimSystem {
    /// The scenario behind the subcommand.
    pub fn scenario(&self) -> &dyn Scenario {
        match self {
            Self::WheelPendulum(args) => args,
            Self::Cubli(args) => args,
            Self::FlyingPlatform(args) => args,
            Self::Platoon(args) => args,
            Self::QuadIntegrator(args) => args,
        }
    }

    /// Parses `system` and its options as they would appear after `stabilis sim` (used by the
    /// Python bindings so that both front ends share one registry and one set of defaults).
    pub fn parse_args<I, S>(system: &str, args: I) -> Result<Self>
    where
        I: IntoIterator<Item = S>,
        S: Into<std::ffi::OsString> + Clone,
    {
        #[derive(Debug, Parser)]
        #[command(name = "stabilis sim", no_binary_name = true)]
        struct Wrapper {
            #[command(subcommand)]
            system: SimSystem,
        }
        let args: Vec<std::ffi::OsString> = args.into_iter().map(Into::into).collect();
        let shown = args
            .iter()
            .map(|a| a.to_string_lossy())
            .collect::<Vec<_>>()
            .join(" ");
        let argv = std::iter::once(std::ffi::OsString::from(system)).chain(args);
        Wrapper::try_parse_from(argv)
            .map(|w| w.system)
            .map_err(|e| {
                let rendered = e.render().to_string();
                let reason = rendered.lines().next().unwrap_or_default();
                SimError::invalid(
                    format!("options of `stabilis sim {system}`"),
                    shown,
                    reason.trim_start_matches("error: "),
                )
            })
    }

    /// Runs the scenario with a progress bar.
    pub fn run(&self) -> Result<Recording> {
        let mut progress = Progress::new(100, "simulating");
        scenarios::run(self.scenario(), &mut progress)
    }
}

/// The result of a verb in both renderings.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// For people.
    pub human: String,
    /// For machines (`--json`).
    pub json: serde_json::Value,
}

/// The `--data` logs and the `--model` file of a workbench verb.
fn workbench_inputs(common: &workbench::Common) -> Vec<std::path::PathBuf> {
    common.data.iter().chain(&common.model).cloned().collect()
}

impl Command {
    /// The files and directories the verb reads: no output may replace or go inside any of them.
    pub fn inputs(&self) -> Vec<std::path::PathBuf> {
        match self {
            Self::Sim(_) => Vec::new(),
            Self::Info(args) => vec![args.file.clone()],
            Self::Tilt(args) => vec![args.data.clone()],
            Self::Discover(args) => workbench_inputs(&args.common),
            Self::Compare(args) | Self::Fit(args) => workbench_inputs(&args.common),
            Self::Model(model::Command::Check(args)) => vec![args.file.clone()],
            Self::Power(args) => args.inputs(),
        }
    }

    /// The outputs the verb writes besides `--json` (`--out`, `--report`), with their options.
    fn outputs(&self) -> Vec<output::Planned<'_>> {
        use output::{Kind, Planned, Target};
        let (option, path, target) = match self {
            // The flying platform writes its logs into a directory.
            Self::Sim(SimSystem::FlyingPlatform(args)) => {
                ("--out", args.out.as_deref(), Target::Into)
            }
            Self::Sim(system) => (
                "--out",
                system.scenario().common().out.as_deref(),
                Target::File(Kind::Mcap),
            ),
            Self::Tilt(args) => ("--out", args.out.as_deref(), Target::File(Kind::Mcap)),
            Self::Discover(args) => ("--report", args.common.report.as_deref(), Target::Dir),
            Self::Compare(args) | Self::Fit(args) => {
                ("--report", args.common.report.as_deref(), Target::Dir)
            }
            Self::Power(args) => ("--report", args.report.as_deref(), Target::Dir),
            Self::Info(_) | Self::Model(_) => ("", None, Target::Dir),
        };
        path.map(|path| Planned {
            option,
            path,
            target,
        })
        .into_iter()
        .collect()
    }

    /// Runs the verb.
    pub fn run(&self) -> Result<Output> {
        match self {
            Self::Sim(system) => sim_output(&system.run()?),
            Self::Info(args) => args.run(),
            Self::Tilt(args) => args.run(),
            Self::Discover(args) => args.run(),
            Self::Compare(args) => args.run(),
            Self::Fit(args) => args.run_fit(),
            Self::Model(cmd) => cmd.run(),
            Self::Power(args) => args.run(),
        }
    }
}

fn sim_output(recording: &Recording) -> Result<Output> {
    let mut human = String::new();
    let system = recording
        .experiment
        .get("system")
        .cloned()
        .unwrap_or_default();
    human.push_str(&format!("{system}: "));
    human.push_str(
        &recording
            .summary
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect::<Vec<_>>()
            .join(", "),
    );
    if let Some(out) = &recording.out {
        human.push_str(&format!("\nwrote {}", out.display()));
    }
    let topics: serde_json::Map<_, _> = recording
        .topics
        .iter()
        .map(|(name, table)| {
            (
                name.clone(),
                serde_json::json!({"messages": table.len(), "fields": table.fields}),
            )
        })
        .collect();
    let json = serde_json::json!({
        "system": system,
        "out": recording.out.as_ref().map(|p| p.display().to_string()),
        "summary": recording.summary,
        "experiment": recording.experiment,
        "topics": topics,
    });
    Ok(Output { human, json })
}

fn is_log(path: &std::path::Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("csv"))
}

/// Parses the command line, runs it, prints the result and returns the exit code: 0 on success,
/// 2 on bad input (clap's usage errors too), 1 when the machine failed.
pub fn main_with_args<I, S>(args: I) -> i32
where
    I: IntoIterator<Item = S>,
    S: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version go to stdout with code 0; usage errors to stderr with code 2.
            let _ = e.print();
            return e.exit_code();
        }
    };
    if let Some(path) = cli.json.as_deref().filter(|p| is_log(p)) {
        // `--json` takes an optional file; `stabilis info --json a.mcap b.mcap` must not
        // overwrite the log a.mcap with JSON.
        let error = SimError::invalid(
            "--json FILE",
            path.display(),
            "is a log (.mcap or .csv); write --json after the input files or give a .json path",
        );
        eprintln!("error: {error}");
        return error.exit_code();
    }
    let inputs = cli.command.inputs();
    // Outputs are refused before the work, not after it: each against the inputs and against
    // the others.
    let json = cli
        .json
        .as_deref()
        .filter(|p| *p != std::path::Path::new("-"));
    let mut outputs = cli.command.outputs();
    // The other outputs, which the JSON written at the end must not replace either.
    let written: Vec<std::path::PathBuf> = inputs
        .iter()
        .cloned()
        .chain(outputs.iter().map(|o| o.path.to_path_buf()))
        .collect();
    outputs.extend(json.map(|path| output::Planned {
        option: "--json",
        path,
        target: output::Target::File(output::Kind::Json),
    }));
    if let Err(error) = output::check_outputs(&outputs, &inputs) {
        eprintln!("error: {error}");
        return error.exit_code();
    }
    let result = cli
        .command
        .run()
        .and_then(|output| match cli.json.as_deref() {
            Some(p) if p != std::path::Path::new("-") => {
                let text = format!("{:#}\n", output::stamped(&output.json));
                output::write_atomically(p, output::Kind::Json, &written, |tmp| {
                    std::fs::write(tmp, text).map_err(|e| SimError::io(tmp, e))
                })?;
                Ok(output.human)
            }
            Some(_) => Ok(output.json.to_string()),
            None => Ok(output.human),
        });
    match result {
        Ok(text) => print_quietly(&text),
        Err(error) => {
            if cli.json.is_some() {
                print_quietly(&serde_json::json!({ "error": error.to_string() }).to_string());
            }
            eprintln!("error: {error}");
            error.exit_code()
        }
    }
}

/// Prints `text` and a newline on stdout and returns exit code 0; a reader that closed the pipe
/// early (`stabilis info x.mcap | head -1`) is not an error, other write failures are (code 1).
fn print_quietly(text: &str) -> i32 {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    match writeln!(stdout, "{text}").and_then(|()| stdout.flush()) {
        Ok(()) => 0,
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => 0,
        Err(e) => {
            eprintln!("error: cannot write to standard output: {e}");
            1
        }
    }
}
