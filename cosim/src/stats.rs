//! Percentiles for timing reports.

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

#[cfg(test)]
mod tests {
    use super::*;

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
