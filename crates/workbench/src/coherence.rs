//! Where in frequency a residual follows the excitation: the squared multiple coherence of
//! each output's residual with the regressors (the logged excitation, or the inputs of an
//! open-loop record), over Hann-windowed segments that do not overlap.
//!
//! The time-domain tests say *that* the innovations correlate with the excitation; this says
//! *where*. A model error passes the excitation through the error's frequency response into
//! the residual, so the coherence rises on the error's band. A right model's residual is the
//! noise alone, independent of an external excitation; its segment transforms at one bin are
//! then independent circular Gaussians, whatever the regressors, and the squared multiple
//! coherence over `K` segments and `q` regressors is Beta(q, K - q) exactly (the `R²` of a
//! complex regression of noise on fixed regressors). `P(C² > c) = (1 - c)^(K-1)` for one.
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::diagnose::LEVEL;
use super::frf::CMatrix;
use super::spectra::{Dft, C64};
use super::stats::beta_i;
use super::welch::hann;

/// Segments the location aims for: a bin's coherence must reach about
/// `ln(bins / LEVEL) / K` to be flagged, 0.08 at 128 segments of 256 samples.
const TARGET_SEGMENTS: usize = 128;
/// Fewest segments for a location at all.
const MIN_SEGMENTS: usize = 16;
/// Shortest and longest segment (powers of two).
const SEGMENT_RANGE: (usize, usize) = (32, 512);
/// A regressor is tested at a bin only where its pooled power is at least this fraction of
/// its largest: a multisine excites a few lines, and bins without excitation can show nothing.
const POWER_FLOOR: f64 = 1e-4;
/// Entries listed, largest excess first.
const ENTRIES: usize = 3;

/// The coherence of one output's residual with the regressors, bin by bin.
#[derive(Debug, Clone, Serialize)]
pub struct OutputCoherence {
    /// Output channel.
    pub output: String,
    /// Frequencies (Hz) of the bins where the coherence is significant (Bonferroni over the
    /// tested bins and outputs).
    pub flagged_hz: Vec<f64>,
    /// Bin of the smallest p-value: `(Hz, squared multiple coherence, p-value)`.
    pub peak: Option<(f64, f64, f64)>,
    /// Every tested bin, `(Hz, squared multiple coherence)` (for plots).
    pub bins: Vec<(f64, f64)>,
}

/// Where the residuals cohere with the regressors.
#[derive(Debug, Clone, Serialize)]
pub struct Coherence {
    /// What the residuals were tested against.
    pub against: String,
    /// Samples per segment.
    pub segment: usize,
    /// Segments pooled over the records.
    pub segments: usize,
    /// Bin spacing, Hz.
    pub resolution_hz: f64,
    /// Bins tested (those where some regressor carries power).
    pub bins_tested: usize,
    /// Per tested bin, `(Hz, the coherence above which it is flagged)`.
    pub flag_above: Vec<(f64, f64)>,
    /// Per output channel.
    pub outputs: Vec<OutputCoherence>,
    /// Span (Hz) of the flagged bins over all outputs.
    pub band_hz: Option<(f64, f64)>,
    /// `(output, regressor, mean coherence / its noise-only mean 1/K)`, largest first: which
    /// pair carries the misfit.
    pub worst_entries: Vec<(String, String, f64)>,
}

/// Segment length: the longest power of two in [`SEGMENT_RANGE`] that leaves
/// [`TARGET_SEGMENTS`] over records of `lengths` samples, else the longest that leaves
/// [`MIN_SEGMENTS`] and more than `4 q`; `None` when none does.
fn segment_for(lengths: &[usize], q: usize) -> Option<usize> {
    let count = |l: usize| lengths.iter().map(|n| n / l).sum::<usize>();
    let sizes = || {
        std::iter::successors(Some(SEGMENT_RANGE.1), |l| Some(l / 2))
            .take_while(|&l| l >= SEGMENT_RANGE.0)
    };
    sizes()
        .find(|&l| count(l) >= TARGET_SEGMENTS)
        .or_else(|| sizes().find(|&l| count(l) >= MIN_SEGMENTS.max(4 * q + 1)))
}

/// Windowed transforms at bins `1..L/2` of every segment of column `j` of every record:
/// one matrix bins x segments (normalised by 1/L, which no coherence sees).
fn transforms(records: &[&DMatrix<f64>], j: usize, window: &[f64]) -> CMatrix {
    let l = window.len();
    let dft = Dft::new(l);
    let segments: usize = records.iter().map(|m| m.nrows() / l).sum();
    let mut out = CMatrix::zeros(l / 2 - 1, segments);
    let mut s = 0;
    for m in records {
        let column = m.column(j);
        for seg in 0..m.nrows() / l {
            let x: Vec<f64> = (0..l).map(|n| window[n] * column[seg * l + n]).collect();
            for b in 0..out.nrows() {
                out[(b, s)] = dft.bin(x.iter().copied(), b + 1);
            }
            s += 1;
        }
    }
    out
}

/// `P(R² >= c)` for `R² ~ Beta(q, K - q)`.
fn beta_sf(c: f64, q: usize, k: usize) -> f64 {
    beta_i((k - q) as f64, q as f64, 1.0 - c)
}

/// The coherence `c` with `P(R² >= c) = level` for `R² ~ Beta(q, K - q)`, by bisection (the
/// tail falls monotonically in `c`).
fn threshold(level: f64, q: usize, k: usize) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if beta_sf(mid, q, k) > level {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Squared multiple coherence of `e` (K segment transforms) with the columns of `r`
/// (K x q): `e^H R (R^H R)^-1 R^H e / e^H e`. `None` when `R^H R` is singular.
pub fn multiple_coherence(e: &DVector<C64>, r: &CMatrix) -> Option<f64> {
    let energy = e.norm_squared();
    if energy <= 0.0 {
        return Some(0.0);
    }
    let gram = r.adjoint() * r;
    let proj = r.adjoint() * e;
    let chol = gram.cholesky()?;
    let c = proj.dotc(&chol.solve(&proj)).re / energy;
    c.is_finite().then_some(c.clamp(0.0, 1.0))
}

/// Locates the coherence of `residuals` (samples x outputs per record) with `regressors`
/// (samples x regressors, the same records) sampled at `sample_rate_hz`. `None` when the
/// records are too short for [`MIN_SEGMENTS`] segments of 32 samples or no bin carries
/// regressor power.
pub fn locate(
    residuals: &[&DMatrix<f64>],
    regressors: &[&DMatrix<f64>],
    output_names: &[String],
    regressor_names: &[String],
    sample_rate_hz: f64,
    against: &str,
) -> Option<Coherence> {
    let q = regressor_names.len();
    let lengths: Vec<usize> = residuals
        .iter()
        .zip(regressors)
        .map(|(e, r)| e.nrows().min(r.nrows()))
        .collect();
    if q == 0 || lengths.is_empty() {
        return None;
    }
    let l = segment_for(&lengths, q)?;
    // Both sides cut to the common length of each record.
    let cut = |m: &[&DMatrix<f64>]| -> Vec<DMatrix<f64>> {
        m.iter()
            .zip(&lengths)
            .map(|(x, &n)| x.rows(0, n).into_owned())
            .collect()
    };
    let (res, reg) = (cut(residuals), cut(regressors));
    let (res, reg): (Vec<&DMatrix<f64>>, Vec<&DMatrix<f64>>) =
        (res.iter().collect(), reg.iter().collect());
    let window = hann(l);
    let rt: Vec<CMatrix> = (0..q).map(|j| transforms(&reg, j, &window)).collect();
    let et: Vec<CMatrix> = (0..output_names.len())
        .map(|i| transforms(&res, i, &window))
        .collect();
    let bins = l / 2 - 1;
    let k = rt[0].ncols();
    let power: Vec<Vec<f64>> = rt
        .iter()
        .map(|t| t.row_iter().map(|row| row.norm_squared()).collect())
        .collect();
    let floors: Vec<f64> = power
        .iter()
        .map(|p| POWER_FLOOR * p.iter().copied().fold(0.0, f64::max))
        .collect();
    // Per bin, the regressors that carry power there.
    let active: Vec<Vec<usize>> = (0..bins)
        .map(|b| {
            (0..q)
                .filter(|&j| floors[j] > 0.0 && power[j][b] >= floors[j])
                .collect()
        })
        .collect();
    let tested: Vec<usize> = (0..bins).filter(|&b| !active[b].is_empty()).collect();
    if tested.is_empty() {
        return None;
    }
    let resolution_hz = sample_rate_hz / l as f64;
    let level = LEVEL / (tested.len() * output_names.len()) as f64;
    let column = |t: &CMatrix, b: usize| -> DVector<C64> { t.row(b).transpose() };
    let outputs: Vec<OutputCoherence> = output_names
        .iter()
        .zip(&et)
        .map(|(name, e)| {
            let mut flagged_hz = Vec::new();
            let mut bins = Vec::new();
            let mut peak: Option<(f64, f64, f64)> = None;
            for &b in &tested {
                let r = CMatrix::from_fn(k, active[b].len(), |s, c| rt[active[b][c]][(b, s)]);
                let Some(c) = multiple_coherence(&column(e, b), &r) else {
                    continue;
                };
                let p = beta_sf(c, active[b].len(), k);
                let hz = (b + 1) as f64 * resolution_hz;
                bins.push((hz, c));
                if p < level {
                    flagged_hz.push(hz);
                }
                if peak.is_none_or(|(_, _, best)| p < best) {
                    peak = Some((hz, c, p));
                }
            }
            OutputCoherence {
                output: name.clone(),
                flagged_hz,
                peak,
                bins,
            }
        })
        .collect();
    let flagged = outputs.iter().flat_map(|o| o.flagged_hz.iter().copied());
    let band_hz = flagged.fold(None, |acc: Option<(f64, f64)>, f| {
        Some(acc.map_or((f, f), |(a, b)| (a.min(f), b.max(f))))
    });
    // Pairwise coherence averaged over the bins where the regressor is tested, against its
    // noise-only mean 1/K.
    let mut worst_entries: Vec<(String, String, f64)> = Vec::new();
    for (name, e) in output_names.iter().zip(&et) {
        for (j, rname) in regressor_names.iter().enumerate() {
            let bins_j: Vec<usize> = tested
                .iter()
                .copied()
                .filter(|b| active[*b].contains(&j))
                .collect();
            let sum: f64 = bins_j
                .iter()
                .filter_map(|&b| {
                    let r = CMatrix::from_fn(k, 1, |s, _| rt[j][(b, s)]);
                    multiple_coherence(&column(e, b), &r)
                })
                .sum();
            if !bins_j.is_empty() {
                let excess = sum / bins_j.len() as f64 * k as f64;
                worst_entries.push((name.clone(), rname.clone(), excess));
            }
        }
    }
    worst_entries.sort_by(|a, b| b.2.total_cmp(&a.2));
    worst_entries.truncate(ENTRIES);
    Some(Coherence {
        against: against.to_string(),
        segment: l,
        segments: k,
        resolution_hz,
        bins_tested: tested.len(),
        flag_above: tested
            .iter()
            .map(|&b| {
                let hz = (b + 1) as f64 * resolution_hz;
                (hz, threshold(level, active[b].len(), k))
            })
            .collect(),
        outputs,
        band_hz,
        worst_entries,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{rngs::StdRng, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};

    fn white(n: usize, rng: &mut StdRng) -> Vec<f64> {
        (0..n).map(|_| StandardNormal.sample(rng)).collect()
    }

    fn columns(cols: &[Vec<f64>]) -> DMatrix<f64> {
        DMatrix::from_fn(cols[0].len(), cols.len(), |i, j| cols[j][i])
    }

    fn names(prefix: &str, n: usize) -> Vec<String> {
        (0..n).map(|i| format!("{prefix}{i}")).collect()
    }

    /// `x` through the resonance `1 / (1 - 2 rho cos(w0) z^-1 + rho^2 z^-2)` at `f0` Hz.
    fn resonance(x: &[f64], f0: f64, fs: f64, rho: f64) -> Vec<f64> {
        let w0 = 2.0 * std::f64::consts::PI * f0 / fs;
        let (a1, a2) = (2.0 * rho * w0.cos(), -rho * rho);
        let mut y = vec![0.0; x.len()];
        for i in 0..x.len() {
            let y1 = if i >= 1 { y[i - 1] } else { 0.0 };
            let y2 = if i >= 2 { y[i - 2] } else { 0.0 };
            y[i] = x[i] + a1 * y1 + a2 * y2;
        }
        y
    }

    /// On noise independent of the regressors, any bin of any output is flagged in at most
    /// the family-wise 1 % of campaigns (Bonferroni is conservative), and the mean squared
    /// coherence is the Beta(q, K - q) mean q / K, for one and for two regressors: 300
    /// campaigns each of two records, two outputs (measured: 3 and 1 of 300 flagged, means
    /// within 1.2 % and 1.7 % of q / K).
    #[test]
    fn noise_alone_is_flagged_at_the_stated_rate_with_the_beta_mean() {
        for q in [1, 2] {
            let (mut flagged, mut sum, mut count) = (0, 0.0, 0usize);
            let mut k_seen = 0;
            for seed in 0..300 {
                let mut rng = StdRng::seed_from_u64(seed);
                let records: Vec<(DMatrix<f64>, DMatrix<f64>)> = (0..2)
                    .map(|_| {
                        let e = columns(&[white(4200, &mut rng), white(4200, &mut rng)]);
                        let r = columns(&(0..q).map(|_| white(4200, &mut rng)).collect::<Vec<_>>());
                        (e, r)
                    })
                    .collect();
                let e: Vec<&DMatrix<f64>> = records.iter().map(|(e, _)| e).collect();
                let r: Vec<&DMatrix<f64>> = records.iter().map(|(_, r)| r).collect();
                let c = locate(&e, &r, &names("y", 2), &names("r", q), 100.0, "r").unwrap();
                k_seen = c.segments;
                if c.band_hz.is_some() {
                    flagged += 1;
                }
                // The peak's coherence is a minimum over p-values, so the mean is taken over
                // every bin separately.
                let et = transforms(&e, 0, &hann(c.segment));
                let rt: Vec<CMatrix> = (0..q)
                    .map(|j| transforms(&r, j, &hann(c.segment)))
                    .collect();
                for b in 0..et.nrows() {
                    let reg = CMatrix::from_fn(c.segments, q, |s, j| rt[j][(b, s)]);
                    sum += multiple_coherence(&et.row(b).transpose(), &reg).unwrap();
                    count += 1;
                }
            }
            assert!(flagged <= 9, "q = {q}: {flagged} of 300 campaigns flagged");
            let mean = sum / count as f64;
            let expected = q as f64 / k_seen as f64;
            // Standard error of the mean over ~9000 bins is about 1 % of it.
            assert!(
                (mean / expected - 1.0).abs() < 0.05,
                "q = {q}: mean coherence {mean} against q/K = {expected}"
            );
        }
    }

    /// A residual that carries the excitation through a resonance at 12 Hz (100 Hz sampling,
    /// pole radius 0.9: about 3 Hz wide, ringing for some ten samples, well inside a segment) is
    /// located on it: the peak within a bin of 12 Hz, and every flagged bin where the closed-form
    /// coherence `|H|² / (|H|² + 1)` is at least the noise-only mean 1/K, on 5 of 5 seeds. A
    /// bin is flagged exactly where its coherence is above its stated threshold.
    #[test]
    fn a_residual_through_a_resonance_is_located_on_it() {
        let (fs, f0, rho, gain) = (100.0, 12.0, 0.9, 0.15);
        let w0 = 2.0 * std::f64::consts::PI * f0 / fs;
        let true_coherence = |f: f64| {
            let z = C64::from_polar(1.0, -2.0 * std::f64::consts::PI * f / fs);
            let h = gain / (C64::from(1.0) - 2.0 * rho * w0.cos() * z + rho * rho * z * z);
            let p = h.norm_sqr();
            p / (p + 1.0)
        };
        for seed in 0..5 {
            let mut rng = StdRng::seed_from_u64(100 + seed);
            let records: Vec<(DMatrix<f64>, DMatrix<f64>)> = (0..2)
                .map(|_| {
                    let r = white(8000, &mut rng);
                    let through = resonance(&r, f0, fs, rho);
                    let noise = white(8000, &mut rng);
                    let e: Vec<f64> = noise
                        .iter()
                        .zip(&through)
                        .map(|(n, t)| n + gain * t)
                        .collect();
                    (columns(&[e]), columns(&[r]))
                })
                .collect();
            let e: Vec<&DMatrix<f64>> = records.iter().map(|(e, _)| e).collect();
            let r: Vec<&DMatrix<f64>> = records.iter().map(|(_, r)| r).collect();
            let c = locate(&e, &r, &names("y", 1), &names("r", 1), fs, "r").unwrap();
            let out = &c.outputs[0];
            let (peak_hz, _, p) = out.peak.unwrap();
            assert!(
                (peak_hz - f0).abs() <= c.resolution_hz && p < 1e-6,
                "seed {seed}: peak at {peak_hz} Hz (p = {p}), bins of {} Hz",
                c.resolution_hz
            );
            let (lo, hi) = c.band_hz.unwrap();
            assert!(lo <= f0 && f0 <= hi, "seed {seed}: band {lo}-{hi} Hz");
            for &f in &out.flagged_hz {
                assert!(
                    true_coherence(f) >= 1.0 / c.segments as f64,
                    "seed {seed}: {f} Hz flagged, closed-form coherence {}",
                    true_coherence(f)
                );
            }
            for (&(hz, coh), &(at, above)) in out.bins.iter().zip(&c.flag_above) {
                assert_eq!(hz, at);
                assert_eq!(
                    coh > above,
                    out.flagged_hz.contains(&hz),
                    "{hz} Hz: {coh} against {above}"
                );
            }
        }
    }

    /// Of two independent excitations, the one the residual follows is named first, many times
    /// its noise-only level, and the other near 1 (3 of 3 seeds).
    #[test]
    fn the_regressor_the_residual_follows_is_named_first() {
        for seed in 0..3 {
            let mut rng = StdRng::seed_from_u64(200 + seed);
            let (r0, r1, noise) = (
                white(6000, &mut rng),
                white(6000, &mut rng),
                white(6000, &mut rng),
            );
            let e: Vec<f64> = (0..6000)
                .map(|i| noise[i] + 0.5 * r1[i] - if i >= 2 { 0.3 * r1[i - 2] } else { 0.0 })
                .collect();
            let (e, r) = (columns(&[e]), columns(&[r0, r1]));
            let c = locate(&[&e], &[&r], &names("y", 1), &names("r", 2), 50.0, "r").unwrap();
            let first = &c.worst_entries[0];
            let second = &c.worst_entries[1];
            assert_eq!(
                (first.0.as_str(), first.1.as_str()),
                ("y0", "r1"),
                "seed {seed}: {c:?}"
            );
            assert!(
                first.2 > 10.0 && (second.2 - 1.0).abs() < 0.5,
                "seed {seed}: {:?}",
                c.worst_entries
            );
            // Broadband: the whole band is flagged.
            assert!(
                c.outputs[0].flagged_hz.len() * 10 >= c.bins_tested * 9,
                "seed {seed}: {c:?}"
            );
        }
    }

    /// A regressor that carries no power at a bin is not tested there: a sine of the 8th bin
    /// of 64-sample segments leaves its own bin and the window's main lobe.
    #[test]
    fn only_bins_the_excitation_reaches_are_tested() {
        let mut rng = StdRng::seed_from_u64(5);
        let n = 64 * 200;
        let r: Vec<f64> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * 8.0 * i as f64 / 64.0).sin())
            .collect();
        let (e, r) = (columns(&[white(n, &mut rng)]), columns(&[r]));
        let c = locate(&[&e], &[&r], &names("y", 1), &names("r", 1), 64.0, "r").unwrap();
        assert!(c.bins_tested <= 3 && c.bins_tested >= 1, "{c:?}");
    }

    #[test]
    fn records_too_short_give_no_location() {
        let e = DMatrix::from_element(100, 1, 1.0);
        assert!(locate(&[&e], &[&e], &names("y", 1), &names("r", 1), 10.0, "r").is_none());
    }

    proptest! {
        /// The squared coherence lies in [0, 1] and does not change when the residual or a
        /// regressor is scaled.
        #[test]
        fn coherence_is_a_scale_free_fraction(
            x in proptest::collection::vec(-5.0f64..5.0, 24),
            a in 0.1f64..10.0,
            b in 0.1f64..10.0,
        ) {
            let e = DVector::from_fn(8, |i, _| C64::new(x[i], x[i + 8]));
            let r = CMatrix::from_fn(8, 2, |i, j| C64::new(x[(i + 3 * j) % 24], x[16 + i]));
            if let Some(c) = multiple_coherence(&e, &r) {
                prop_assert!((0.0..=1.0).contains(&c));
                let mut r2 = r.clone();
                r2.column_mut(1).scale_mut(b);
                let c2 = multiple_coherence(&(e * C64::from(a)), &r2).unwrap();
                prop_assert!((c - c2).abs() <= 1e-9);
            }
        }
    }
}
