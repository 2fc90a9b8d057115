//! What the random sampling beside a search says about a requirement: of the admissible
//! timings drawn uniformly from the bounds, how many broke it, and the one-sided 95 % upper
//! bound on the probability that a timing drawn so breaks it (Clopper and Pearson's exact
//! binomial bound: C. J. Clopper, E. S. Pearson, "The use of confidence or fiducial limits
//! illustrated in the case of the binomial", Biometrika 26(4), 1934).

use super::search::{Eval, Method};
use super::Objective;

/// The random sampling's evidence on a requirement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampled {
    /// Timings drawn.
    pub n: usize,
    /// Of them, those that broke the requirement (a failed replay counts as broken).
    pub broken: usize,
    /// The one-sided 95 % upper bound on the probability that a timing drawn breaks it.
    pub upper_95: f64,
}

/// The evidence of the random evaluations in `evals` on requirement `objective`.
pub fn sampled<'a>(objective: &Objective, evals: impl Iterator<Item = &'a Eval>) -> Sampled {
    let (mut n, mut broken) = (0, 0);
    for e in evals.filter(|e| e.method == Method::Random) {
        n += 1;
        broken += usize::from(objective.is_requirement() && (!e.error.is_empty() || e.violated));
    }
    Sampled {
        n,
        broken,
        upper_95: upper_95(broken, n),
    }
}

/// The one-sided 95 % Clopper-Pearson upper bound on a probability after `k` events in `n`
/// independent trials: the p at which P(X ≤ k; n, p) = 0.05 (1 when k = n or n = 0).
pub fn upper_95(k: usize, n: usize) -> f64 {
    if k >= n {
        return 1.0;
    }
    // P(X ≤ k) falls from 1 to 0 as p rises from 0 to 1: bisection to the double's precision.
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if binomial_cdf(k, n, mid) > 0.05 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// P(X ≤ k) for X binomial with `n` trials of probability `p` (0 < p < 1), summed in logs.
fn binomial_cdf(k: usize, n: usize, p: f64) -> f64 {
    let (lp, lq) = (p.ln(), (-p).ln_1p());
    let mut ln_choose = 0.0;
    let mut sum = 0.0;
    for i in 0..=k {
        if i > 0 {
            ln_choose += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        sum += (ln_choose + i as f64 * lp + (n - i) as f64 * lq).exp();
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound against its two closed forms: with no event, 1 − 0.05^(1/n) (about 3/n, the
    /// "rule of three"); with one non-event, P(X ≤ n − 1) = 1 − pⁿ gives 0.95^(1/n). In
    /// between, P(X ≤ k) at the bound, summed directly from the binomial terms, is 0.05.
    #[test]
    fn the_bound_is_clopper_pearsons() {
        for n in [1usize, 5, 20, 60, 500] {
            let none = 1.0 - 0.05f64.powf(1.0 / n as f64);
            assert!((upper_95(0, n) - none).abs() < 1e-12, "n {n}");
            if n > 1 {
                let one_kept = 0.95f64.powf(1.0 / n as f64);
                assert!((upper_95(n - 1, n) - one_kept).abs() < 1e-12, "n {n}");
            }
            assert_eq!(upper_95(n, n), 1.0);
        }
        assert!((upper_95(0, 1000) * 1000.0 - 3.0).abs() < 0.01);
        for (k, n) in [(1u64, 10u64), (3, 50), (7, 40)] {
            let p = upper_95(k as usize, n as usize);
            let choose =
                |n: u64, i: u64| (0..i).fold(1.0, |c, j| c * (n - j) as f64 / (j + 1) as f64);
            let cdf: f64 = (0..=k)
                .map(|i| choose(n, i) * p.powi(i as i32) * (1.0 - p).powi((n - i) as i32))
                .sum();
            assert!((cdf - 0.05).abs() < 1e-9, "k {k}, n {n}: {cdf}");
        }
    }
}
