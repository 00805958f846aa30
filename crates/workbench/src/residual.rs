//! Residual tests in the time domain: whiteness (normalised autocorrelation) and the
//! correlation of the residual with past inputs, each against its 99% band `±2.576/√N`
//! (the band of a white residual independent of the inputs), and the lag-0 correlation of the
//! residual with every model state and input.
//!
//! Inputs are correlated only with later residual samples (input leading by `τ >= 0`): on
//! closed-loop data the residual feeds back into later inputs, so correlation at negative lags
//! is expected from the loop and says nothing about the model.
use nalgebra::DMatrix;
use serde::Serialize;

use super::coherence::Coherence;
use super::diagnose::LEVEL;
use super::stats::chi2_sf;

/// Two-sided 99% quantile of the standard normal distribution.
pub const Z99: f64 = 2.575_829_303_548_901;

/// Default number of lags tested.
pub const DEFAULT_LAGS: usize = 25;

/// `Σ_t x_t y_t` over the common length, in eight independent partial sums (so the
/// compiler can keep them in vector registers; the lagged products are most of the cost of
/// the residual tests).
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [0.0; 8];
    let (xc, yc) = (x.chunks_exact(8), y.chunks_exact(8));
    let tail: f64 = xc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in xc.zip(yc) {
        for l in 0..8 {
            acc[l] += a[l] * b[l];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// Sums over several records of the products needed for normalised correlations.
fn lagged_sum(a: &[Vec<f64>], b: &[Vec<f64>], lag: usize) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let n = x.len().min(y.len());
            if lag < n {
                dot(&x[lag..n], &y[..n - lag])
            } else {
                0.0
            }
        })
        .sum()
}

fn centred(x: &[f64]) -> Vec<f64> {
    let m = x.iter().sum::<f64>() / x.len().max(1) as f64;
    x.iter().map(|v| v - m).collect()
}

/// Normalised correlation `r(τ) = Σ_t a_t b_{t-τ} / sqrt(Σ a² Σ b²)` of centred records for
/// `τ = 0..=lags`, pooled over records (each record centred on its own mean).
pub fn correlation(a: &[Vec<f64>], b: &[Vec<f64>], lags: usize) -> Vec<f64> {
    let a: Vec<Vec<f64>> = a.iter().map(|x| centred(x)).collect();
    let b: Vec<Vec<f64>> = b.iter().map(|x| centred(x)).collect();
    centred_correlation(&a, &b, lags)
}

/// [`correlation`] of records already centred.
fn centred_correlation(a: &[Vec<f64>], b: &[Vec<f64>], lags: usize) -> Vec<f64> {
    let norm = (lagged_sum(a, a, 0) * lagged_sum(b, b, 0)).sqrt();
    (0..=lags)
        .map(|l| {
            if norm > 0.0 {
                lagged_sum(a, b, l) / norm
            } else {
                0.0
            }
        })
        .collect()
}

/// A correlation sequence tested against its 99% band.
#[derive(Debug, Clone, Serialize)]
pub struct BandTest {
    /// Half-width of the 99% band.
    pub band: f64,
    /// Lags (samples) whose correlation leaves the band.
    pub outside: Vec<usize>,
    /// Lag of the largest |correlation| among the tested lags.
    pub peak_lag: usize,
    /// The correlation at that lag.
    pub peak: f64,
    /// Family-wise p-value of the peak (Bonferroni over the tested lags, `N r² ~ χ²(1)`).
    pub p_value: f64,
    /// `p_value < 0.01`: the sequence is not what a white, input-independent residual gives.
    pub fails: bool,
    /// The correlation at every lag from 0 (for plots).
    pub correlation: Vec<f64>,
}

impl BandTest {
    /// Tests `r[first..]` of a correlation over `samples` samples.
    fn new(r: &[f64], first: usize, samples: usize) -> Self {
        let band = Z99 / (samples.max(1) as f64).sqrt();
        let outside = (first..r.len()).filter(|&l| r[l].abs() > band).collect();
        let (peak_lag, peak) =
            (first..r.len())
                .map(|l| (l, r[l]))
                .fold((first, 0.0_f64), |acc, (l, v)| {
                    if v.abs() > acc.1.abs() {
                        (l, v)
                    } else {
                        acc
                    }
                });
        let tested = r.len().saturating_sub(first).max(1) as f64;
        let p_value = (chi2_sf(samples as f64 * peak * peak, 1.0) * tested).min(1.0);
        Self {
            band,
            outside,
            peak_lag,
            peak,
            p_value,
            fails: p_value < LEVEL,
            correlation: r.to_vec(),
        }
    }
}

/// Residual tests of one output channel.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelResidual {
    /// Output channel.
    pub output: String,
    /// Whiteness: autocorrelation at lags 1..=L.
    pub whiteness: BandTest,
    /// Residual not white at the 99% level.
    pub not_white: bool,
    /// Cross-correlation with each input leading by 0..=L samples, `(input, test)`.
    pub inputs: Vec<(String, BandTest)>,
    /// Inputs whose cross-correlation test fails.
    pub correlated_inputs: Vec<String>,
    /// Largest |lag-0 correlation| with a model state, `(state index, correlation)`.
    pub state_correlation: Option<(usize, f64)>,
    /// Largest |lag-0 correlation| with an input, `(input, correlation)`.
    pub input_correlation: Option<(String, f64)>,
}

/// Residual tests on all outputs.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualTests {
    /// Which residual was tested.
    pub residual: String,
    /// Lags tested.
    pub lags: usize,
    /// Samples pooled.
    pub samples: usize,
    /// Per output channel.
    pub channels: Vec<ChannelResidual>,
    /// Where in frequency the residuals follow the excitation; set by the prediction-error
    /// criterion when the regressors are independent of the noise (a logged excitation, or
    /// open-loop inputs).
    pub coherence: Option<Coherence>,
}

/// Column `j` of every record, each centred on its own mean.
fn centred_column(records: &[&DMatrix<f64>], j: usize) -> Vec<Vec<f64>> {
    records
        .iter()
        .map(|m| centred(m.column(j).as_slice()))
        .collect()
}

fn strongest<K>(items: impl Iterator<Item = (K, f64)>) -> Option<(K, f64)> {
    items.fold(None, |acc: Option<(K, f64)>, (k, v)| match acc {
        Some((_, b)) if b.abs() >= v.abs() => acc,
        _ => Some((k, v)),
    })
}

/// Tests residuals (one matrix samples x outputs per record) against the inputs (samples x
/// inputs) and model states (samples x states) of the same records. Input leads from
/// `first_input_lag` are tested: 0 for open-loop data, 1 in closed loop, where a controller
/// with feed-through computes `u[k]` from `y[k]` and so correlates the two at lag 0.
pub fn residual_tests(
    residuals: &[&DMatrix<f64>],
    inputs: &[&DMatrix<f64>],
    states: &[&DMatrix<f64>],
    output_names: &[String],
    input_names: &[String],
    lags: usize,
    first_input_lag: usize,
) -> ResidualTests {
    let samples: usize = residuals.iter().map(|r| r.nrows()).sum();
    let nx = states.first().map_or(0, |s| s.ncols());
    let inputs: Vec<Vec<Vec<f64>>> = (0..input_names.len())
        .map(|j| centred_column(inputs, j))
        .collect();
    let states: Vec<Vec<Vec<f64>>> = (0..nx).map(|s| centred_column(states, s)).collect();
    let channels = output_names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let e = centred_column(residuals, i);
            let whiteness = BandTest::new(&centred_correlation(&e, &e, lags), 1, samples);
            let not_white = whiteness.fails;
            let input_r: Vec<Vec<f64>> = inputs
                .iter()
                .map(|u| centred_correlation(&e, u, lags))
                .collect();
            let input_tests: Vec<(String, BandTest)> = input_names
                .iter()
                .zip(&input_r)
                .map(|(iname, r)| (iname.clone(), BandTest::new(r, first_input_lag, samples)))
                .collect();
            let correlated_inputs = input_tests
                .iter()
                .filter(|(_, t)| t.fails)
                .map(|(n, _)| n.clone())
                .collect();
            let input_correlation = strongest(
                input_names
                    .iter()
                    .zip(&input_r)
                    .map(|(n, r)| (n.clone(), r[0])),
            );
            let state_correlation = strongest(
                states
                    .iter()
                    .enumerate()
                    .map(|(s, x)| (s, centred_correlation(&e, x, 0)[0])),
            );
            ChannelResidual {
                output: name.clone(),
                whiteness,
                not_white,
                inputs: input_tests,
                correlated_inputs,
                state_correlation,
                input_correlation,
            }
        })
        .collect();
    ResidualTests {
        residual: "one-step prediction residual".into(),
        lags,
        samples,
        channels,
        coherence: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{rngs::StdRng, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};

    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = StdRng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    fn as_matrix(x: &[f64]) -> DMatrix<f64> {
        DMatrix::from_column_slice(x.len(), 1, x)
    }

    fn run(e: &[f64], u: &[f64]) -> ChannelResidual {
        let (e, u) = (as_matrix(e), as_matrix(u));
        let x = u.clone();
        residual_tests(&[&e], &[&u], &[&x], &["y".into()], &["u".into()], 20, 0)
            .channels
            .remove(0)
    }

    #[test]
    fn white_residual_independent_of_the_input_passes() {
        let (e, u) = (white(5000, 1), white(5000, 2));
        let c = run(&e, &u);
        assert!(!c.not_white, "{:?}", c.whiteness);
        assert!(c.correlated_inputs.is_empty(), "{:?}", c.inputs);
        assert!(c.whiteness.p_value > 0.01);
    }

    #[test]
    fn fir_filtered_residual_fails_whiteness_at_its_lags() {
        // e_t = w_t + 0.8 w_{t-2}: autocorrelation 0.8 / 1.64 = 0.488 at lag 2, zero elsewhere.
        let w = white(5000, 3);
        let e: Vec<f64> = (0..w.len())
            .map(|t| w[t] + if t >= 2 { 0.8 * w[t - 2] } else { 0.0 })
            .collect();
        let c = run(&e, &white(5000, 4));
        assert!(c.not_white);
        assert_eq!(c.whiteness.outside, vec![2], "{:?}", c.whiteness);
        assert_eq!(c.whiteness.peak_lag, 2);
        assert!(
            (c.whiteness.peak - 0.8 / 1.64).abs() < 0.03,
            "{}",
            c.whiteness.peak
        );
    }

    #[test]
    fn fir_with_two_taps_fails_whiteness() {
        // e_t = w_t + 0.6 w_{t-1} + 0.6 w_{t-3}: correlation at lags 1, 2, 3.
        let w = white(5000, 5);
        let e: Vec<f64> = (0..w.len())
            .map(|t| {
                w[t] + if t >= 1 { 0.6 * w[t - 1] } else { 0.0 }
                    + if t >= 3 { 0.6 * w[t - 3] } else { 0.0 }
            })
            .collect();
        let c = run(&e, &white(5000, 6));
        assert!(c.not_white);
        assert_eq!(c.whiteness.outside, vec![1, 2, 3], "{:?}", c.whiteness);
    }

    #[test]
    fn delayed_input_in_the_residual_peaks_at_its_lag() {
        // e_t = 0.5 u_{t-3} + w_t: correlation 0.5 / sqrt(1.25) = 0.447 at lag 3.
        let u = white(5000, 7);
        let w = white(5000, 8);
        let e: Vec<f64> = (0..u.len())
            .map(|t| w[t] + if t >= 3 { 0.5 * u[t - 3] } else { 0.0 })
            .collect();
        let c = run(&e, &u);
        let (_, t) = &c.inputs[0];
        assert_eq!(c.correlated_inputs, vec!["u".to_string()]);
        assert_eq!(t.peak_lag, 3);
        assert_eq!(t.outside, vec![3], "{t:?}");
        assert!((t.peak - 0.5 / 1.25f64.sqrt()).abs() < 0.03, "{}", t.peak);
        // A delayed input alone does not colour a residual of white terms.
        assert!(!c.not_white);
        // At lag 0 the residual is uncorrelated with u (and with the state, here u itself).
        assert!(c.input_correlation.unwrap().1.abs() < 0.05);
    }

    #[test]
    fn pooling_records_uses_all_samples() {
        let e1 = as_matrix(&white(1000, 9));
        let e2 = as_matrix(&white(3000, 10));
        let u1 = as_matrix(&white(1000, 11));
        let u2 = as_matrix(&white(3000, 12));
        let r = residual_tests(
            &[&e1, &e2],
            &[&u1, &u2],
            &[&u1, &u2],
            &["y".into()],
            &["u".into()],
            10,
            0,
        );
        assert_eq!(r.samples, 4000);
        assert!((r.channels[0].whiteness.band - Z99 / 4000f64.sqrt()).abs() < 1e-15);
    }

    proptest! {
        /// The eight-way partial sums equal the plain sum over the common length (chunk and
        /// remainder both exercised).
        #[test]
        fn dot_is_the_plain_sum(x in proptest::collection::vec(-5.0f64..5.0, 0..40),
                                seed in 0u64..1000) {
            let y = white(x.len() + (seed % 3) as usize, seed);
            let plain: f64 = x.iter().zip(&y).map(|(a, b)| a * b).sum();
            let scale: f64 = x.iter().zip(&y).map(|(a, b)| (a * b).abs()).sum();
            prop_assert!((dot(&x, &y) - plain).abs() <= 1e-12 * scale.max(1.0));
        }

        /// A normalised correlation is bounded by one (Cauchy-Schwarz), and a record's
        /// autocorrelation at lag 0 is exactly one.
        #[test]
        fn correlation_bounded(x in proptest::collection::vec(-5.0f64..5.0, 8..64),
                               seed in 0u64..1000) {
            let y = white(x.len(), seed);
            let r = correlation(std::slice::from_ref(&x), &[y], 5);
            prop_assert!(r.iter().all(|v| v.abs() <= 1.0 + 1e-12));
            let a = correlation(std::slice::from_ref(&x), std::slice::from_ref(&x), 0);
            let var: f64 = centred(&x).iter().map(|v| v * v).sum();
            if var > 1e-9 {
                prop_assert!((a[0] - 1.0).abs() < 1e-12);
            }
        }
    }
}
