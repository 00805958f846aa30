//! Random-phase multisines with crest-factor selection and the paper's orthogonal
//! 18-experiment design (spec §6.2).

use crate::error::{require_positive, Error, Result};
use crate::geometry::{INPUT_NAMES, N_INPUTS};
use nalgebra::{Complex, DMatrix};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Number of experiments of the paper's design.
pub const N_EXPERIMENTS: usize = 18;

/// One period of a multisine `s[n] = sum_k a_k cos(2 pi k n / N + phi_k)` on DFT bins `k`.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    /// Period length N in samples.
    pub period: usize,
    /// Excited DFT bins (line `k` has frequency `k fs / N`).
    pub bins: Vec<usize>,
    /// Cosine amplitudes per bin, scaled so that the signal has unit RMS.
    pub amplitudes: Vec<f64>,
    /// Phases per bin, rad.
    pub phases: Vec<f64>,
}

impl Multisine {
    /// Amplitude profile `a_k ∝ k^-1/2` (spec §6.2 default), unit RMS.
    pub fn default_amplitudes(bins: &[usize]) -> Vec<f64> {
        let raw: Vec<f64> = bins.iter().map(|&k| 1.0 / (k as f64).sqrt()).collect();
        let rms = (raw.iter().map(|a| a * a).sum::<f64>() / 2.0).sqrt();
        raw.iter().map(|a| a / rms).collect()
    }

    /// Best (lowest crest factor) of `tries` uniform random-phase draws.
    pub fn random_phase(
        period: usize,
        bins: &[usize],
        amplitudes: &[f64],
        tries: usize,
        rng: &mut StdRng,
    ) -> Result<Self> {
        if bins.is_empty() {
            return Err(Error::Invalid {
                name: "bins",
                reason: "no excited line".into(),
            });
        }
        if let Some(&k) = bins.iter().find(|&&k| k == 0 || 2 * k >= period) {
            return Err(Error::Invalid {
                name: "bins",
                reason: format!(
                    "bin {k} must lie in 1..{} (below Nyquist) for period {period}",
                    period.div_ceil(2)
                ),
            });
        }
        if amplitudes.len() != bins.len() {
            return Err(Error::Length {
                what: "amplitudes",
                got: amplitudes.len(),
                expected: bins.len(),
            });
        }
        if tries == 0 {
            return Err(Error::Invalid {
                name: "tries",
                reason: "must be >= 1".into(),
            });
        }
        // cos/sin of 2 pi k n / N on the excited bins, so each draw costs multiply-adds only.
        let table: Vec<(f64, f64)> = bins
            .iter()
            .flat_map(|&k| {
                (0..period).map(move |n| {
                    let angle = core::f64::consts::TAU * ((k * n) % period) as f64 / period as f64;
                    (angle.cos(), angle.sin())
                })
            })
            .collect();
        let mut signal = vec![0.0; period];
        let mut best: Option<(f64, Vec<f64>)> = None;
        for _ in 0..tries {
            let phases: Vec<f64> = bins
                .iter()
                .map(|_| rng.random::<f64>() * core::f64::consts::TAU)
                .collect();
            signal.iter_mut().for_each(|v| *v = 0.0);
            for (i, (a, ph)) in amplitudes.iter().zip(&phases).enumerate() {
                let (c, s) = (a * ph.cos(), a * ph.sin());
                for (v, (cn, sn)) in signal.iter_mut().zip(&table[i * period..(i + 1) * period]) {
                    *v += c * cn - s * sn;
                }
            }
            let cf = crest_factor_of(&signal);
            if best.as_ref().is_none_or(|(b, _)| cf < *b) {
                best = Some((cf, phases));
            }
        }
        best.map(|(_, phases)| Multisine {
            period,
            bins: bins.to_vec(),
            amplitudes: amplitudes.to_vec(),
            phases,
        })
        .ok_or_else(|| Error::Numerical("multisine search".into()))
    }

    /// Sample `n` of the periodic signal with every line shifted by `shift` rad.
    pub fn sample(&self, n: usize, shift: f64) -> f64 {
        let w = core::f64::consts::TAU * (n % self.period) as f64 / self.period as f64;
        self.bins
            .iter()
            .zip(&self.amplitudes)
            .zip(&self.phases)
            .map(|((&k, a), ph)| a * (w * k as f64 + ph + shift).cos())
            .sum()
    }

    /// One period of the signal.
    pub fn period_signal(&self, shift: f64) -> Vec<f64> {
        (0..self.period).map(|n| self.sample(n, shift)).collect()
    }

    /// Crest factor `max |s| / rms(s)` of one period.
    pub fn crest_factor(&self) -> f64 {
        crest_factor_of(&self.period_signal(0.0))
    }

    /// Complex line amplitude `S(k)` on each excited bin (`s = Re sum S e^{j w n}`).
    pub fn spectrum(&self) -> Vec<Complex<f64>> {
        self.amplitudes
            .iter()
            .zip(&self.phases)
            .map(|(a, ph)| Complex::from_polar(*a, *ph))
            .collect()
    }
}

/// `max |s| / rms(s)`.
fn crest_factor_of(s: &[f64]) -> f64 {
    let peak = s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rms = (s.iter().map(|v| v * v).sum::<f64>() / s.len() as f64).sqrt();
    peak / rms
}

/// Which signal, DFT row and input channel experiment `e` (0-based) uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExperimentSlot {
    /// Multisine index 0 (S1) or 1 (S2).
    pub signal: usize,
    /// Row `k` of the 3-point DFT matrix.
    pub dft_row: usize,
    /// Channel: 0 flap 1 (local x), 1 flap 2 (local y), 2 vertical thrust.
    pub channel: usize,
}

impl ExperimentSlot {
    /// The paper's rule (spec §6.2) for experiment `e` in 0..18.
    pub fn of(e: usize) -> Result<Self> {
        if e >= N_EXPERIMENTS {
            return Err(Error::Invalid {
                name: "experiment",
                reason: format!("index {e} not in 0..18"),
            });
        }
        Ok(Self {
            signal: e / 9,
            dft_row: (e % 9) / 3,
            channel: e % 3,
        })
    }

    /// Input columns excited by this experiment.
    pub fn inputs(&self) -> [usize; 3] {
        [self.channel, 3 + self.channel, 6 + self.channel]
    }
}

/// The orthogonal multisine design: `R = [(V ⊗ diag λ) S1; (V ⊗ diag λ) S2]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentDesign {
    /// RMS amplitude per channel (flap 1, flap 2, vertical), N.
    pub lambda: [f64; 3],
    /// The two phase realisations with the same amplitude spectrum.
    pub signals: [Multisine; 2],
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Periods recorded after the transient.
    pub periods: usize,
    /// Samples discarded at the start.
    pub transient: usize,
}

impl ExperimentDesign {
    /// The paper's design: 50 Hz, N = 250, lines 0.2..4 Hz (bins 1..20), amplitude ∝ f^-1/2,
    /// best of 1000 phase draws per signal, 10 periods after 200 transient samples,
    /// λ = (1.2, 0.8, 2.0) N.
    pub fn paper(seed: u64) -> Result<Self> {
        Self::paper_with_lambda([1.2, 0.8, 2.0], seed)
    }

    /// The paper's design (lines, periods, phase search) with excitation RMS `lambda`.
    pub fn paper_with_lambda(lambda: [f64; 3], seed: u64) -> Result<Self> {
        Self::new(
            lambda,
            50.0,
            250,
            &(1..=20).collect::<Vec<_>>(),
            1000,
            10,
            200,
            seed,
        )
    }

    /// Excitation RMS (flap 1, flap 2, vertical) that keeps the REF closed loop almost always
    /// inside the flap limits (about 0.1 % of commands clipped, against about 11 % with the
    /// spec's λ = (1.2, 0.8, 2.0): flap 2 has only ±1.5 N of authority, 0.43 N of which the
    /// yaw trim uses, and vertical excitation loads it through the thrust-to-yaw coupling).
    pub const LAMBDA_WITHIN_LIMITS: [f64; 3] = [1.0, 0.4, 0.4];

    /// [`ExperimentDesign::paper`] with [`ExperimentDesign::LAMBDA_WITHIN_LIMITS`].
    pub fn within_limits(seed: u64) -> Result<Self> {
        Self::paper_with_lambda(Self::LAMBDA_WITHIN_LIMITS, seed)
    }

    /// A design with the given settings; both signals share the amplitude spectrum.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        lambda: [f64; 3],
        sample_rate_hz: f64,
        period: usize,
        bins: &[usize],
        tries: usize,
        periods: usize,
        transient: usize,
        seed: u64,
    ) -> Result<Self> {
        for (i, name) in ["lambda[0]", "lambda[1]", "lambda[2]"]
            .into_iter()
            .enumerate()
        {
            require_positive(name, lambda[i])?;
        }
        require_positive("sample_rate_hz", sample_rate_hz)?;
        if periods == 0 {
            return Err(Error::Invalid {
                name: "periods",
                reason: "must be >= 1".into(),
            });
        }
        let amps = Multisine::default_amplitudes(bins);
        let mut rng = StdRng::seed_from_u64(seed);
        let s1 = Multisine::random_phase(period, bins, &amps, tries, &mut rng)?;
        let s2 = Multisine::random_phase(period, bins, &amps, tries, &mut rng)?;
        Ok(Self {
            lambda,
            signals: [s1, s2],
            sample_rate_hz,
            periods,
            transient,
        })
    }

    /// Samples per experiment: transient plus whole periods.
    pub fn samples(&self) -> usize {
        self.transient + self.periods * self.signals[0].period
    }

    /// Excited line frequencies in rad/s.
    pub fn omegas(&self) -> Vec<f64> {
        let s = &self.signals[0];
        s.bins
            .iter()
            .map(|&k| core::f64::consts::TAU * k as f64 * self.sample_rate_hz / s.period as f64)
            .collect()
    }

    /// Excitation of experiment `e` (0-based): one 9-vector per sample. The transient is the
    /// periodic signal run backwards in time, so sample `transient` starts a period.
    pub fn excitation(&self, e: usize) -> Result<Vec<[f64; N_INPUTS]>> {
        let slot = ExperimentSlot::of(e)?;
        let sig = &self.signals[slot.signal];
        let n_per = sig.period;
        let offset = n_per - self.transient % n_per;
        let per_unit: Vec<Vec<f64>> = (0..3)
            .map(|l| {
                // V_{kl} = exp(-j 2 pi k l / 3) shifts every line of unit l by -2 pi k l / 3.
                let shift = -core::f64::consts::TAU * (slot.dft_row * l) as f64 / 3.0;
                sig.period_signal(shift)
                    .iter()
                    .map(|v| v * self.lambda[slot.channel])
                    .collect()
            })
            .collect();
        Ok((0..self.samples())
            .map(|n| {
                let mut r = [0.0; N_INPUTS];
                for (l, sig_l) in per_unit.iter().enumerate() {
                    r[3 * l + slot.channel] = sig_l[(n + offset) % n_per];
                }
                r
            })
            .collect())
    }

    /// Comma-separated names of the inputs experiment `e` excites.
    pub fn excited_names(&self, e: usize) -> Result<String> {
        Ok(ExperimentSlot::of(e)?
            .inputs()
            .iter()
            .map(|&i| INPUT_NAMES[i])
            .collect::<Vec<_>>()
            .join(","))
    }

    /// Excitation matrix `R(line)` (18 x 9) of the complex line amplitudes on each excited line.
    pub fn excitation_matrices(&self) -> Vec<DMatrix<Complex<f64>>> {
        let spectra = [self.signals[0].spectrum(), self.signals[1].spectrum()];
        (0..self.signals[0].bins.len())
            .map(|line| {
                let mut r = DMatrix::<Complex<f64>>::zeros(N_EXPERIMENTS, N_INPUTS);
                for e in 0..N_EXPERIMENTS {
                    let slot = ExperimentSlot {
                        signal: e / 9,
                        dft_row: (e % 9) / 3,
                        channel: e % 3,
                    };
                    for l in 0..3 {
                        let v = Complex::from_polar(
                            1.0,
                            -core::f64::consts::TAU * (slot.dft_row * l) as f64 / 3.0,
                        );
                        r[(e, 3 * l + slot.channel)] =
                            v * self.lambda[slot.channel] * spectra[slot.signal][line];
                    }
                }
                r
            })
            .collect()
    }
}
