//! Discrete Fourier transforms of periodic records and the detection of the excited lines.
//!
//! Only a few tens of lines are excited in an identification experiment, so the transform is
//! evaluated directly at the lines that matter (a table of twiddle factors, O(N) per line)
//! instead of a full FFT of every period.
use nalgebra::{Complex, DMatrix};

/// Complex double.
pub type C64 = Complex<f64>;

/// Twiddle factors `exp(-j 2 pi n / N)` for a period of `N` samples.
#[derive(Debug, Clone)]
pub struct Dft {
    twiddle: Vec<C64>,
}

impl Dft {
    /// Twiddle table for periods of `n` samples.
    pub fn new(n: usize) -> Self {
        let twiddle = (0..n)
            .map(|i| {
                let a = -2.0 * std::f64::consts::PI * i as f64 / n as f64;
                C64::new(a.cos(), a.sin())
            })
            .collect();
        Self { twiddle }
    }

    /// Samples per period.
    pub fn len(&self) -> usize {
        self.twiddle.len()
    }

    /// True for an empty period (never built by the workbench).
    pub fn is_empty(&self) -> bool {
        self.twiddle.is_empty()
    }

    /// The twiddle factor `exp(-j 2 pi i / N)`, `i` taken modulo N.
    pub fn twiddle(&self, i: usize) -> C64 {
        self.twiddle[i % self.twiddle.len()]
    }

    /// DFT bin `k` of `x` (length N), normalised by 1/N so that a sine of amplitude a gives a/2.
    pub fn bin(&self, x: impl Iterator<Item = f64>, k: usize) -> C64 {
        let n = self.twiddle.len();
        let mut acc = C64::new(0.0, 0.0);
        let mut idx = 0usize;
        for v in x {
            acc += self.twiddle[idx] * v;
            idx += k;
            if idx >= n {
                idx %= n;
            }
        }
        acc / n as f64
    }
}

/// Mean over the periods of one column, sample by sample (its DFT equals the mean of the
/// period DFTs, by linearity).
pub fn period_mean(
    m: &DMatrix<f64>,
    column: usize,
    start: usize,
    period: usize,
    periods: usize,
) -> Vec<f64> {
    let mut mean = vec![0.0; period];
    for p in 0..periods {
        let base = start + p * period;
        for (i, acc) in mean.iter_mut().enumerate() {
            *acc += m[(base + i, column)];
        }
    }
    let scale = 1.0 / periods as f64;
    mean.iter_mut().for_each(|v| *v *= scale);
    mean
}

/// The excited bins among `1..power.len()` (index 0, the mean, is never excited).
///
/// Excited lines stand far above the rest: the powers are sorted and split at the largest
/// ratio between neighbours, provided it is at least 10 (10 dB). Without such a gap every
/// bin carrying power above 1e-12 of the largest is taken as excited (a full-band signal).
pub fn excited_bins(power: &[f64]) -> Vec<usize> {
    let max = power.iter().skip(1).cloned().fold(0.0_f64, f64::max);
    if max <= 0.0 {
        return Vec::new();
    }
    let floor = 1e-12 * max;
    let mut sorted: Vec<f64> = power.iter().skip(1).map(|p| p.max(floor)).collect();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let mut best_ratio = 1.0;
    let mut threshold = floor;
    for w in sorted.windows(2) {
        let ratio = w[0] / w[1];
        if ratio > best_ratio {
            best_ratio = ratio;
            threshold = w[1];
        }
    }
    if best_ratio < 10.0 {
        threshold = floor;
    }
    (1..power.len()).filter(|&k| power[k] > threshold).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn sine_gives_half_amplitude_at_its_bin() {
        let n = 64;
        let dft = Dft::new(n);
        let x: Vec<f64> = (0..n)
            .map(|i| 3.0 * (2.0 * std::f64::consts::PI * 5.0 * i as f64 / n as f64 + 0.4).cos())
            .collect();
        let b = dft.bin(x.iter().cloned(), 5);
        assert!((b.norm() - 1.5).abs() < 1e-12);
        assert!((b.arg() - 0.4).abs() < 1e-12);
        assert!(dft.bin(x.iter().cloned(), 6).norm() < 1e-12);
    }

    #[test]
    fn finds_lines_above_a_noise_floor() {
        let mut power = vec![1e-3; 40];
        for k in [2, 3, 7, 11] {
            power[k] = 0.5 + k as f64 * 0.01;
        }
        assert_eq!(excited_bins(&power), vec![2, 3, 7, 11]);
    }

    proptest! {
        /// Parseval: the bins of a real period carry its energy.
        #[test]
        fn parseval(x in proptest::collection::vec(-10.0f64..10.0, 16)) {
            let dft = Dft::new(16);
            let energy: f64 = x.iter().map(|v| v * v).sum::<f64>() / 16.0;
            let spectral: f64 = (0..16).map(|k| dft.bin(x.iter().cloned(), k).norm_sqr()).sum();
            prop_assert!((energy - spectral).abs() <= 1e-9 * (1.0 + energy));
        }
    }
}
