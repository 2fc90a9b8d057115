//! Percentiles for timing reports, and [`Timings`], which gathers them over a run of any
//! length in constant memory.

use hdrhistogram::Histogram;
use serde::Serialize;

/// p50 / p99 / max of a set of durations, in microseconds.
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct Percentiles {
    /// Number of samples.
    pub n: usize,
    /// Median (µs).
    pub p50: f64,
    /// 99th percentile (µs).
    pub p99: f64,
    /// Maximum (µs).
    pub max: f64,
    /// Mean (µs).
    pub mean: f64,
}

/// Nearest-rank percentiles of `values_us` (sorted in place).
pub fn percentiles(values_us: &mut [f64]) -> Percentiles {
    if values_us.is_empty() {
        return Percentiles::default();
    }
    values_us.sort_by(|a, b| a.total_cmp(b));
    let n = values_us.len();
    let rank = |p: f64| values_us[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
    Percentiles {
        n,
        p50: rank(0.50),
        p99: rank(0.99),
        max: values_us[n - 1],
        mean: values_us.iter().sum::<f64>() / n as f64,
    }
}

/// A distribution of non-negative values (µs, or counts) gathered one at a time in constant
/// memory: an HDR histogram with three significant digits (percentiles within 0.1 % of the
/// exact nearest rank, at a resolution of 0.001), with the count, sum and maximum kept exactly.
/// Over an hour-long run at 1 ms this holds a few kilobytes where a vector of every value
/// held tens of megabytes per series.
#[derive(Clone)]
pub struct Timings {
    h: Histogram<u64>,
    n: usize,
    sum: f64,
    max: f64,
}

impl Default for Timings {
    fn default() -> Self {
        Timings {
            h: Histogram::new(3).expect("three significant digits are valid"),
            n: 0,
            sum: 0.0,
            max: 0.0,
        }
    }
}

impl Timings {
    /// Adds one value (negative values and NaN count as 0).
    pub fn record(&mut self, v: f64) {
        let v = if v.is_finite() && v > 0.0 { v } else { 0.0 };
        // The histogram resizes to take any value; should that ever fail, the value is
        // clamped to the largest it can hold (the exact maximum is kept apart).
        let raw = (v * 1e3).round() as u64;
        if self.h.record(raw).is_err() {
            self.h.saturating_record(raw);
        }
        self.n += 1;
        self.sum += v;
        self.max = self.max.max(v);
    }

    /// Values recorded.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The value at quantile `q` in 0..=1 (nearest rank, to the histogram's resolution).
    pub fn quantile(&self, q: f64) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        (self.h.value_at_quantile(q) as f64 * 1e-3).min(self.max)
    }

    /// How many values lie in `[lo, hi)`.
    pub fn count_between(&self, lo: f64, hi: f64) -> u64 {
        let (lo, hi) = (
            (lo.max(0.0) * 1e3).ceil() as u64,
            (hi.max(0.0) * 1e3).ceil() as u64,
        );
        if hi <= lo {
            return 0;
        }
        self.h
            .iter_recorded()
            .filter(|v| (lo..hi).contains(&v.value_iterated_to()))
            .map(|v| v.count_since_last_iteration())
            .sum()
    }

    /// p50, p99, maximum and mean.
    pub fn percentiles(&self) -> Percentiles {
        if self.n == 0 {
            return Percentiles::default();
        }
        Percentiles {
            n: self.n,
            p50: self.quantile(0.50),
            p99: self.quantile(0.99),
            max: self.max,
            mean: self.sum / self.n as f64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timings_agree_with_the_exact_nearest_rank_within_a_thousandth() {
        // A skewed distribution, as request latencies are: most near 2 µs, a long tail.
        let mut exact: Vec<f64> = (0..100_000u64)
            .map(|i| {
                let u = ((i * 7919) % 100_000) as f64 / 100_000.0;
                2.0 + 0.5 * u + if i % 97 == 0 { 300.0 * u } else { 0.0 }
            })
            .collect();
        let mut t = Timings::default();
        for v in &exact {
            t.record(*v);
        }
        let (a, b) = (t.percentiles(), percentiles(&mut exact));
        assert_eq!(a.n, b.n);
        assert_eq!(a.max, b.max);
        assert!((a.mean - b.mean).abs() <= 1e-9 * b.mean);
        for (x, y) in [(a.p50, b.p50), (a.p99, b.p99)] {
            assert!((x - y).abs() <= 1e-3 * y + 1e-3, "{x} vs {y}");
        }
        assert_eq!(t.count_between(0.0, 1e9), 100_000);
        let below_3 = exact.iter().filter(|v| **v < 3.0).count() as u64;
        let got = t.count_between(0.0, 3.0);
        assert!(got.abs_diff(below_3) <= 100, "{got} vs {below_3}");
        assert_eq!(Timings::default().percentiles().n, 0);
    }

    #[test]
    fn nearest_rank_on_1_to_100() {
        let mut v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let p = percentiles(&mut v);
        assert_eq!(
            (p.n, p.p50, p.p99, p.max, p.mean),
            (100, 50.0, 99.0, 100.0, 50.5)
        );
        assert_eq!(percentiles(&mut []).n, 0);
    }
}
