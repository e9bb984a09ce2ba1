//! Sample statistics of a campaign's, a sweep's or a benchmark's results, with **one** quantile
//! rule for every table Cohort writes, so that "P99" means the same in every one.
//!
//! The rule is linear interpolation between order statistics, Hyndman and Fan's definition 7
//! (*Sample quantiles in statistical packages*, The American Statistician 50(4), 1996) — the
//! default of numpy (`np.quantile`, method `"linear"`), pandas, R and Julia, so a user who loads a
//! table's raw column and asks their own tool gets the same number: for `n` sorted values
//! x₀ ≤ … ≤ xₙ₋₁ and q ∈ [0, 1], h = (n − 1)·q and Q(q) = x⌊h⌋ + (h − ⌊h⌋)(x⌊h⌋₊₁ − x⌊h⌋).
//! Q(0) is the minimum, Q(1) the maximum, Q(0.5) the usual median (the mean of the two middle
//! values when n is even).
//!
//! What this does not cover, on purpose: quantiles read from histograms (message latencies in
//! `cohort_runtime::record`, solver times in `cohort_runtime::solver_stats`) are resolved to a bin
//! and stay with their histograms.

/// `values` sorted ascending by [`f64::total_cmp`] (NaN last).
pub fn sorted(values: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = values.into_iter().collect();
    v.sort_by(f64::total_cmp);
    v
}

/// The q-quantile (q ∈ [0, 1], clamped) of `sorted` by the rule of this module; NaN when empty.
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    let n = sorted.len();
    if n == 0 {
        return f64::NAN;
    }
    let h = (n - 1) as f64 * q.clamp(0.0, 1.0);
    let i = h.floor() as usize;
    if i + 1 >= n {
        return sorted[n - 1];
    }
    let frac = h - i as f64;
    if frac == 0.0 { sorted[i] } else { sorted[i] + frac * (sorted[i + 1] - sorted[i]) }
}

/// The median of `sorted` ([`quantile`] at 0.5); NaN when empty.
pub fn median(sorted: &[f64]) -> f64 {
    quantile(sorted, 0.5)
}

/// The arithmetic mean; NaN when empty.
pub fn mean(values: &[f64]) -> f64 {
    if values.is_empty() { f64::NAN } else { values.iter().sum::<f64>() / values.len() as f64 }
}

/// What a table says about one column of results.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Describe {
    pub n: usize,
    pub min: f64,
    pub p1: f64,
    pub median: f64,
    pub p99: f64,
    pub max: f64,
    pub mean: f64,
    /// Sample standard deviation (n − 1 in the denominator; 0 for one value).
    pub std: f64,
    /// Half-width of the normal-approximation 95 % confidence interval of the mean,
    /// 1.959964 · std / √n.
    pub ci95_half: f64,
}

/// [`Describe`] of `values` (any order); every field NaN when empty.
pub fn describe(values: &[f64]) -> Describe {
    let s = sorted(values.iter().copied());
    let n = s.len();
    let m = mean(&s);
    let var = if n > 1 { s.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64 } else { 0.0 };
    let std = if n == 0 { f64::NAN } else { var.sqrt() };
    Describe {
        n,
        min: quantile(&s, 0.0),
        p1: quantile(&s, 0.01),
        median: median(&s),
        p99: quantile(&s, 0.99),
        max: quantile(&s, 1.0),
        mean: m,
        std,
        ci95_half: 1.959_964 * std / (n as f64).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_numpy_linear() {
        // np.quantile([1, 2, 3, 4, 10], [0, .01, .25, .5, .99, 1]) = 1, 1.04, 2, 3, 9.76, 10
        let s = sorted([10.0, 3.0, 1.0, 4.0, 2.0]);
        let want = [(0.0, 1.0), (0.01, 1.04), (0.25, 2.0), (0.5, 3.0), (0.99, 9.76), (1.0, 10.0)];
        for (q, v) in want {
            assert!((quantile(&s, q) - v).abs() < 1e-12, "q = {q}: {} against numpy's {v}", quantile(&s, q));
        }
        assert_eq!(median(&[1.0, 2.0, 3.0, 4.0]), 2.5);
        assert!(quantile(&[], 0.5).is_nan());
        assert_eq!(quantile(&[7.0], 0.99), 7.0);
    }

    #[test]
    fn describe_gives_the_mean_and_its_interval() {
        let d = describe(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]);
        assert_eq!((d.n, d.min, d.max, d.mean), (8, 2.0, 9.0, 5.0));
        // sample variance 32/7
        assert!((d.std - (32.0f64 / 7.0).sqrt()).abs() < 1e-12);
        assert!((d.ci95_half - 1.959_964 * d.std / 8f64.sqrt()).abs() < 1e-12);
        assert!(describe(&[]).mean.is_nan());
    }
}
