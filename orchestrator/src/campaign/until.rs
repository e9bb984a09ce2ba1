//! The running estimate of a campaign's metric and `--until METRIC:±X`: stop once the 95 %
//! confidence interval of the metric's mean is narrower than ±X.
//!
//! The rule is judged on the cases in index order — the first `n` cases, for the smallest `n ≥
//! --min-cases` whose interval is narrow enough — never on the order cases happened to finish, so
//! where a campaign stops (and its table) does not depend on the number of workers. Cases past
//! `n` that were already under way are kept on disk (a later, longer campaign reuses them) but
//! not in the table.

/// `--until`'s metric and half-width.
#[derive(Debug, Clone, PartialEq)]
pub struct Until {
    pub metric: String,
    pub half_width: f64,
}

impl std::str::FromStr for Until {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (metric, x) =
            s.rsplit_once(':').ok_or_else(|| format!("{s:?}: expected METRIC:±X (e.g. worst_err_m:±0.05)"))?;
        let x = x.trim_start_matches('±').trim_start_matches("+-").trim_start_matches("+/-");
        let half_width: f64 = x.parse().map_err(|_| format!("{s:?}: {x:?} is not a number"))?;
        if metric.is_empty() {
            return Err(format!("{s:?}: no metric before the ':'"));
        }
        if !(half_width.is_finite() && half_width > 0.0) {
            return Err(format!("{s:?}: the half-width must be a finite number > 0"));
        }
        Ok(Self { metric: metric.to_string(), half_width })
    }
}

/// The running mean of a metric over cases in index order, with its 95 % interval (normal
/// approximation, 1.959964·s/√n, as `cohort_report::stats::describe`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Running {
    pub n: usize,
    mean: f64,
    m2: f64,
}

impl Running {
    /// Welford's update; non-finite values are not counted.
    pub fn push(&mut self, x: f64) {
        if !x.is_finite() {
            return;
        }
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }

    /// Half-width of the 95 % interval (infinite below two values).
    pub fn half_width(&self) -> f64 {
        if self.n < 2 {
            return f64::INFINITY;
        }
        1.959964 * (self.m2 / (self.n - 1) as f64).sqrt() / (self.n as f64).sqrt()
    }

    /// The estimate as a progress line says it: the mean and its 95 % interval, or why there is
    /// none yet (never a NaN or an infinite width).
    pub fn describe(&self) -> String {
        match self.n {
            0 => "no value yet".to_string(),
            1 => format!("{:.6} (n = 1, no interval before 2 cases)", self.mean),
            n => format!("{:.6} ± {:.6} (95 %, n = {n})", self.mean, self.half_width()),
        }
    }
}

/// The number of leading cases at which `--until` is met: the smallest `n ≥ min_cases` among the
/// first `values.len()` (each `None` until that case has finished) whose interval is narrower than
/// `half_width`. Judged only over the finished prefix.
pub fn met_at(values: &[Option<Option<f64>>], min_cases: usize, half_width: f64) -> Option<usize> {
    let mut r = Running::default();
    for (k, v) in values.iter().enumerate() {
        let Some(v) = v else { return None };
        if let Some(x) = v {
            r.push(*x);
        }
        if k + 1 >= min_cases && r.half_width() < half_width {
            return Some(k + 1);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn until_parses_its_forms_and_refuses_the_rest() {
        let u = |s: &str| s.parse::<Until>();
        assert_eq!(u("e_m:±0.5").unwrap(), Until { metric: "e_m".into(), half_width: 0.5 });
        assert_eq!(u("a.b_m:+-2").unwrap().half_width, 2.0);
        assert_eq!(u("servicer_1.e_m:0.1").unwrap().metric, "servicer_1.e_m");
        for bad in ["e_m", ":1", "e_m:x", "e_m:-1", "e_m:0", "e_m:inf"] {
            assert!(u(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_progress_line_names_no_nan_nor_an_infinite_interval() {
        let mut r = Running::default();
        assert_eq!(r.describe(), "no value yet");
        r.push(2.5);
        assert_eq!(r.describe(), "2.500000 (n = 1, no interval before 2 cases)");
        r.push(f64::NAN);
        assert_eq!(r.n, 1, "a non-finite value is not counted");
        r.push(3.5);
        assert_eq!(r.describe(), format!("3.000000 ± {:.6} (95 %, n = 2)", r.half_width()));
        assert!(r.half_width().is_finite());
    }

    #[test]
    fn the_rule_is_met_on_the_finished_prefix_only() {
        // Alternating 0/1: s ≈ 0.5, half-width ≈ 0.98/√n; < 0.2 from n = 25 on (s grows slightly).
        let xs: Vec<Option<Option<f64>>> = (0..100).map(|i| Some(Some((i % 2) as f64))).collect();
        let n = met_at(&xs, 10, 0.2).unwrap();
        let mut r = Running::default();
        xs[..n].iter().for_each(|x| r.push(x.unwrap().unwrap()));
        assert!(r.half_width() < 0.2);
        let mut before = Running::default();
        xs[..n - 1].iter().for_each(|x| before.push(x.unwrap().unwrap()));
        assert!(before.half_width() >= 0.2);
        // A gap (a case not finished yet) before n: not met, whatever follows.
        let mut gap = xs.clone();
        gap[5] = None;
        assert_eq!(met_at(&gap, 10, 0.2), None);
        // Never before min_cases, even when already narrow.
        let same: Vec<_> = (0..50).map(|_| Some(Some(1.0))).collect();
        assert_eq!(met_at(&same, 10, 0.2), Some(10));
    }
}
