//! Tail probabilities of the chi-square and F distributions for the significance tests.
//!
//! Written here (Lanczos log-gamma, Lentz continued fractions as in Numerical Recipes) because
//! no statistics crate is among the workspace dependencies and only these three functions are
//! needed; the tests compare them with values from scipy.stats.

/// Natural log of the gamma function (Lanczos, g = 7, n = 9), relative error below 1e-14.
pub fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = G[0];
    let t = x + 7.5;
    for (i, g) in G.iter().enumerate().skip(1) {
        a += g / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let ln_pre = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        // Series for P.
        let mut sum = 1.0 / a;
        let mut term = sum;
        let mut ap = a;
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * ln_pre.exp()
    } else {
        // Continued fraction for Q (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        ln_pre.exp() * h
    }
}

/// Regularised incomplete beta I_x(a, b).
pub fn beta_i(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_cf(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * beta_cf(b, a, 1.0 - x) / b
    }
}

fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let tiny = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..10_000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// P(X > x) for X ~ chi-square with `k` degrees of freedom.
pub fn chi2_sf(x: f64, k: f64) -> f64 {
    gamma_q(0.5 * k, 0.5 * x)
}

/// P(X > f) for X ~ F(d1, d2).
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    beta_i(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f))
}

/// The Clopper-Pearson (exact) two-sided interval of a binomial proportion at confidence
/// `1 - alpha` for `successes` of `trials`: the `alpha / 2` quantile of Beta(x, n - x + 1) and
/// the `1 - alpha / 2` quantile of Beta(x + 1, n - x), found by bisection on [`beta_i`].
/// Its coverage is at least `1 - alpha` for every true proportion (conservative). `(0, 1)`
/// for no trials.
pub fn clopper_pearson(successes: usize, trials: usize, alpha: f64) -> (f64, f64) {
    let (x, n) = (successes.min(trials) as f64, trials as f64);
    // The p with I_p(a, b) = q (I rises with p).
    let quantile = |a: f64, b: f64, q: f64| {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if beta_i(a, b, mid) < q {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let lower = if x == 0.0 {
        0.0
    } else {
        quantile(x, n - x + 1.0, 0.5 * alpha)
    };
    let upper = if x >= n {
        1.0
    } else {
        quantile(x + 1.0, n - x, 1.0 - 0.5 * alpha)
    };
    (lower, upper)
}

/// "p = 0.494" to three decimals, "p > 0.999" where those would round to one (a test that
/// finds nothing does not make its hypothesis certain).
pub(crate) fn p_equals(p: f64) -> String {
    if p > 0.9995 {
        "p > 0.999".to_string()
    } else {
        format!("p = {p:.3}")
    }
}

/// `p = 1.23e-5`, or `p < 1e-300` where it underflows: over thousands of residuals a gross
/// misfit's tail probability rounds to zero, and "p = 0.00e0" reads as a certainty.
pub(crate) fn p_scientific(p: f64) -> String {
    if p < 1e-300 {
        "p < 1e-300".to_string()
    } else {
        format!("p = {p:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_p_value_that_underflows_is_a_bound() {
        assert_eq!(p_scientific(0.0), "p < 1e-300");
        assert_eq!(p_scientific(1.52e-3), "p = 1.52e-3");
    }

    #[test]
    fn a_p_value_that_rounds_to_one_is_not_printed_as_one() {
        assert_eq!(p_equals(0.4944), "p = 0.494");
        assert_eq!(p_equals(0.9994), "p = 0.999");
        assert_eq!(p_equals(0.9996), "p > 0.999");
        assert_eq!(p_equals(1.0), "p > 0.999");
    }

    #[test]
    fn matches_scipy_reference_values() {
        // scipy.stats.chi2.sf / f.sf / special.gammaln.
        assert!((ln_gamma(10.0) - 12.801_827_480_081_469).abs() < 1e-12);
        assert!((ln_gamma(0.3) - 1.095_797_994_818_075_6).abs() < 1e-12);
        assert!((chi2_sf(3.0, 2.0) - 0.223_130_160_148_429_83).abs() < 1e-12);
        assert!((chi2_sf(2200.0, 2160.0) - 0.269_280_104_336_830_03).abs() < 1e-8);
        assert!((f_sf(2.0, 3.0, 10.0) - 0.178_007_407_375_175_42).abs() < 1e-10);
        assert!((f_sf(3.5, 6.0, 2100.0) - 0.001_899_801_151_119_947_3).abs() < 1e-10);
    }

    #[test]
    fn clopper_pearson_matches_closed_forms_and_r() {
        // x = 0 and x = n have closed forms: 1 - (a/2)^(1/n) and (a/2)^(1/n).
        for n in [1usize, 8, 20, 100] {
            let (lo, hi) = clopper_pearson(0, n, 0.05);
            assert_eq!(lo, 0.0);
            assert!(
                (hi - (1.0 - 0.025f64.powf(1.0 / n as f64))).abs() < 1e-12,
                "{n}"
            );
            let (lo, hi) = clopper_pearson(n, n, 0.05);
            assert_eq!(hi, 1.0);
            assert!((lo - 0.025f64.powf(1.0 / n as f64)).abs() < 1e-12, "{n}");
        }
        // R: binom.test(3, 10)$conf.int = 0.06673951 0.65245285;
        // binom.test(17, 20)$conf.int = 0.6210732 0.9679291.
        let (lo, hi) = clopper_pearson(3, 10, 0.05);
        assert!((lo - 0.066_739_51).abs() < 1e-8 && (hi - 0.652_452_85).abs() < 1e-8);
        let (lo, hi) = clopper_pearson(17, 20, 0.05);
        assert!((lo - 0.621_073_2).abs() < 1e-7 && (hi - 0.967_929_1).abs() < 1e-7);
        assert_eq!(clopper_pearson(0, 0, 0.05), (0.0, 1.0));
    }

    proptest! {
        /// Survival functions are probabilities and fall with the statistic.
        #[test]
        fn survival_is_monotone(x in 0.0f64..50.0, dx in 0.01f64..5.0, k in 1.0f64..200.0) {
            let (a, b) = (chi2_sf(x, k), chi2_sf(x + dx, k));
            prop_assert!((0.0..=1.0).contains(&a) && b <= a + 1e-12);
            let (fa, fb) = (f_sf(x, k, 500.0), f_sf(x + dx, k, 500.0));
            prop_assert!((0.0..=1.0).contains(&fa) && fb <= fa + 1e-12);
        }
    }
}
