//! Nonlinear model files and the time-domain criterion on a pendulum whose truth is known: an
//! inverted pendulum balanced by state feedback, simulated here with its own integrator (Euler
//! on 50 sub-steps per sample, not the predictor's RK4), with dry friction at the joint and a
//! sensor offset switchable.
#![allow(clippy::unwrap_used)]
use std::path::Path;
use std::sync::Arc;

use nalgebra::DMatrix;
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use workbench::discover::Candidates;
use workbench::{
    Criterion, DataOptions, Dataset, EstimatorChoice, Experiment, Model, ModelFile, ModelStructure,
    Workbench,
};

/// `theta'' = k sin(theta) + c torque`, torque = input plus what effects add.
const PENDULUM: &str = r#"
name = "pend"
states = ["theta", "omega"]
inputs = ["T"]
outputs = ["theta"]
[parameters]
k = { value = 20.0, min = 1.0, max = 100.0 }
c = { value = 10.0, min = 1.0, max = 100.0 }
[definitions]
torque = "T"
[nonlinear]
f.theta = "omega"
f.omega = "k*sin(theta) + c*torque"
h.theta = "theta"
operating_point = { theta = 0, omega = 0, T = 0 }
[effects.dry]
description = "dry friction at the joint, smoothed over eps"
parameters = { tc = { value = 0.05, min = 0.0, max = 5.0 }, eps = { value = 0.05, fixed = true } }
add.torque = "-tc*tanh(omega/eps)"
[effects.viscous]
description = "viscous friction at the joint"
parameters = { b = { value = 0.05, min = 0.0, max = 5.0 } }
add.torque = "-b*omega"
"#;

fn file(text: &str) -> workbench::Result<ModelFile> {
    ModelFile::parse(text, Path::new("pend.toml"))
}

/// What [`simulate`] hides in the pendulum: dry friction `tc` at the joint (smoothed over
/// 0.05 rad/s like the file), a sensor offset `bias`, a flexible sensor mount of [`MODE`]
/// flexed by `mode_gain` times the angular acceleration, a first-order actuator lag `lag` (s),
/// the angle read in counts of `step` rad (0: not quantized), at `fs` Hz, the controller
/// (and the excitation) updated every `hold` samples.
#[derive(Clone, Copy)]
struct Truth {
    tc: f64,
    bias: f64,
    mode_gain: f64,
    lag: f64,
    step: f64,
    fs: f64,
    hold: usize,
}

const CLEAN: Truth = Truth {
    tc: 0.0,
    bias: 0.0,
    mode_gain: 0.0,
    lag: 0.0,
    step: 0.0,
    fs: 100.0,
    hold: 1,
};

/// The seeds of a study that takes a minute or more per seed: the first on every run, all of
/// them where `STABILIS_CAMPAIGNS` is set (`scripts/test.sh --campaigns`), as pytest's
/// `campaign` mark does.
fn campaign_seeds(seeds: &[u64]) -> &[u64] {
    if std::env::var_os("STABILIS_CAMPAIGNS").is_some() {
        seeds
    } else {
        &seeds[..1]
    }
}

/// Truth: k = 25, c = 12, dry friction `tc`, sensor offset `bias`.
fn campaign(tc: f64, bias: f64, seed: u64) -> Dataset {
    simulate(Truth { tc, bias, ..CLEAN }, seed)
}

/// Frequency (Hz) and damping ratio of the flexible mode [`campaign_with_mode`] can add.
const MODE: (f64, f64) = (12.0, 0.03);

/// [`campaign`] whose angle sensor sits on a mount with a flexible mode of [`MODE`], flexed by
/// the pendulum's angular acceleration, `m'' + 2 zeta w m' + w^2 m = gain theta''`: an error
/// confined to the mode's band, which no effect of the file describes.
fn campaign_with_mode(tc: f64, bias: f64, gain: f64, seed: u64) -> Dataset {
    simulate(
        Truth {
            tc,
            bias,
            mode_gain: gain,
            ..CLEAN
        },
        seed,
    )
}

/// Two records of 6000 controller samples of the pendulum `theta'' = k sin(theta) + c torque`
/// (k = 25, c = 12) under `truth`. Feedback `u = -5 y - 1.2 omega + r` on the measured angle and the
/// true rate, `r` white noise of rms 0.6 held per sample, torque noise, angle noise 1e-3 rad
/// (1e-4 rad when quantized, so that the counts show).
fn simulate(truth: Truth, seed: u64) -> Dataset {
    let (k, c, t) = (25.0, 12.0, 1.0 / truth.fs);
    let wm = 2.0 * std::f64::consts::PI * MODE.0;
    let sensor = if truth.step > 0.0 { 1e-4 } else { 1e-3 };
    let mut rng = StdRng::seed_from_u64(seed);
    let mut experiments = Vec::new();
    for e in 0..2 {
        let n = 6000 * truth.hold;
        let (mut u, mut y, mut r) = (
            DMatrix::zeros(n, 1),
            DMatrix::zeros(n, 1),
            DMatrix::zeros(n, 1),
        );
        let (mut th, mut om, mut applied) = (0.0f64, 0.0f64, 0.0f64);
        let (mut m, mut mv) = (0.0f64, 0.0f64);
        for i in 0..n {
            let read = th + m + truth.bias + sensor * rng.sample::<f64, _>(StandardNormal);
            y[(i, 0)] = if truth.step > 0.0 {
                (read / truth.step).round() * truth.step
            } else {
                read
            };
            if i % truth.hold == 0 {
                r[(i, 0)] = 0.6 * rng.sample::<f64, _>(StandardNormal);
                u[(i, 0)] = -5.0 * y[(i, 0)] - 1.2 * om + r[(i, 0)];
            } else {
                r[(i, 0)] = r[(i - 1, 0)];
                u[(i, 0)] = u[(i - 1, 0)];
            }
            let w = 0.02 * rng.sample::<f64, _>(StandardNormal);
            let h = t / 50.0;
            for _ in 0..50 {
                applied = if truth.lag > 0.0 {
                    applied + h * (u[(i, 0)] - applied) / truth.lag
                } else {
                    u[(i, 0)]
                };
                let torque = applied + w - truth.tc * (om / 0.05).tanh();
                let acc = k * th.sin() + c * torque;
                th += h * om;
                om += h * acc;
                let macc = truth.mode_gain * acc - 2.0 * MODE.1 * wm * mv - wm * wm * m;
                m += h * mv;
                mv += h * macc;
            }
        }
        experiments.push(Experiment {
            name: format!("experiment {}", e + 1),
            u,
            y,
            r: Some(r),
            periodic: None,
        });
    }
    Dataset {
        sample_rate_hz: truth.fs,
        inputs: vec!["T".into()],
        outputs: vec!["theta".into()],
        experiments,
    }
}

fn workbench(data: Dataset) -> Workbench {
    Workbench::with_options(
        Arc::new(file(PENDULUM).unwrap()),
        data,
        EstimatorChoice::Auto,
        DataOptions::default(),
    )
    .unwrap()
}

/// The linearization at the operating point is the closed form `A = [[0, 1], [k, 0]]`,
/// `B = [0, c]`, and the dry friction adds `-c tc / eps` to `A[1][1]` (its derivative at zero
/// speed, chained through the definition `torque`).
#[test]
fn the_linearization_is_the_closed_form() {
    let m = file(PENDULUM).unwrap();
    let ss = m.state_space(&[], &[20.0, 10.0]).unwrap();
    assert_eq!(ss.a, DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 20.0, 0.0]));
    assert_eq!(ss.b, DMatrix::from_row_slice(2, 1, &[0.0, 10.0]));
    assert_eq!(ss.c, DMatrix::from_row_slice(1, 2, &[1.0, 0.0]));
    let dry = m.state_space(&["dry".into()], &[20.0, 10.0, 0.3]).unwrap();
    assert!((dry.a[(1, 1)] + 10.0 * 0.3 / 0.05).abs() < 1e-12);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Away from zero (an operating point at an angle and a speed) the symbolic Jacobian
    /// equals central differences of `f` and `h` (relative 1e-6), with both effects on.
    #[test]
    fn the_linearization_is_the_jacobian_of_f_and_h(
        th0 in -1.0f64..1.0, om0 in -0.5f64..0.5, u0 in -1.0f64..1.0,
        k in 1.0f64..50.0, c in 1.0f64..30.0, tc in 0.0f64..1.0, b in 0.0f64..1.0,
    ) {
        let text = PENDULUM.replace(
            "operating_point = { theta = 0, omega = 0, T = 0 }",
            &format!("operating_point = {{ theta = {th0}, omega = {om0}, T = {u0} }}"),
        );
        let m = file(&text).unwrap();
        let on = vec!["dry".to_string(), "viscous".to_string()];
        let theta = [k, c, tc, b];
        let ss = m.state_space(&on, &theta).unwrap();
        let d = m.dynamics(&on, &theta).unwrap().unwrap();
        let mut scratch = Vec::new();
        let z0 = [th0, om0, u0];
        let eval = |z: &[f64], scratch: &mut Vec<f64>| {
            let (mut dx, mut y) = (vec![0.0; 2], vec![0.0; 1]);
            d.f(&z[..2], &z[2..], &mut dx, scratch).unwrap();
            d.h(&z[..2], &z[2..], &mut y, scratch).unwrap();
            [dx[0], dx[1], y[0]]
        };
        for j in 0..3 {
            let h = 1e-6;
            let (mut zp, mut zm) = (z0, z0);
            zp[j] += h;
            zm[j] -= h;
            let (fp, fm) = (eval(&zp, &mut scratch), eval(&zm, &mut scratch));
            for i in 0..3 {
                let fd = (fp[i] - fm[i]) / (2.0 * h);
                let an = match (i, j) {
                    (0 | 1, 0 | 1) => ss.a[(i, j)],
                    (0 | 1, _) => ss.b[(i, 0)],
                    (_, 0 | 1) => ss.c[(0, j)],
                    _ => ss.d[(0, 0)],
                };
                prop_assert!((an - fd).abs() <= 1e-6 * (1.0 + fd.abs()), "d{i}/d{j}: {an} vs {fd}");
            }
        }
    }
}

#[test]
fn bad_nonlinear_files_are_refused_by_name() {
    let cases = [
        (
            PENDULUM.replace(", omega = 0, T = 0 }", ", T = 0 }"),
            vec![
                "pend.toml",
                "nonlinear.operating_point",
                "missing state omega",
            ],
        ),
        (
            PENDULUM.replace(", T = 0 }", " }"),
            vec!["nonlinear.operating_point", "missing input T"],
        ),
        (
            PENDULUM.replace("\"k*sin(theta) + c*torque\"", "\"k/theta\""),
            vec!["nonlinear.f.omega", "inf", "theta = 0"],
        ),
        (
            PENDULUM.replace("h.theta = \"theta\"", "h.theta = \"log(theta)\""),
            vec!["nonlinear.h.theta", "theta = 0"],
        ),
        (
            PENDULUM.replace("f.theta = \"omega\"\n", ""),
            vec!["nonlinear.f.theta", "missing"],
        ),
        (
            PENDULUM.replace(
                "add.torque = \"-b*omega\"",
                "A = { \"omega,omega\" = \"-b\" }",
            ),
            vec!["effects.viscous.A", "add.<definition>"],
        ),
        (
            format!("{PENDULUM}\n[linear]\nA = [[0, 1], [1, 0]]\nB = [[0], [1]]\nC = [[1, 0]]\n"),
            vec!["not both"],
        ),
        (
            PENDULUM.replace("add.torque = \"-b*omega\"", "add.tork = \"-b*omega\""),
            vec!["effects.viscous.add.tork", "not a definition"],
        ),
        (
            PENDULUM.replace(
                "f.theta = \"omega\"\nf.omega = \"k*sin(theta) + c*torque\"",
                "f = [\"omega\", \"k*sin(theta) + c*torque\"]",
            ),
            vec!["nonlinear.f", "not a table (given: array)", "f.theta = "],
        ),
        // A term an effect adds is named itself when its derivative is not finite, not the
        // expression it adds to nor the state it spoils through the chain rule.
        (
            PENDULUM.replace("\"-b*omega\"", "\"-b*sqrt(omega)\""),
            vec!["effects.viscous.add.torque: its derivative by omega is -inf"],
        ),
        (
            PENDULUM.replace("k*sin(theta)", "k*sin(theta) - abs(omega)"),
            vec![
                "nonlinear.f.omega",
                "cannot differentiate",
                "sqrt(v^2 + eps^2) for abs(v)",
            ],
        ),
    ];
    for (text, wants) in cases {
        let msg = file(&text).unwrap_err().to_string();
        for w in wants {
            assert!(msg.contains(w), "{msg:?} lacks {w:?}");
        }
    }
    // A linear file may not read states in a definition or add to f.
    let linear = "name = \"p\"\nstates = [\"x\"]\ninputs = [\"u\"]\noutputs = [\"x\"]\n\
                  [definitions]\nq = \"x\"\n[linear]\nA = [[-1]]\nB = [[1]]\nC = [[1]]\n";
    let msg = file(linear).unwrap_err().to_string();
    assert!(
        msg.contains("definitions.q") && msg.contains("[nonlinear]"),
        "{msg}"
    );
}

/// The flexible mount of [`campaign_with_mode`] as an effect with states of its own, `q` and
/// `qd`, flexed by the angular acceleration and read with the angle; its documented frequency
/// is the one `compare` locates within 10 % (69 rad/s, 11 Hz, for 12 Hz).
const MOUNT: &str = r#"
[effects.mount]
description = "flexible sensor mount: q'' + 2 zm wm q' + wm^2 q = gm theta'', read with theta"
parameters = { wm = { value = 69.0, min = 6.0, max = 300.0, unit = "rad/s" }, zm = { value = 0.05, min = 0.0, max = 1.0 }, gm = { value = 0.1, min = -2.0, max = 2.0 } }
states = ["q", "qd"]
add.f.q = "qd"
add.f.qd = "gm*(k*sin(theta) + c*torque) - 2*zm*wm*qd - wm^2*q"
add.h.theta = "q"
"#;

/// The mount's states follow the pendulum's in the nonlinear model and its linearization,
/// which is the closed form; at an operating point given for them, the model starts there.
#[test]
fn an_effect_with_states_of_its_own_linearizes_to_the_closed_form() {
    let m = file(&format!("{PENDULUM}{MOUNT}")).unwrap();
    let on = vec!["mount".to_string()];
    let (k, c, wm, zm, gm) = (20.0, 10.0, 69.0, 0.05, 0.1);
    let ss = m.state_space(&on, &[k, c, wm, zm, gm]).unwrap();
    #[rustfmt::skip]
    let a = DMatrix::from_row_slice(4, 4, &[
        0.0, 1.0, 0.0, 0.0,
        k, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
        gm * k, 0.0, -wm * wm, -2.0 * zm * wm,
    ]);
    assert!((&ss.a - a).amax() < 1e-12, "{}", ss.a);
    assert!((&ss.b - DMatrix::from_row_slice(4, 1, &[0.0, c, 0.0, gm * c])).amax() < 1e-12);
    assert_eq!(ss.c, DMatrix::from_row_slice(1, 4, &[1.0, 0.0, 1.0, 0.0]));
    assert_eq!(m.state_names(&on), ["theta", "omega", "q", "qd"]);
    assert_eq!(m.state_space(&[], &[k, c]).unwrap().a.nrows(), 2);
    let d = m.dynamics(&on, &[k, c, wm, zm, gm]).unwrap().unwrap();
    assert_eq!(d.states(), 4);
    let (mut dx, mut y) = (vec![0.0; 4], vec![0.0; 1]);
    d.f(&[0.1, 0.0, 0.01, 0.0], &[0.0], &mut dx, &mut Vec::new())
        .unwrap();
    d.h(&[0.1, 0.0, 0.01, 0.0], &[0.0], &mut y, &mut Vec::new())
        .unwrap();
    let acc = k * 0.1f64.sin();
    let want = [0.0, acc, 0.0, gm * acc - wm * wm * 0.01];
    assert!(
        dx.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
        "{dx:?}"
    );
    assert!((y[0] - 0.11).abs() < 1e-15);
    let at = file(&format!(
        "{PENDULUM}{MOUNT}operating_point = {{ q = 0.002 }}\n"
    ))
    .unwrap();
    let d = at.dynamics(&on, &[k, c, wm, zm, gm]).unwrap().unwrap();
    assert_eq!(d.operating_point().0, [0.0, 0.0, 0.002, 0.0]);
    for (mount, want) in [
        (
            MOUNT.replace("add.f.qd = ", "add.f.omega = "),
            "\"qd\" has no derivative: give add.f.qd",
        ),
        (
            MOUNT.replace("add.h.theta = \"q\"", ""),
            "q, qd read by nothing outside the effect",
        ),
        (
            format!("{MOUNT}operating_point = {{ qq = 0 }}\n"),
            "effects.mount.operating_point.qq: \"qq\" is not one of the effect's states: q, qd",
        ),
        (
            MOUNT.replace("states = [\"q\", \"qd\"]", "states = [\"q\", \"omega\"]"),
            "effects.mount.states: \"omega\" is already a state or input name",
        ),
    ] {
        let msg = file(&format!("{PENDULUM}{mount}")).unwrap_err().to_string();
        assert!(msg.contains(want), "{msg:?} lacks {want:?}");
    }
    // The model's own expressions may not read an effect's states.
    let msg = file(&format!(
        "{}{MOUNT}",
        PENDULUM.replace("h.theta = \"theta\"", "h.theta = \"theta + q\"")
    ))
    .unwrap_err()
    .to_string();
    assert!(
        msg.contains("nonlinear.h.theta")
            && msg.contains("\"q\" in \"theta + q\" is not visible here"),
        "{msg}"
    );
}

/// The mode `the_time_criterion_locates_a_missing_mode_in_frequency` finds unexplained, offered
/// as an effect with states: found and explained with its frequency and gain within 3
/// standard errors of the truth (12 Hz, 0.2; 3 of 3 seeds; measured z of the frequency 0.66,
/// -1.10, 0.48), and not found in logs without it (3 of 3); under the FRF criterion found
/// too (3 of 3; the model is seen through the Welch window's kernel), the same two within 3
/// standard errors (z of the frequency 1.61, -1.54, -0.29).
#[test]
fn a_missing_mode_offered_as_an_effect_with_states_is_found() {
    let text = format!("{PENDULUM}{MOUNT}");
    let wm = 2.0 * std::f64::consts::PI * MODE.0;
    for seed in [31, 32, 33] {
        let d = workbench_with(&text, campaign_with_mode(0.0, 0.0, 0.2, seed), None)
            .discover()
            .unwrap();
        let verdict = d.conclusion.verdict_sentence();
        assert_eq!(d.conclusion.found, ["mount"], "seed {seed}: {verdict}");
        assert!(!d.conclusion.unexplained, "seed {seed}: {verdict}");
        let near_truth = |d: &workbench::discover::Discovery, criterion: &str| {
            let last = d.steps.last().unwrap();
            for (name, truth) in [("wm", wm), ("gm", 0.2)] {
                let p = last.params.iter().find(|p| p.name == name).unwrap();
                let se = p.std.unwrap();
                assert!(
                    (p.value - truth).abs() <= 3.0 * se,
                    "seed {seed}, {criterion}: {name} {} +- {se} for {truth}",
                    p.value
                );
            }
        };
        near_truth(&d, "time");
        let clean = workbench_with(&text, campaign(0.0, 0.0, seed), None)
            .discover()
            .unwrap();
        assert!(
            !clean.conclusion.found.iter().any(|e| e == "mount"),
            "seed {seed}: {:?}",
            clean.conclusion.found
        );
        // The FRF criterion fits it alike: the model is seen through the Welch window's kernel,
        // so bins that smooth the mode's peak smooth the model's too.
        let frf = workbench_with(
            &text,
            campaign_with_mode(0.0, 0.0, 0.2, seed),
            Some(Criterion::Frf),
        )
        .discover()
        .unwrap();
        let c = &frf.conclusion;
        assert_eq!(c.found, ["mount"], "seed {seed}: {}", c.verdict_sentence());
        near_truth(&frf, "FRF");
    }
}

/// A predictor that cannot stay bounded is refused naming the experiment and the sample.
#[test]
fn a_diverging_predictor_names_the_sample() {
    let text = PENDULUM.replace(
        "\"k*sin(theta) + c*torque\"",
        "\"k*sin(theta) + c*torque + 1e6*omega^3\"",
    );
    let wb = Workbench::with_options(
        Arc::new(file(&text).unwrap()),
        campaign(0.0, 0.0, 1),
        EstimatorChoice::Auto,
        DataOptions::default(),
    )
    .unwrap();
    let msg = wb.compared().unwrap_err().to_string();
    assert!(msg.contains("diverges") && msg.contains("sample"), "{msg}");
}

/// Sensor noise coloured by a first-order filter (pole 0.95) on top of the white: the right
/// model's innovations are not white, which its predictor cannot mend, and wherever the
/// verdict reads "explained" (seeds 11 and 12) the summary says what that means; on the white
/// campaign it says nothing of the kind. On seed 13 the verdict reads misfit (p = 0.0098): in
/// closed loop a noise model that does not fit biases the fit a little, which the note says.
#[test]
fn coloured_noise_beside_an_explained_verdict_is_named() {
    const NOTE: &str = "not white in [theta] beside the verdict \"explained\"";
    let mut noted = 0;
    for seed in [11, 12, 13] {
        let mut data = campaign(0.0, 0.0, seed);
        let mut rng = StdRng::seed_from_u64(seed + 100);
        for e in &mut data.experiments {
            let mut c = 0.0;
            for i in 0..e.y.nrows() {
                c = 0.95 * c + 1e-3 * rng.sample::<f64, _>(StandardNormal);
                e.y[(i, 0)] += c;
            }
        }
        let wb = workbench(data);
        let d = wb.compared().unwrap();
        let summary = workbench::report::table(&wb, &d);
        if !d.conclusion.unexplained {
            assert!(summary.contains(NOTE), "seed {seed}: {summary}");
            noted += 1;
        }
        let wb = workbench(campaign(0.0, 0.0, seed));
        let summary = workbench::report::table(&wb, &wb.compared().unwrap());
        assert!(!summary.contains(NOTE), "seed {seed}: {summary}");
    }
    assert!(noted >= 2, "{noted} of 3 explained");
}

/// Nothing hidden: nothing found (3 of 3 seeds); the true model's parameters within 3 %.
#[test]
fn nothing_hidden_finds_nothing() {
    for seed in [11, 12, 13] {
        let wb = workbench(campaign(0.0, 0.0, seed));
        assert_eq!(wb.criterion(), Criterion::Time);
        let d = wb.discover().unwrap();
        // The summary judges this cost by the residual tests, not the FRF's noise reference.
        let summary = workbench::report::table(&wb, &d);
        assert!(
            summary.contains("cost/resid.") && !summary.contains("expected cost"),
            "{summary}"
        );
        // Its verdict's p-value is the excitation test's, and says so.
        let verdict = d.conclusion.verdict_sentence();
        assert!(
            verdict.contains("for the innovations' correlation with the excitation")
                && !verdict.contains("remaining cost"),
            "{verdict}"
        );
        // A candidate whose fit stopped early shows no reduction: its cost is not a fitted one.
        for c in d
            .steps
            .iter()
            .flat_map(|s| &s.candidates)
            .filter(|c| c.abandoned)
        {
            let line = summary
                .lines()
                .find(|l| l.contains(&format!("not added: {}", c.effect)))
                .unwrap_or_else(|| panic!("{summary}"));
            assert!(
                line.contains("fit stopped") && !line.contains("reduction"),
                "{line}"
            );
            // It stops on the effect size alone, and says whether it passes the tests there
            // (the verdict's near miss names such a candidate "passes the tests").
            assert!(line.contains("more than noise alone varies it"), "{line}");
            assert_eq!(line.contains("passes the tests"), c.passes_tests, "{line}");
        }
        assert!(
            d.conclusion.found.is_empty() && d.conclusion.tentative.is_empty(),
            "seed {seed}: {:?} {:?}",
            d.conclusion.found,
            d.conclusion.tentative
        );
        let p = &d.steps[0].params;
        assert!(
            (p[0].value / 25.0 - 1.0).abs() < 0.03,
            "seed {seed}: k {}",
            p[0].value
        );
        assert!(
            (p[1].value / 12.0 - 1.0).abs() < 0.03,
            "seed {seed}: c {}",
            p[1].value
        );
    }
}

/// Dry friction hidden: added as the dry effect, not the viscous one, its level within 10 %
/// (3 of 3 seeds), and confirmed (not left tentative by the verdict) on at least 2 of 3: the
/// verdict's test against the excitation has a nominal false-alarm rate of 1 % per output, and
/// a fixed-gain predictor of a nonlinear model leaves its errors weakly modulated by the
/// trajectory (measured: 10 of 10 seeds 21-30 confirmed since the gain is designed on the
/// linearization averaged along the data; on the operating point's, where the friction's slope
/// is steepest, seed 22 was tentative at p = 0.008). A sensor
/// offset hidden: an offset within 10 % of the truth or of the torque offset that holds the
/// same levels (3 of 3), that rival named, and the verdict naming what else shifts the
/// levels.
#[test]
fn dry_friction_and_a_sensor_offset_are_found_as_themselves() {
    let mut confirmed = 0;
    let seeds = campaign_seeds(&[21, 22, 23]);
    for &seed in seeds {
        let wb = workbench(campaign(0.3, 0.0, seed));
        let d = wb.discover().unwrap();
        // The step table's fit % is the criterion's own (the EKF's k-step prediction), and it
        // rises when the friction is added.
        let json = workbench::report::json(&wb, &d);
        let fit = |i: usize| json["steps"][i]["fit_percent"]["theta"].as_f64().unwrap();
        for (i, st) in d.steps.iter().enumerate() {
            let k_step = &st.time_fit.prediction_error.as_ref().unwrap().k_step;
            assert_eq!(fit(i), k_step[0].1, "seed {seed} step {i}");
        }
        assert!(fit(d.steps.len() - 1) > fit(0), "seed {seed}: {json}");
        let added: Vec<&String> = d
            .conclusion
            .found
            .iter()
            .chain(&d.conclusion.tentative)
            .collect();
        assert_eq!(
            added,
            ["dry"],
            "seed {seed}: {}",
            d.conclusion.verdict.sentence()
        );
        assert!(!d
            .conclusion
            .verdict_sentence()
            .contains("any static error of the model"));
        confirmed += usize::from(d.conclusion.found == ["dry"]);
        let last = d.steps.last().unwrap();
        let tc = last.params.iter().find(|p| p.name == "tc").unwrap().value;
        assert!((tc / 0.3 - 1.0).abs() < 0.1, "seed {seed}: tc {tc}");
    }
    // The rate over the campaign's three seeds.
    assert!(
        seeds.len() < 3 || confirmed >= 2,
        "confirmed on {confirmed} of 3 seeds"
    );
    for &seed in campaign_seeds(&[31, 32, 33]) {
        let d = workbench(campaign(0.0, 0.02, seed)).discover().unwrap();
        // One input and one output held by the loop: an angle offset b and a torque offset
        // d = -k b / c hold the same levels (k sin(y - b) + c u = 0 against k sin(y) + c (u +
        // d) = 0, to the sine's curvature), so the offset is found as one of them, left
        // tentative, with the other named as a rival, at the closed-form level.
        let added: Vec<&String> = d
            .conclusion
            .found
            .iter()
            .chain(&d.conclusion.tentative)
            .collect();
        let caveats = d.conclusion.caveats.join("; ");
        let (name, level, other) = match added.as_slice() {
            [e] if *e == "sensor_bias" => ("bias_theta", 0.02, "input_bias"),
            [e] if *e == "input_bias" => ("bias_T", -25.0 * 0.02 / 12.0, "sensor_bias"),
            _ => panic!("seed {seed}: added {added:?}; {caveats}"),
        };
        assert!(
            caveats.contains(&format!("{other} fits these data as well")),
            "seed {seed}: {caveats}"
        );
        // Levels alone show an offset, and a static model error shifts them alike: said.
        let verdict = d.conclusion.verdict_sentence();
        assert!(
            verdict.contains("any static error of the model moves the levels"),
            "seed {seed}: {verdict}"
        );
        let last = d.steps.last().unwrap();
        let bias = last.params.iter().find(|p| p.name == name).unwrap().value;
        assert!(
            (bias / level - 1.0).abs() < 0.1,
            "seed {seed}: {name} {bias}, closed form {level}"
        );
    }
}

/// `input_bias` drives the plant with the logged input plus its offset (closed form: the
/// pendulum's `omega' = k sin(theta) + c (T + d)`), its operating point is the logged input
/// that holds the model's (`T = -d`), the linearization does not change, and only a
/// nonlinear model is offered it (a linear model compares deviations).
#[test]
fn an_input_bias_drives_the_plant_with_the_offset_input() {
    let model = Model::new(Arc::new(file(PENDULUM).unwrap()));
    assert!(model.candidates().contains(&"input_bias".to_string()));
    assert!(!model.frf_candidates().contains(&"input_bias".to_string()));
    let biased = model.with_effect("input_bias").unwrap();
    let names: Vec<String> = biased
        .parameters()
        .unwrap()
        .into_iter()
        .map(|p| p.name)
        .collect();
    assert_eq!(names, ["k", "c", "bias_T"]);
    let (k, c, d) = (20.0, 10.0, 0.13);
    let dynamics = biased.dynamics(&[k, c, d]).unwrap();
    let (x0, u0) = dynamics.operating_point();
    assert_eq!((x0, u0), (vec![0.0, 0.0], vec![-d]));
    for (theta, omega, t) in [(0.3, -1.0, 0.2), (-0.7, 2.0, -0.4)] {
        let mut dx = [0.0; 2];
        dynamics
            .f(&[theta, omega], &[t], &mut dx, &mut Vec::new())
            .unwrap();
        let closed = k * f64::sin(theta) + c * (t + d);
        assert!((dx[1] - closed).abs() < 1e-12, "{dx:?} against {closed}");
        assert_eq!(dx[0], omega);
    }
    let plain = model.state_space(&[k, c]).unwrap();
    let with = biased.state_space(&[k, c, d]).unwrap();
    assert!((&plain.a - &with.a).norm() < 1e-9 && (&plain.b - &with.b).norm() < 1e-9);
    let linear = "name = \"p\"\nstates = [\"x\"]\ninputs = [\"u\"]\noutputs = [\"x\"]\n\
                  [linear]\nA = [[-1]]\nB = [[1]]\nC = [[1]]\n";
    let model = Model::new(Arc::new(file(linear).unwrap()));
    assert!(!model.candidates().contains(&"input_bias".to_string()));
}

/// The issue's example, verbatim (`examples/models/pendulum_nonlinear.toml`): its
/// linearization at upright is the closed form, and the dry friction adds
/// `-tc / (eps Jp)` to `A[1][1]`.
#[test]
fn the_documented_example_linearizes_to_the_closed_form() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/models/pendulum_nonlinear.toml");
    let m = ModelFile::from_path(&path).unwrap();
    assert!(m.is_nonlinear());
    let jp: f64 = 0.02 + 0.5 * 0.4 * 0.4;
    let ss = m.state_space(&[], &[0.5, 0.4, 0.02]).unwrap();
    assert!((ss.a[(1, 0)] - 0.5 * 9.81 * 0.4 / jp).abs() < 1e-12);
    assert!((ss.b[(1, 0)] - 1.0 / jp).abs() < 1e-12);
    let with = vec!["joint_coulomb".to_string()];
    let ss = m.state_space(&with, &[0.5, 0.4, 0.02, 0.01]).unwrap();
    assert!((ss.a[(1, 1)] + 0.01 / 0.05 / jp).abs() < 1e-12);
}

/// `compare` and `fit` try no candidate under the time criterion either: a misfit verdict
/// says so (it read "no candidate effect explains it"), in the conclusion and the JSON.
#[test]
fn compare_with_the_time_criterion_claims_no_candidate_test() {
    // Dry friction hidden and not in the model: a structured misfit remains.
    let wb = workbench(campaign(0.3, 0.0, 21));
    let d = wb.compared().unwrap();
    assert_eq!(d.conclusion.candidates, Candidates::Untried);
    assert!(
        d.conclusion.unexplained,
        "{}",
        d.conclusion.verdict_sentence()
    );
    let verdict = d.conclusion.verdict_sentence();
    assert!(
        verdict.contains("no candidate effect was tried") && !verdict.contains("explains it"),
        "{verdict}"
    );
    let json = workbench::report::json(&wb, &d);
    assert_eq!(json["verdict_text"].as_str(), Some(verdict.as_str()));
}

/// Where the time criterion's misfit sits: the angle sensor's mount flexes at 12 Hz, which the
/// file does not describe, and the innovations follow the excitation there. The verdict names
/// the band where they cohere with it and the excitation-output pair: the coherence peaks
/// within the Hann window's main lobe (two bins) of the mode and the band holds it, on 3 of 3
/// seeds (measured: 6.25-15.63 Hz, peak 10.9 Hz on seeds 31 and 32; seed 33 adds a bin at
/// 1.56 Hz, where the fit's compensation of the mode leaves an error, p = 5e-6). On the same
/// records without the mode nothing is located (3 of 3).
#[test]
fn the_time_criterion_locates_a_missing_mode_in_frequency() {
    let f = MODE.0;
    for seed in [31, 32, 33] {
        let wb = workbench(campaign_with_mode(0.0, 0.0, 0.2, seed));
        assert_eq!(wb.criterion(), Criterion::Time);
        let d = wb.compared().unwrap();
        let verdict = d.conclusion.verdict_sentence();
        assert!(d.conclusion.unexplained, "seed {seed}: {verdict}");
        let c = d.steps[0].residual_tests.coherence.as_ref().unwrap();
        let (peak, _, _) = c.outputs[0].peak.unwrap();
        assert!(
            (peak - f).abs() <= 2.0 * c.resolution_hz,
            "seed {seed}: peak at {peak} Hz in bins of {} Hz",
            c.resolution_hz
        );
        let (lo, hi) = c.band_hz.unwrap_or_else(|| panic!("seed {seed}: {c:?}"));
        assert!(lo <= f && f <= hi, "seed {seed}: band {lo}-{hi} Hz");
        assert!(
            verdict.contains(&format!("{lo:.2}-{hi:.2} Hz")) && verdict.contains("r_T->theta"),
            "seed {seed}: {verdict}"
        );
        // The summary prints the location; the HTML report plots it and, the time criterion
        // having no noise reference of its own, states none.
        let summary = workbench::report::table(&wb, &d);
        assert!(
            summary.contains("coherence with the logged excitation"),
            "{summary}"
        );
        let tmp = tempfile::Builder::new()
            .prefix(&format!("stabilis-coherence-{seed}-"))
            .tempdir()
            .unwrap();
        let dir = tmp.path().join("report");
        assert!(
            !dir.exists(),
            "{} is not this test's to remove",
            dir.display()
        );
        workbench::report::write_report(&dir, &wb, &d).unwrap();
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        drop(tmp);
        assert!(
            html.contains("theta: coherence") && !html.contains("Expected cost of the true model"),
            "seed {seed}"
        );
        let clean = workbench(campaign(0.0, 0.0, seed)).compared().unwrap();
        let c = clean.steps[0].residual_tests.coherence.as_ref().unwrap();
        assert!(c.band_hz.is_none(), "seed {seed}: {c:?}");
    }
}

/// A lag the data do not have, added by hand and fitted: it fits to a small fraction of a
/// sample and the model stays explained (3 of 3 seeds), as it was without it. With the lag's
/// bound at 1/40 sample the fit ended on the bound and the verdict read misfit: here on seed
/// 13 (p = 0.007), on a two-wheeled robot's records of higher signal-to-noise ratio on 5 of
/// 5 campaigns.
#[test]
fn a_lag_the_data_do_not_have_fits_to_nothing_and_stays_explained() {
    for seed in [11, 12, 13] {
        let mut wb = workbench(campaign(0.0, 0.0, seed));
        wb.add("actuator_lag").unwrap();
        let d = wb.compared().unwrap();
        assert!(
            !d.conclusion.unexplained,
            "seed {seed}: {}",
            d.conclusion.verdict_sentence()
        );
        let tau = d.steps[0].params.iter().find(|p| p.name == "tau").unwrap();
        let se = tau.std.unwrap_or(0.0);
        assert!(
            tau.value < 0.1 * 0.01 && tau.value < 3.0 * se,
            "seed {seed}: tau {} +- {se}",
            tau.value
        );
    }
}

/// The file's own servo lag, a state of its own, is the built-in `actuator_lag` under another
/// name: under the time criterion the two fit to one time constant but not to one cost (the
/// predictor's noise model carries the file's lag state, the built-in lag filters the input),
/// and the discovery had left the right model tentative, "actuator_lag fits these data as
/// well as servo". Their fitted frequency responses tell them for one effect
/// (`discover::twins`): `servo` is found on 3 of 3 seeds, within 3 standard errors of the
/// simulator's 30 ms, under both criteria.
#[test]
fn the_files_own_lag_state_is_found_beside_its_built_in_twin() {
    let text = format!(
        "{PENDULUM}{}",
        r#"[effects.servo]
description = "first-order servo lag of the torque behind the command"
parameters = { tl = { value = 0.01, min = 0.0005, max = 0.2 } }
states = ["a"]
add.f.a = "(T - a)/tl"
add.torque = "a - T"
operating_point = { a = 0 }
"#
    );
    for seed in [31, 32, 33] {
        for criterion in [Criterion::Time, Criterion::Frf] {
            let data = simulate(Truth { lag: 0.03, ..CLEAN }, seed);
            let wb = workbench_with(&text, data, Some(criterion));
            let d = wb.discover().unwrap();
            let summary = workbench::report::table(&wb, &d);
            assert_eq!(d.conclusion.found, ["servo"], "seed {seed}: {summary}");
            let p = d.steps.last().unwrap().params.iter();
            let tl = p.clone().find(|p| p.name == "tl").unwrap();
            assert!(
                (tl.value - 0.03).abs() < 3.0 * tl.std.unwrap(),
                "seed {seed}: {summary}"
            );
        }
    }
}

/// Logs taken at 1 kHz of a loop whose controller runs at 100 Hz (the input held over ten
/// samples), a 30 ms actuator lag and dry friction of 0.1 hidden: the time criterion reads
/// them at the inputs' rate and finds both, every parameter within 3 standard errors,
/// explained, on 3 of 3 seeds. At every sample its one-step prediction is nearly all sensor
/// noise: seed 43 read "explained" with the lag and a viscous friction, k 74.4 ± 2.5 and c
/// 33.9 ± 1.0 for 25 and 12, tau 89 ms (seeds 41 and 42 found both, k 1.5 errors low). The
/// FRF criterion keeps every sample.
#[test]
fn logs_faster_than_the_controller_are_read_at_the_inputs_rate() {
    let truth = Truth {
        lag: 0.03,
        tc: 0.1,
        fs: 1000.0,
        hold: 10,
        ..CLEAN
    };
    for seed in [41, 42, 43] {
        let wb = workbench(simulate(truth, seed));
        assert_eq!(wb.hold(), Some(10));
        assert_eq!(wb.data().sample_rate_hz, 100.0);
        assert_eq!(wb.data().experiments[0].u.nrows(), 6000);
        let d = wb.discover().unwrap();
        let summary = workbench::report::table(&wb, &d);
        assert!(
            summary.contains("input hold: the inputs change every 10 samples"),
            "{summary}"
        );
        assert_eq!(
            d.conclusion.found,
            ["actuator_lag", "dry"],
            "seed {seed}: {summary}"
        );
        assert!(!d.conclusion.unexplained, "seed {seed}: {summary}");
        let params = &d.steps.last().unwrap().params;
        for (name, truth) in [("k", 25.0), ("c", 12.0), ("tc", 0.1), ("tau", 0.03)] {
            let p = params.iter().find(|p| p.name == name).unwrap();
            assert!(
                (p.value - truth).abs() < 3.0 * p.std.unwrap(),
                "seed {seed}, {name}: {summary}"
            );
        }
        let frf = workbench_with(PENDULUM, simulate(truth, seed), Some(Criterion::Frf));
        assert_eq!((frf.hold(), frf.data().sample_rate_hz), (None, 1000.0));
    }
}

fn workbench_with(text: &str, data: Dataset, criterion: Option<Criterion>) -> Workbench {
    Workbench::with_options(
        Arc::new(file(text).unwrap()),
        data,
        EstimatorChoice::Auto,
        DataOptions {
            criterion,
            ..DataOptions::default()
        },
    )
    .unwrap()
}

/// The JSON's `residuals` and `noise_expected_cost` are the criterion's own: under the time
/// criterion the whitened one-step prediction errors the cost sums (it read the FRF's 324 real
/// residuals and 218.5 against costs of 32 000) and no noise reference; under the FRF
/// criterion its lines' real residuals and the Monte-Carlo reference.
#[test]
fn the_json_counts_the_criterions_own_residuals() {
    let wb = workbench(campaign(0.0, 0.0, 11));
    let d = wb.compared().unwrap();
    let json = workbench::report::json(&wb, &d);
    assert!(json.get("noise_expected_cost").is_none(), "{json}");
    let n = json["residuals"].as_u64().unwrap() as f64;
    let st = &d.steps[0];
    // Two experiments of 6000 samples less the predictor's start-up, one output.
    assert!(n > 11_000.0 && n <= 12_000.0, "{n}");
    assert!(
        (st.cost / n - st.normalized_cost).abs() < 1e-12 * st.normalized_cost,
        "cost {} over {n} residuals against {} per residual",
        st.cost,
        st.normalized_cost
    );
    let wb = workbench_with(PENDULUM, campaign(0.0, 0.0, 11), Some(Criterion::Frf));
    let d = wb.compared().unwrap();
    let json = workbench::report::json(&wb, &d);
    assert_eq!(
        json["noise_expected_cost"].as_f64(),
        Some(wb.noise().mean())
    );
    assert_eq!(
        json["residuals"].as_u64(),
        Some(wb.noise().n_residuals as u64)
    );
}

/// An abandoned candidate's cost is only an upper bound where its fit stopped: its JSON
/// `reduction_percent` is null (it read -9 %), a fitted one's a number; the scores stay.
#[test]
fn an_abandoned_candidate_has_no_reduction_in_the_json() {
    let wb = workbench(campaign(0.0, 0.0, 12));
    let d = wb.discover().unwrap();
    let json = workbench::report::json(&wb, &d);
    let mut abandoned = 0;
    for (st, js) in d.steps.iter().zip(json["steps"].as_array().unwrap()) {
        for (c, jc) in st
            .candidates
            .iter()
            .zip(js["candidates"].as_array().unwrap())
        {
            assert_eq!(jc["effect"].as_str(), Some(c.effect.as_str()));
            if c.abandoned {
                abandoned += 1;
                assert!(jc["reduction_percent"].is_null(), "{jc}");
            } else {
                assert_eq!(jc["reduction_percent"].as_f64(), Some(c.reduction_percent));
            }
            assert_eq!(jc["cost"].as_f64(), Some(c.cost));
            assert_eq!(jc["p_value"].as_f64(), Some(c.p_value));
        }
    }
    assert!(abandoned > 0, "no candidate was abandoned: nothing tested");
}

/// A parameter the data cannot separate from another (`c` and a gain `g2` enter only as
/// their product): the fit holds the one the structural check says it will (the same rule,
/// `fit::holds`), and the summary says the other values hold given it.
#[test]
fn the_check_and_the_fit_name_the_same_held_parameter() {
    let text = PENDULUM
        .replace(
            "c = { value = 10.0, min = 1.0, max = 100.0 }",
            "c = { value = 10.0, min = 1.0, max = 100.0 }\ng2 = { value = 1.0, min = 0.1, max = 10.0 }",
        )
        .replace("c*torque", "c*g2*torque");
    let wb = workbench_with(&text, campaign(0.0, 0.0, 11), None);
    let model = wb.model();
    let id = workbench::identifiability::analyse(model, &model.documented().unwrap()).unwrap();
    assert_eq!(id.unseparated, vec![vec!["c", "g2"]]);
    assert_eq!(id.holds, ["g2"]);
    let d = wb.compared().unwrap();
    let held: Vec<&str> = d.steps[0]
        .params
        .iter()
        .filter(|p| p.held)
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(held, ["g2"]);
    let summary = workbench::report::table(&wb, &d);
    assert!(
        summary.contains(
            "held at documented values (not separable by the data): g2; the other values and \
             their standard errors hold given g2 at its documented value"
        ),
        "{summary}"
    );
}

/// Documented values far from the truth (k 10x below, c 8x above) end where the right ones
/// do, and are not read as logs in another unit: the predictor is redesigned at the fit until the refit leaves the cost per residual
/// near one. With two fixed rounds a ball-and-beam whose documented inertia and motor constant
/// were 10x off kept a stale gain (0.90 per residual) and missed one of its two frictions.
#[test]
fn far_documented_values_reach_the_same_discovery() {
    let far = PENDULUM
        .replace(
            "k = { value = 20.0, min = 1.0, max = 100.0 }",
            "k = { value = 2.5, min = 1.0, max = 100.0 }",
        )
        .replace(
            "c = { value = 10.0, min = 1.0, max = 100.0 }",
            "c = { value = 96.0, min = 1.0, max = 100.0 }",
        );
    assert_ne!(far, PENDULUM);
    for &seed in campaign_seeds(&[21, 23]) {
        let near = workbench(campaign(0.3, 0.0, seed)).discover().unwrap();
        let d = workbench_with(&far, campaign(0.3, 0.0, seed), None)
            .discover()
            .unwrap();
        let added = |d: &workbench::discover::Discovery| -> Vec<String> {
            d.conclusion
                .found
                .iter()
                .chain(&d.conclusion.tentative)
                .cloned()
                .collect()
        };
        assert_eq!(added(&d), added(&near), "seed {seed}");
        // The documented model fits 374 times better with the angle scaled by 1/57.3, yet the
        // logs' own best factor is 1.6 times that: no unit is named.
        assert!(
            !d.conclusion
                .warnings
                .iter()
                .any(|w| w.contains("scaled by")),
            "seed {seed}: {:?}",
            d.conclusion.warnings
        );
        let (a, b) = (d.steps.last().unwrap(), near.steps.last().unwrap());
        for (p, q) in a.params.iter().zip(&b.params) {
            // Fixed parameters have no standard error and must be equal.
            let se = q.std.unwrap_or(0.0);
            assert!(
                (p.value - q.value).abs() <= se + 1e-12 * q.value.abs(),
                "seed {seed}: {} {} from far, {} +- {se} from near",
                p.name,
                p.value,
                q.value,
            );
        }
    }
}

/// An operating point that is no equilibrium is named when the predictor's design fails on
/// its linearization: a body whose tilt the thrust must show, linearized at zero thrust where
/// the hover needs 1, has an unstable tilt the outputs do not see (the design's own error
/// named only that mode). At the hover the same file designs.
#[test]
fn an_operating_point_off_equilibrium_is_named_when_the_design_fails() {
    let text = |thrust: f64| {
        format!(
            r#"
name = "hover"
states = ["x", "v", "th", "w"]
inputs = ["T"]
outputs = ["x"]
[parameters]
a = {{ value = 4.0, min = 0.1 }}
[nonlinear]
f.x = "v"
f.v = "T*th"
f.th = "w"
f.w = "a*th + (T - 1)"
h.x = "x"
operating_point = {{ x = 0, v = 0, th = 0, w = 0, T = {thrust} }}
"#
        )
    };
    let mut rng = StdRng::seed_from_u64(5);
    let n = 2000;
    let data = Dataset {
        sample_rate_hz: 100.0,
        inputs: vec!["T".into()],
        outputs: vec!["x".into()],
        experiments: vec![Experiment {
            name: "experiment 1".into(),
            u: DMatrix::from_fn(n, 1, |_, _| {
                1.0 + 0.1 * rng.sample::<f64, _>(StandardNormal)
            }),
            y: DMatrix::from_fn(n, 1, |_, _| 0.01 * rng.sample::<f64, _>(StandardNormal)),
            r: None,
            periodic: None,
        }],
    };
    let err = workbench_with(&text(0.0), data.clone(), None)
        .discover()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("the operating point is not an equilibrium (d(w)/dt = -1.0000)")
            && err.matches("hover").count() == 1,
        "{err}"
    );
    let at_hover = workbench_with(&text(1.0), data, None).discover();
    assert!(
        at_hover
            .as_ref()
            .err()
            .is_none_or(|e| !e.to_string().contains("equilibrium")),
        "{:?}",
        at_hover.err()
    );
}

/// An operating point that is not an equilibrium is measured against the closed form and
/// named where a user reads it. The pendulum at `T0 = 0.5` moves at `omega' = c T0 = 5`, all
/// of its row's linear term `c |T0|`; at `theta0 = 0.3` with the balancing torque written to
/// six digits it is still; the FRF criterion's verdict on the off point carries the warning,
/// on the balanced file it does not.
#[test]
fn an_operating_point_off_equilibrium_is_measured_and_named() {
    let off = PENDULUM.replace(
        "operating_point = { theta = 0, omega = 0, T = 0 }",
        "operating_point = { theta = 0, omega = 0, T = 0.5 }",
    );
    let model = Model::new(Arc::new(file(&off).unwrap()));
    let drift = model.drift(&[20.0, 10.0]).unwrap();
    assert_eq!(drift.len(), 1, "{drift:?}");
    assert_eq!(drift[0].state, "omega");
    assert!((drift[0].rate - 5.0).abs() < 1e-12, "{drift:?}");
    assert!((drift[0].relative - 1.0).abs() < 1e-12, "{drift:?}");
    let t0 = -20.0 * 0.3f64.sin() / 10.0;
    let balanced = PENDULUM.replace(
        "operating_point = { theta = 0, omega = 0, T = 0 }",
        &format!("operating_point = {{ theta = 0.3, omega = 0, T = {t0:.6} }}"),
    );
    let model = Model::new(Arc::new(file(&balanced).unwrap()));
    assert!(model.drift(&[20.0, 10.0]).unwrap().is_empty());
    // A linear model has no operating point to drift from.
    let linear = "name = \"p\"\nstates = [\"x\"]\ninputs = [\"u\"]\noutputs = [\"x\"]\n\
                  [linear]\nA = [[-1]]\nB = [[1]]\nC = [[1]]\n";
    let model = Model::new(Arc::new(file(linear).unwrap()));
    assert!(model.drift(&[]).unwrap().is_empty());

    let warned = |text: &str| {
        let d = workbench_with(text, campaign(0.0, 0.0, 11), Some(Criterion::Frf))
            .compared()
            .unwrap();
        d.conclusion
            .warnings
            .iter()
            .any(|w| w.contains("not an equilibrium") && w.contains("d(omega)/dt"))
    };
    assert!(warned(&off));
    assert!(!warned(PENDULUM));
}

/// Under the FRF criterion, logs that rest more than 2 % of the operating point's value from
/// it are named with their mean and the distance (computed here from the logs), since the
/// fit linearized at the operating point makes up the difference: the pendulum's angle read
/// through a mount at 1 rad (`h = theta + 1`), logged 3 % and 1 % above it.
#[test]
fn logs_resting_away_from_the_operating_point_are_named_under_the_frf_criterion() {
    let mounted = PENDULUM.replace("h.theta = \"theta\"", "h.theta = \"theta + 1\"");
    for (shift, named) in [(1.03, true), (1.01, false)] {
        let mut data = campaign(0.0, 0.0, 11);
        for e in &mut data.experiments {
            e.y.add_scalar_mut(shift);
        }
        let mean = data.output_samples(0).sum::<f64>() / data.output_samples(0).count() as f64;
        let d = workbench_with(&mounted, data, Some(Criterion::Frf))
            .compared()
            .unwrap();
        let warning = d
            .conclusion
            .warnings
            .iter()
            .find(|w| w.contains("the logs rest away from the operating point"));
        assert_eq!(warning.is_some(), named, "shift {shift}: {warning:?}");
        if let Some(w) = warning {
            let said = format!(
                "the logged output theta averages {mean:.6} where the operating point gives 1.000000, {:.1} % apart",
                100.0 * (mean - 1.0)
            );
            assert!(w.contains(&said), "{w}\nexpected: {said}");
        }
    }
}

/// Under the FRF criterion, the stand's roll and yaw gyros logged in each other's column, or
/// its two rotors' commands, are named as swapped (the documented model fits the swapped
/// logs to the noise level), and logs in the model's order name no swap.
#[test]
fn two_columns_logged_in_each_others_place_are_named_under_the_frf_criterion() {
    let named = |data: Dataset| {
        let d = workbench_with(STAND, data, Some(Criterion::Frf))
            .compared()
            .unwrap();
        d.conclusion
            .warnings
            .iter()
            .find(|w| w.contains("swapped"))
            .cloned()
    };
    assert_eq!(named(stand(3)), None);
    let mut outputs = stand(3);
    for e in &mut outputs.experiments {
        e.y.swap_columns(2, 3);
    }
    let said = named(outputs).expect("the swapped gyros are named");
    assert!(said.contains("with outputs gx and gz swapped"), "{said}");
    let mut inputs = stand(3);
    for e in &mut inputs.experiments {
        e.u.swap_columns(0, 1);
        if let Some(r) = &mut e.r {
            r.swap_columns(0, 1);
        }
    }
    let said = named(inputs).expect("the swapped rotors are named");
    assert!(said.contains("with inputs T1 and T2 swapped"), "{said}");
}

/// A fit an order of magnitude from the documented values is named beside the verdict, under
/// either criterion: the pendulum's `k` documented at 2 where the plant has 25 fits near 25,
/// 12.5 times it; documented at 20 it is not named.
#[test]
fn a_fit_far_from_the_documented_values_is_named() {
    let off = PENDULUM.replace("k = { value = 20.0", "k = { value = 2.0");
    for criterion in [Criterion::Time, Criterion::Frf] {
        let named = |text: &str| {
            let d = workbench_with(text, campaign(0.0, 0.0, 11), Some(criterion))
                .compared()
                .unwrap();
            let k = d.steps[0]
                .params
                .iter()
                .find(|p| p.name == "k")
                .unwrap()
                .value;
            let warned = d
                .conclusion
                .warnings
                .iter()
                .any(|w| w.contains("parameters fitted far from their documented values (k 1"));
            (k, warned, d.conclusion.verdict_sentence())
        };
        let (k, warned, verdict) = named(&off);
        assert!((k / 25.0 - 1.0).abs() < 0.05, "{criterion:?}: k {k}");
        assert!(
            warned && verdict.contains("times it"),
            "{criterion:?}: {verdict}"
        );
        let (_, warned, verdict) = named(PENDULUM);
        assert!(!warned, "{criterion:?}: {verdict}");
    }
}

/// A candidate's documented value is where its fit starts, not a measured property: the dry
/// friction documented at 0.01 and found near the plant's 0.3 (30 times it) is not named as a
/// parameter fitted far from its documented value (3 of 3 seeds, time criterion), while the
/// model's own `k` documented at 2 still is.
#[test]
fn a_discovered_effect_far_from_its_guess_is_not_named() {
    let guessed = PENDULUM.replace(
        "tc = { value = 0.05, min = 0.0",
        "tc = { value = 0.01, min = 0.0",
    );
    assert_ne!(guessed, PENDULUM);
    for seed in [21, 22, 23] {
        let d = workbench_with(&guessed, campaign(0.3, 0.0, seed), None)
            .discover()
            .unwrap();
        let added: Vec<&String> = d
            .conclusion
            .found
            .iter()
            .chain(&d.conclusion.tentative)
            .collect();
        assert_eq!(added, ["dry"], "seed {seed}");
        let tc = d
            .steps
            .last()
            .unwrap()
            .params
            .iter()
            .find(|p| p.name == "tc")
            .unwrap()
            .value;
        assert!((tc / 0.3 - 1.0).abs() < 0.1, "seed {seed}: tc {tc}");
        let verdict = d.conclusion.verdict_sentence();
        assert!(
            !verdict.contains("fitted far from"),
            "seed {seed}: {verdict}"
        );
    }
    let off = guessed.replace("k = { value = 20.0", "k = { value = 2.0");
    let d = workbench_with(&off, campaign(0.3, 0.0, 21), None)
        .discover()
        .unwrap();
    let verdict = d.conclusion.verdict_sentence();
    assert!(
        verdict.contains("parameters fitted far from their documented values (k 1"),
        "{verdict}"
    );
    assert!(!verdict.contains("tc 3"), "{verdict}");
}

/// An output the model holds constant (its expression reads no state or input at the
/// operating point) is refused by name before any fit: its Kalman predictor has no state to
/// estimate, which panicked in the Riccati check (an empty eigen-decomposition).
#[test]
fn an_output_the_model_holds_constant_is_refused_by_name() {
    let text = PENDULUM.replace(r#"h.theta = "theta""#, r#"h.theta = "0*theta""#);
    assert_ne!(text, PENDULUM);
    let err = Workbench::with_options(
        Arc::new(file(&text).unwrap()),
        campaign(0.0, 0.0, 1),
        EstimatorChoice::Auto,
        DataOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("output theta depends on no state and no input at the documented values"),
        "{err}"
    );
}

/// A 15 ms actuator lag at 200 Hz with the angle read in counts of 0.01 rad (still in 95 % of
/// the samples): the quantization error stays put while the angle sits on a count, a coloured
/// noise. With white innovations assumed the time criterion left a misfit with k about 20
/// times off (its verdict naming the quantizer and the FRF criterion's lag); with the
/// innovations whitened by their autoregression it finds the lag and reads explained, seeds
/// 1-4, every parameter 0.9-2.8 standard errors low (k 21.1-22.9 for 25, tau 12.9-13.7 ms for
/// 15): the quantization error is not the Gaussian noise the likelihood assumes.
#[test]
fn coarsely_quantized_logs_read_the_lag_under_the_time_criterion() {
    let truth = Truth {
        lag: 0.015,
        step: 0.01,
        fs: 200.0,
        ..CLEAN
    };
    for seed in [1, 2, 3] {
        let d = workbench(simulate(truth, seed)).discover().unwrap();
        let verdict = d.conclusion.verdict_sentence();
        assert_eq!(
            d.conclusion.found,
            ["actuator_lag"],
            "seed {seed}: {verdict}"
        );
        assert!(!d.conclusion.unexplained, "seed {seed}: {verdict}");
        let last = d.steps.last().unwrap();
        for (name, truth) in [("k", 25.0), ("c", 12.0), ("tau", 0.015)] {
            let p = last.params.iter().find(|p| p.name == name).unwrap();
            let se = p.std.unwrap();
            assert!(
                (p.value - truth).abs() <= 3.0 * se,
                "seed {seed}: {name} {} ± {se}",
                p.value
            );
        }
    }
    let d = workbench(campaign(0.0, 0.0, 11)).discover().unwrap();
    assert!(
        d.conclusion.warnings.is_empty(),
        "{:?}",
        d.conclusion.warnings
    );
}

/// A balancing stand's roll (unstable, `mgh`) and yaw, two rotors: roll torque `d (T1 - T2)`,
/// yaw torque `kd (T1 + T2)` (the rotors' drag, 5 times weaker per newton than the lever
/// `d`, relative to the inertia), and a disturbance torque of the same size on both axes.
const STAND: &str = r#"
name = "stand"
states = ["phi", "psi", "p", "r"]
inputs = ["T1", "T2"]
outputs = ["phi", "psi", "gx", "gz"]
[parameters]
Ixx = { value = 0.010, min = 0.0 }
Izz = { value = 0.018, min = 0.0 }
mgh = { value = 0.15, min = 0.0 }
d = { value = 0.085, fixed = true }
kd = { value = 0.016, fixed = true }
[nonlinear]
f.phi = "p"
f.psi = "r"
f.p = "(d*(T1 - T2) + mgh*sin(phi))/Ixx"
f.r = "kd*(T1 + T2)/Izz"
h.phi = "phi"
h.psi = "psi"
h.gx = "p"
h.gz = "r"
operating_point = { phi = 0, psi = 0, p = 0, r = 0, T1 = 0, T2 = 0 }
"#;

/// Two records of 6000 samples at 250 Hz of [`STAND`] with `Ixx = 0.0104`, `Izz = 0.0185`,
/// `mgh = 0.157` under PD control of both axes on the measured angles and rates, white
/// excitation of 0.4 N per rotor, torque noise of 0.003 N m on each axis held per sample,
/// angle noise 3 mrad, rate noise 0.02 rad/s; RK4 on 4 sub-steps per sample.
fn stand(seed: u64) -> Dataset {
    stand_with(seed, STAND_TRUTH)
}

/// What [`stand_with`] simulates beside [`STAND`].
#[derive(Clone, Copy)]
struct StandTruth {
    /// Rotor T1's share of its commanded thrust.
    gain: f64,
    /// Time constant of a first-order filter on the roll gyro `gx`, s.
    gyro_lag: f64,
    /// Yaw torque per roll rate, N m s: a coupling no effect of the file describes.
    coupling: f64,
}

const STAND_TRUTH: StandTruth = StandTruth {
    gain: 1.0,
    gyro_lag: 0.0,
    coupling: 0.0,
};

/// One classical Runge-Kutta step of `x' = f(x)` over `h` (the test simulators' integrator,
/// with inputs held over the step).
fn rk4<const N: usize>(f: impl Fn([f64; N]) -> [f64; N], x: [f64; N], h: f64) -> [f64; N] {
    let step = |k: [f64; N], a: f64| std::array::from_fn(|i| x[i] + a * k[i]);
    let k1 = f(x);
    let k2 = f(step(k1, h / 2.0));
    let k3 = f(step(k2, h / 2.0));
    let k4 = f(step(k3, h));
    std::array::from_fn(|j| x[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]))
}

/// [`stand`] under `truth`.
fn stand_with(seed: u64, truth: StandTruth) -> Dataset {
    let (ixx, izz, mgh, d, kd, t) = (0.0104, 0.0185, 0.157, 0.085, 0.016, 1.0 / 250.0);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut normal = move || rng.sample::<f64, _>(StandardNormal);
    let f = |x: [f64; 4], u: [f64; 2], w: [f64; 2]| {
        [
            x[2],
            x[3],
            (d * (u[0] - u[1]) + mgh * x[0].sin() + w[0]) / ixx,
            (kd * (u[0] + u[1]) + truth.coupling * x[2] + w[1]) / izz,
        ]
    };
    let mut experiments = Vec::new();
    for e in 0..2 {
        let n = 6000;
        let (mut u, mut y, mut r) = (
            DMatrix::zeros(n, 2),
            DMatrix::zeros(n, 4),
            DMatrix::zeros(n, 2),
        );
        let (mut x, mut gyro) = ([0.0f64; 4], 0.0f64);
        for i in 0..n {
            let noise = [3e-3, 3e-3, 0.02, 0.02];
            for (j, s) in noise.iter().enumerate() {
                let read = if j == 2 && truth.gyro_lag > 0.0 {
                    gyro
                } else {
                    x[j]
                };
                y[(i, j)] = read + s * normal();
            }
            let roll = -(2.5 * y[(i, 0)] + 0.22 * y[(i, 2)]);
            let yaw = -(1.2 * y[(i, 1)] + 0.2 * y[(i, 3)]);
            for j in 0..2 {
                r[(i, j)] = 0.4 * normal();
                let sign = if j == 0 { 1.0 } else { -1.0 };
                u[(i, j)] = sign * roll / (2.0 * d) + yaw / (2.0 * kd) + r[(i, j)];
            }
            let (ui, w) = (
                [truth.gain * u[(i, 0)], u[(i, 1)]],
                [3e-3 * normal(), 3e-3 * normal()],
            );
            let h = t / 4.0;
            for _ in 0..4 {
                x = rk4(|x| f(x, ui, w), x, h);
                if truth.gyro_lag > 0.0 {
                    gyro += (x[2] - gyro) * (1.0 - (-h / truth.gyro_lag).exp());
                }
            }
        }
        experiments.push(Experiment {
            name: format!("experiment {}", e + 1),
            u,
            y,
            r: Some(r),
            periodic: None,
        });
    }
    Dataset {
        sample_rate_hz: 250.0,
        inputs: vec!["T1".into(), "T2".into()],
        outputs: ["phi", "psi", "gx", "gz"].map(String::from).to_vec(),
        experiments,
    }
}

/// The noise model gives each direction the inputs reach its own share. With one share for
/// all, the stand's yaw (which the rotors reach 9 times more weakly per newton than its roll,
/// where the disturbance torque is the same) got too little process noise, and the true
/// model's fit put `Izz` 4.5-7.5 standard errors high on 4 of 4 seeds (a misfit on seed 1).
/// Now 4 of 4 read explained with `Izz` at -0.3 .. +2.2 and `Ixx` at -0.6 .. +1.0 standard
/// errors; the test allows 4 and 3.
#[test]
fn process_noise_along_each_direction_the_inputs_reach_keeps_the_fit_unbiased() {
    for seed in 1..=4 {
        let wb = Workbench::with_options(
            Arc::new(file(STAND).unwrap()),
            stand(seed),
            EstimatorChoice::Auto,
            DataOptions::default(),
        )
        .unwrap();
        let d = wb.compared().unwrap();
        let p = &d.steps.last().unwrap().params;
        let z = |name: &str, truth: f64| {
            let q = p.iter().find(|q| q.name == name).unwrap();
            (q.value - truth) / q.std.unwrap()
        };
        let summary = workbench::report::table(&wb, &d);
        assert!(!d.conclusion.unexplained, "seed {seed}: {summary}");
        assert!(z("Izz", 0.0185).abs() < 4.0, "seed {seed}: {summary}");
        assert!(z("Ixx", 0.0104).abs() < 3.0, "seed {seed}: {summary}");
    }
}

/// One rotor at 85 % of its commanded thrust, the yaw inertia known (fixed at the truth: with
/// both inertias free a weaker T1 and a stronger T2 fit alike, the inertias rescaled, and the
/// two gains are rivals): discovery adds its gain under either criterion and reads the logs
/// explained, the gain within 3 standard errors and 3 % of the truth, 3 of 3 seeds (measured
/// 0.836-0.855 under the time-domain criterion, standard errors 0.006; 0.841-0.865 under the
/// FRF, 0.007); with both rotors true, nothing is added (the same seeds).
#[test]
fn a_weak_actuator_is_found_by_its_gain() {
    for seed in 1..=3 {
        for criterion in [Criterion::Time, Criterion::Frf] {
            let options = DataOptions {
                criterion: Some(criterion),
                ..DataOptions::default()
            };
            let known = STAND.replace(
                "Izz = { value = 0.018, min = 0.0 }",
                "Izz = { value = 0.0185, fixed = true }",
            );
            let wb = |gain: f64| {
                Workbench::with_options(
                    Arc::new(file(&known).unwrap()),
                    stand_with(
                        seed,
                        StandTruth {
                            gain,
                            ..STAND_TRUTH
                        },
                    ),
                    EstimatorChoice::Auto,
                    options,
                )
                .unwrap()
            };
            let weak = wb(0.85);
            let d = weak.discover().unwrap();
            let summary = workbench::report::table(&weak, &d);
            assert_eq!(d.conclusion.found, ["actuator_gain_T1"], "{summary}");
            assert!(!d.conclusion.unexplained, "{summary}");
            let p = d.steps.last().unwrap().params.iter();
            let g = p.clone().find(|p| p.name == "gain_T1").unwrap();
            let z = (g.value - 0.85) / g.std.unwrap();
            assert!(
                z.abs() < 3.0 && (g.value - 0.85).abs() < 0.03 * 0.85,
                "{summary}"
            );
            let nominal = wb(1.0);
            let d = nominal.discover().unwrap();
            let summary = workbench::report::table(&nominal, &d);
            assert!(d.conclusion.found.is_empty(), "{summary}");
        }
    }
}

/// A 10 ms filter on the roll gyro, which the time-domain criterion does not search: its
/// misfit verdict names what the FRF criterion reads, explained with `sensor_lag_gx` found
/// (3 of 3 seeds), and with a roll-to-yaw coupling no effect describes, under which the FRF
/// criterion reads a misfit too, still the lag and how to fit it (3 of 3; before, nothing).
#[test]
fn an_output_lag_the_frf_criterion_adds_is_named_beside_a_misfit() {
    for &seed in campaign_seeds(&[1, 2, 3]) {
        for coupling in [0.0, 0.03] {
            let truth = StandTruth {
                gyro_lag: 0.01,
                coupling,
                ..STAND_TRUTH
            };
            let wb = Workbench::with_options(
                Arc::new(file(STAND).unwrap()),
                stand_with(seed, truth),
                EstimatorChoice::Auto,
                DataOptions::default(),
            )
            .unwrap();
            let d = wb.discover().unwrap();
            let summary = workbench::report::table(&wb, &d);
            assert!(d.conclusion.unexplained, "{summary}");
            let said = d.conclusion.warnings.join(" ");
            let expected = if coupling == 0.0 {
                "read explained, sensor_lag_gx found"
            } else {
                "read a misfit too, with sensor_lag_gx tentative"
            };
            assert!(said.contains(expected), "seed {seed}: {summary}");
            if coupling > 0.0 {
                assert!(said.contains("`fit --with sensor_lag_gx`"), "{summary}");
            }
        }
    }
}

/// A reaction-wheel pendulum: body angle and rate, wheel speed relative to the body, the motor
/// torque `T` turning the wheel against the body.
const WHEEL: &str = r#"
name = "wheel"
states = ["theta", "omega", "ws"]
inputs = ["T"]
outputs = ["theta", "ws"]
[parameters]
mgl = { value = 0.3, min = 0.01 }
Jb = { value = 0.01, min = 1e-4 }
Jw = { value = 5e-4, min = 1e-6 }
[definitions]
thdd = "(mgl*sin(theta) - T)/Jb"
[nonlinear]
f.theta = "omega"
f.omega = "thdd"
f.ws = "T/Jw - thdd"
h.theta = "theta"
h.ws = "ws"
operating_point = { theta = 0, omega = 0, ws = 0, T = 0 }
"#;

/// Three records of 40 s at 200 Hz of the [`WHEEL`] (truth mgl 0.3, Jb 0.0103, Jw 5.12e-4)
/// balanced by state feedback on the measured angle, a 30 Hz filtered difference of it and the
/// wheel speed, a multisine of 0.02 N m rms on the torque, a white torque disturbance of 0.002
/// N m rms held per sample, sensor noise 2e-4 rad and 0.05 rad/s, and the encoder `offset`.
fn wheel(seed: u64, offset: f64) -> Dataset {
    use std::f64::consts::TAU;
    let (mgl, jb, jw, t): (f64, f64, f64, f64) = (0.3, 0.0103, 5.12e-4, 1.0 / 200.0);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut normal = move || rng.sample::<f64, _>(StandardNormal);
    let f = |x: [f64; 3], tm: f64| {
        let thdd = (mgl * x[0].sin() - tm) / jb;
        [x[1], thdd, tm / jw - thdd]
    };
    let (period, n) = (1000, 8000);
    let phases: Vec<f64> = (0..100).map(|_| TAU * normal()).collect();
    let sines: Vec<f64> = (0..period)
        .map(|k| {
            (1..=100)
                .map(|l| (TAU * l as f64 * k as f64 / period as f64 + phases[l - 1]).cos())
                .sum::<f64>()
        })
        .collect();
    let rms = (sines.iter().map(|v| v * v).sum::<f64>() / period as f64).sqrt();
    let filter = (-TAU * 30.0 * t).exp();
    let experiments = (0..3)
        .map(|e| {
            let (mut u, mut y, mut r) = (
                DMatrix::zeros(n, 1),
                DMatrix::zeros(n, 2),
                DMatrix::zeros(n, 1),
            );
            let (mut x, mut last, mut rate) = ([0.01 * normal(), 0.0, 0.0], None, 0.0);
            for i in 0..n {
                y[(i, 0)] = x[0] + offset + 2e-4 * normal();
                y[(i, 1)] = x[2] + 0.05 * normal();
                let d = (y[(i, 0)] - last.unwrap_or(y[(i, 0)])) / t;
                last = Some(y[(i, 0)]);
                rate = filter * rate + (1.0 - filter) * d;
                r[(i, 0)] = 0.02 * sines[i % period] / rms;
                u[(i, 0)] = 4.12 * y[(i, 0)] + 0.627 * rate + 0.00886 * y[(i, 1)] + r[(i, 0)];
                let tm = u[(i, 0)] + 0.002 * normal();
                let h = t / 10.0;
                for _ in 0..10 {
                    x = rk4(|x| f(x, tm), x, h);
                }
            }
            Experiment {
                name: format!("record {e}"),
                u,
                y,
                r: Some(r),
                periodic: None,
            }
        })
        .collect();
    Dataset {
        sample_rate_hz: 200.0,
        inputs: vec!["T".into()],
        outputs: vec!["theta".into(), "ws".into()],
        experiments,
    }
}

/// A single record of three periods leaves the periodic FRF one degree of freedom for its
/// two outputs' noise: the FRF criterion refuses it naming that, and the time criterion, which
/// does not rest on it, takes the Welch estimate (it refused those logs too) and reads the
/// reaction-wheel pendulum's true model explained, the body inertia within 1 % (3 seeds).
#[test]
fn too_few_periods_for_the_periodic_noise_reference_leave_the_time_criterion_working() {
    for seed in [1, 2, 3] {
        let mut data = wheel(seed, 0.0);
        data.experiments.truncate(1);
        let e = &mut data.experiments[0];
        e.u = e.u.rows(0, 3000).into_owned();
        e.y = e.y.rows(0, 3000).into_owned();
        e.r = e.r.as_ref().map(|r| r.rows(0, 3000).into_owned());
        assert!(data.is_periodic());
        let refused = Workbench::with_options(
            Arc::new(file(WHEEL).unwrap()),
            data.clone(),
            EstimatorChoice::Auto,
            DataOptions {
                criterion: Some(Criterion::Frf),
                ..DataOptions::default()
            },
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
        assert!(
            refused.contains("noise degrees of freedom = 1: need at least 2"),
            "seed {seed}: {refused}"
        );
        let wb = workbench_with(WHEEL, data, None);
        assert!(wb
            .welch_reason()
            .is_some_and(|w| w.contains("needs more periods")));
        let d = wb.compared().unwrap();
        assert!(
            !d.conclusion.unexplained,
            "seed {seed}: {}",
            d.conclusion.verdict_sentence()
        );
        let jb = d.steps[0].params.iter().find(|p| p.name == "Jb").unwrap();
        assert!(
            (jb.value / 0.0103 - 1.0).abs() < 0.01,
            "seed {seed}: Jb {}",
            jb.value
        );
    }
}

/// A model with every parameter held (its true values) is compared and discovered under the
/// time criterion like any other: it read a panic (a Jacobian of no column) where the FRF
/// criterion worked. Its logs read explained with nothing added, and no parameter is shown.
#[test]
fn a_model_with_every_parameter_held_is_compared_and_discovered() {
    let held = WHEEL
        .replace(
            "mgl = { value = 0.3, min = 0.01 }",
            "mgl = { value = 0.3, fixed = true }",
        )
        .replace(
            "Jb = { value = 0.01, min = 1e-4 }",
            "Jb = { value = 0.0103, fixed = true }",
        )
        .replace(
            "Jw = { value = 5e-4, min = 1e-6 }",
            "Jw = { value = 5.12e-4, fixed = true }",
        );
    assert_eq!(held.matches("fixed = true").count(), 3);
    let wb = workbench_with(&held, wheel(1, 0.0), None);
    for d in [wb.compared().unwrap(), wb.discover().unwrap()] {
        assert!(
            !d.conclusion.unexplained,
            "{}",
            d.conclusion.verdict_sentence()
        );
        assert!(d.conclusion.found.is_empty() && d.conclusion.tentative.is_empty());
        assert!(d.steps[0].params.is_empty(), "{:?}", d.steps[0].params);
    }
}

/// The reaction-wheel pendulum's wheel speed moves with the torque noise, so its first
/// differences read 18 times its sensor noise (the angle's 2.5 times): with the sensors'
/// factors searched only together the predictor's gain was off, and its true model read a
/// misfit (seed 1 here: p = 3e-6, the body inertia 5.5 standard errors low; an outside
/// simulator of the same rig 3 of 3). Each sensor's factor is searched alone too, and each
/// record's predictor starts from the state fitted to its first outputs (from the zero state
/// the wheel speed's slow start-up moved the noise search's optimum: explained on 2 of 3, the
/// inertia up to 3.9 standard errors off): explained on 3 of 3, the body inertia within 0.5 %
/// and 3 standard errors on every seed (measured on seeds 1-10: 10 of 10, within 0.32 % and
/// 2.6). With its encoder 0.02 rad off the starting fit drives the gravity torque to its
/// bound, and the offset's candidate stopped short there (nothing added, 3 of 3 on the outside
/// simulator); fitted again from the documented values it is found, explained, within 0.1 %
/// of the offset with the inertia within 1 %, on 3 of 3 (measured on seeds 11-17: 7 of 7,
/// within 0.02 % and 0.82 %; tentative beside a misfit with the inertia 9-10 % low from the
/// zero state).
#[test]
fn a_wheel_speed_moved_by_the_noise_and_an_encoder_offset_read_as_themselves() {
    let mut explained = 0;
    for seed in [1, 2, 3] {
        let d = workbench_with(WHEEL, wheel(seed, 0.0), None)
            .discover()
            .unwrap();
        assert!(
            d.conclusion.found.is_empty() && d.conclusion.tentative.is_empty(),
            "seed {seed}: {}",
            d.conclusion.verdict_sentence()
        );
        explained += usize::from(!d.conclusion.unexplained);
        let last = d.steps.last().unwrap();
        let jb = last.params.iter().find(|p| p.name == "Jb").unwrap();
        let std = jb.std.unwrap();
        assert!(
            (jb.value - 0.0103).abs() < 3.0 * std && (jb.value / 0.0103 - 1.0).abs() < 0.005,
            "seed {seed}: Jb {} ± {std}",
            jb.value
        );
    }
    assert_eq!(explained, 3, "explained on {explained} of 3");
    for seed in [11, 12, 13] {
        let d = workbench_with(WHEEL, wheel(seed, 0.02), None)
            .discover()
            .unwrap();
        assert_eq!(d.conclusion.found, ["sensor_bias"], "seed {seed}");
        assert!(d.conclusion.tentative.is_empty(), "seed {seed}");
        assert!(!d.conclusion.unexplained, "seed {seed}");
        let last = d.steps.last().unwrap();
        let bias = last.params.iter().find(|p| p.name == "bias_theta").unwrap();
        let jb = last.params.iter().find(|p| p.name == "Jb").unwrap();
        assert!(
            (bias.value / 0.02 - 1.0).abs() < 0.001 && (jb.value / 0.0103 - 1.0).abs() < 0.01,
            "seed {seed}: bias {}, Jb {}",
            bias.value,
            jb.value
        );
    }
}
