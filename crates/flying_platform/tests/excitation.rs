//! Multisine design (AT-14) and the orthogonal 18-experiment scheme (AT-15).
#![allow(clippy::unwrap_used)]

use flying_platform::excitation::{ExperimentDesign, ExperimentSlot, Multisine};
use nalgebra::{Complex, DMatrix};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::SeedableRng;

/// Plain DFT of one period (reference, independent of the multisine's own formula).
fn dft(x: &[f64]) -> Vec<Complex<f64>> {
    let n = x.len();
    (0..n)
        .map(|k| {
            x.iter()
                .enumerate()
                .map(|(i, v)| {
                    Complex::from_polar(*v, -std::f64::consts::TAU * (k * i) as f64 / n as f64)
                })
                .sum()
        })
        .collect()
}

#[test]
fn paper_multisine_has_exactly_bins_1_to_20_and_low_crest_factor() {
    let design = ExperimentDesign::paper(1).unwrap();
    let s1 = &design.signals[0];
    let x = s1.period_signal(0.0);
    assert_eq!(x.len(), 250);
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / 250.0).sqrt();
    assert!((rms - 1.0).abs() < 1e-12, "unit RMS, got {rms}");
    let spectrum = dft(&x);
    let total: f64 = spectrum.iter().map(|c| c.norm_sqr()).sum();
    let outside: f64 = spectrum
        .iter()
        .enumerate()
        .filter(|(k, _)| !((1..=20).contains(k) || (230..=249).contains(k)))
        .map(|(_, c)| c.norm_sqr())
        .sum();
    assert!(
        outside < 1e-20 * total,
        "energy outside the excited bins: {}",
        outside / total
    );
    assert!(spectrum[1..=20].iter().all(|c| c.norm() > 1.0));
    // Amplitudes ∝ f^-1/2 and the DFT phases are the drawn phases.
    for (i, c) in spectrum[1..=20].iter().enumerate() {
        let a = c.norm() * 2.0 / 250.0;
        assert!((a - s1.amplitudes[i]).abs() < 1e-12);
        assert!(
            (Complex::from_polar(1.0, c.arg()) - Complex::from_polar(1.0, s1.phases[i])).norm()
                < 1e-9
        );
    }
    let cf = s1.crest_factor();
    assert!(cf < 2.1, "crest factor {cf}");
    let s2 = &design.signals[1];
    assert_eq!(s1.amplitudes, s2.amplitudes);
    assert_ne!(s1.phases, s2.phases);
}

#[test]
fn best_of_many_draws_is_the_minimum_crest_factor() {
    let bins: Vec<usize> = (1..=20).collect();
    let amps = Multisine::default_amplitudes(&bins);
    let best =
        Multisine::random_phase(250, &bins, &amps, 200, &mut StdRng::seed_from_u64(5)).unwrap();
    let mut rng = StdRng::seed_from_u64(5);
    let min = (0..200)
        .map(|_| {
            Multisine::random_phase(250, &bins, &amps, 1, &mut rng)
                .unwrap()
                .crest_factor()
        })
        .fold(f64::INFINITY, f64::min);
    assert_eq!(best.crest_factor(), min);
}

#[test]
fn experiment_mapping_follows_the_paper() {
    let flap1: Vec<usize> = (0..18)
        .filter(|&e| ExperimentSlot::of(e).unwrap().channel == 0)
        .map(|e| e + 1)
        .collect();
    let vertical: Vec<usize> = (0..18)
        .filter(|&e| ExperimentSlot::of(e).unwrap().channel == 2)
        .map(|e| e + 1)
        .collect();
    assert_eq!(flap1, [1, 4, 7, 10, 13, 16]);
    assert_eq!(vertical, [3, 6, 9, 12, 15, 18]);
    let d = ExperimentDesign::paper(3).unwrap();
    assert_eq!(d.excited_names(0).unwrap(), "F1x,F2x,F3x");
    assert_eq!(d.excited_names(17).unwrap(), "F1z,F2z,F3z");
    assert!(ExperimentSlot::of(18).is_err());
    // The time-domain excitation carries only the slot's channels and a period starts after the transient.
    let r = d.excitation(4).unwrap();
    assert_eq!(r.len(), 200 + 2500);
    assert!(r
        .iter()
        .all(|v| v.iter().enumerate().all(|(i, x)| i % 3 == 1 || *x == 0.0)));
    let s = d.signals[0].period_signal(-std::f64::consts::TAU / 3.0);
    assert!((r[200][4] - 0.8 * s[0]).abs() < 1e-12 && (r[200 + 250][4] - 0.8 * s[0]).abs() < 1e-12);
}

#[test]
fn excitation_matrix_is_orthogonal_with_condition_max_over_min_lambda() {
    let d = ExperimentDesign::paper(7).unwrap();
    let spectra = [d.signals[0].spectrum(), d.signals[1].spectrum()];
    for (line, r) in d.excitation_matrices().iter().enumerate() {
        let rhr = r.adjoint() * r;
        let scale = 3.0 * (spectra[0][line].norm_sqr() + spectra[1][line].norm_sqr());
        let expected = DMatrix::<Complex<f64>>::from_fn(9, 9, |i, j| {
            if i == j {
                Complex::new(scale * d.lambda[i % 3].powi(2), 0.0)
            } else {
                Complex::new(0.0, 0.0)
            }
        });
        assert!((rhr - &expected).camax() < 1e-10 * scale);
        let sv = r.clone().svd(false, false).singular_values;
        let cond = sv.max() / sv.min();
        assert!((cond - 2.5).abs() < 1e-9, "cond {cond}");
    }
}

#[test]
fn bad_designs_are_named_errors() {
    let bins = [0usize, 3];
    let amps = Multisine::default_amplitudes(&[1, 3]);
    let err =
        Multisine::random_phase(250, &bins, &amps, 10, &mut StdRng::seed_from_u64(0)).unwrap_err();
    assert!(err.to_string().contains("bins"), "{err}");
    let err =
        ExperimentDesign::new([1.0, -1.0, 1.0], 50.0, 250, &[1, 2], 1, 10, 200, 0).unwrap_err();
    assert!(err.to_string().contains("lambda[1]"), "{err}");
}

proptest! {
    /// The time signal's DFT on an excited bin is N/2 times the line's complex amplitude,
    /// for any phases and any DFT-row shift.
    #[test]
    fn line_amplitudes_survive_any_shift(seed in 0u64..1000, shift in 0.0..6.3f64) {
        let bins = [1usize, 4, 9];
        let amps = Multisine::default_amplitudes(&bins);
        let m = Multisine::random_phase(50, &bins, &amps, 1, &mut StdRng::seed_from_u64(seed)).unwrap();
        let x = m.period_signal(shift);
        let spec = dft(&x);
        for (i, &k) in bins.iter().enumerate() {
            let want = m.spectrum()[i] * Complex::from_polar(25.0, shift);
            prop_assert!((spec[k] - want).norm() < 1e-9);
        }
    }
}
