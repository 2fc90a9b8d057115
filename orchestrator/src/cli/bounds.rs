//! Every numeric command-line value is parsed by one of these, with its allowed range: a
//! value outside it (or not a number: `NaN`, `inf`, `1e300` for a count, `-1`, a number
//! beyond `u64`) is refused by the argument parser with the option named, the value and
//! the range (exit 2), before anything runs. Integers are parsed as integers (no detour
//! through `f64`), so every count and seed arrives exactly.

use std::ops::RangeInclusive;

/// A parser for an integer in `range`; `unit` is appended to the message (`" ms"`).
pub fn int<T>(
    range: RangeInclusive<T>,
    unit: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone
where
    T: std::str::FromStr + PartialOrd + std::fmt::Display + Copy + Send + Sync + 'static,
{
    move |text: &str| {
        let allowed = || {
            format!(
                "allowed a whole number from {} to {}{unit}",
                range.start(),
                range.end()
            )
        };
        let v: T = text.trim().parse().map_err(|_| allowed())?;
        if range.contains(&v) {
            Ok(v)
        } else {
            Err(allowed())
        }
    }
}

/// How an end of a real interval counts.
#[derive(Clone, Copy, Debug)]
pub enum End {
    /// The end itself is allowed.
    Closed,
    /// Only values strictly inside.
    Open,
}

/// A parser for a finite real number between `lo` and `hi`, each end open or closed.
pub fn real(
    lo: (f64, End),
    hi: (f64, End),
    unit: &'static str,
) -> impl Fn(&str) -> Result<f64, String> + Clone {
    move |text: &str| {
        let allowed = || {
            let l = match lo.1 {
                End::Closed => '[',
                End::Open => '(',
            };
            let h = match hi.1 {
                End::Closed => ']',
                End::Open => ')',
            };
            format!("allowed a number in {l}{}, {}{h}{unit}", lo.0, hi.0)
        };
        let v: f64 = text.trim().parse().map_err(|_| allowed())?;
        let above = match lo.1 {
            End::Closed => v >= lo.0,
            End::Open => v > lo.0,
        };
        let below = match hi.1 {
            End::Closed => v <= hi.0,
            End::Open => v < hi.0,
        };
        // NaN fails both comparisons.
        if above && below {
            Ok(v)
        } else {
            Err(allowed())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_are_exact_and_bounded_and_reals_finite_and_bounded() {
        let seed = int(0..=u64::MAX, "");
        assert_eq!(seed("9007199254740993"), Ok(9_007_199_254_740_993));
        assert_eq!(seed("18446744073709551615"), Ok(u64::MAX));
        for bad in ["18446744073709551616", "-1", "1e3", "1.5", "NaN", ""] {
            assert!(seed(bad).is_err(), "{bad}");
        }
        let jobs = int(1..=256usize, "");
        assert_eq!(
            jobs("0").unwrap_err(),
            "allowed a whole number from 1 to 256"
        );
        let pace = real((1e-6, End::Closed), (1000.0, End::Closed), "");
        assert_eq!(pace("1000"), Ok(1000.0));
        assert_eq!(pace("1e-6"), Ok(1e-6));
        for bad in ["0", "1e-300", "1x", "NaN", "inf", "-inf", "1e300", "-1"] {
            assert!(pace(bad).is_err(), "{bad}");
        }
        assert_eq!(
            pace("nan").unwrap_err(),
            "allowed a number in [0.000001, 1000]"
        );
        let spread = real((0.0, End::Closed), (1.0, End::Open), "");
        assert_eq!(spread("0"), Ok(0.0));
        assert!(spread("1").is_err());
    }
}
