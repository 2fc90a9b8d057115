//! Floats as every table of a run writes them: shortest round-trip text, one form everywhere
//! (`timeseries.csv`, `events.csv`, the JSON of `run.mcap`), so that a value read from one file
//! is the same double as in another.

/// `x` as [`put_f64`] writes it.
pub fn fmt_f64(x: f64) -> String {
    let mut s = String::new();
    put_f64(x, &mut s);
    s
}

/// Writes `x` in shortest round-trip form: positional (`0.0123`) where that is as short as the
/// exponent form, and with an exponent (`1.5e-7`, `2e22`) below 1e-4 and from 1e16 in
/// magnitude, where the positional form would grow with the exponent (a decayed transient of
/// 1e-300 would take 300 characters). Every value is at most 24 characters, so a row's width
/// stays within a constant of its start over any run length. A whole number keeps its `.0`
/// (`0.0`, `-3.0`), so that a reader that guesses column types from the first rows (polars,
/// DuckDB) reads a float column as floats even where it starts at zero.
///
/// The bytes are those of `std`'s `{x}` (with `.0` for a whole number) and `{x:e}` (test
/// `every_float_is_written_as_std_writes_it`); the shortest digits come from `ryu`, which makes
/// writing a row 1.6-1.8 times faster (`cargo bench -p orchestrator --bench record`).
pub fn put_f64(x: f64, out: &mut String) {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() {
        std_put_f64(x, out);
        return;
    }
    let mut buf = ryu::Buffer::new();
    let text = buf.format_finite(x);
    if halfway_places(x).is_some_and(|k| k == places(text)) {
        // Two shortest forms equally near: `ryu` takes the even last digit, `std` the larger
        // magnitude. Rare (only values with at most 25 binary places or a small odd part).
        std_put_f64(x, out);
        return;
    }
    // `ryu` writes 1e-5 ≤ |x| < 1e16 positionally (whole numbers with `.0`) and the rest as
    // `d.ddde±x`, which is `std`'s `{:e}`; from 1e-5 to 1e-4 the exponent form is ours.
    if a >= 1e-4 {
        out.push_str(text);
        return;
    }
    if a < 1e-5 {
        out.push_str(text);
        return;
    }
    // `0.0000ddd` → `d.dde-5`.
    let (sign, digits) = match text.strip_prefix('-') {
        Some(rest) => ("-", rest),
        None => ("", text),
    };
    let digits = digits
        .strip_prefix("0.0000")
        .expect("ryu writes 1e-5..1e-4 as 0.0000ddd");
    out.push_str(sign);
    out.push_str(&digits[..1]);
    if digits.len() > 1 {
        out.push('.');
        out.push_str(&digits[1..]);
    }
    out.push_str("e-5");
}

/// [`put_f64`] by `std`'s formatting: the reference its fast path matches byte for byte
/// (test `every_float_is_written_as_std_writes_it`), and its path for the rare values where
/// `ryu` rounds differently.
pub(crate) fn std_put_f64(x: f64, out: &mut String) {
    use std::fmt::Write as _;
    let a = x.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e16).contains(&a) {
        let _ = write!(out, "{x:e}");
        return;
    }
    let start = out.len();
    let _ = write!(out, "{x}");
    if a.is_finite() && !out[start..].contains('.') {
        out.push_str(".0");
    }
}

/// The one number of decimal places `k` at which `|x|` could lie exactly halfway between two
/// decimals of `k` places (`|x|·10^k = D + ½`), if there is one a shortest form could end at.
///
/// `2·|x|·10^k` must be an odd integer. With `|x| = m·2^e` and `m = m'·2^t` (`m'` odd) it is
/// `m'·5^k·2^(t+e+1+k)`: odd and whole exactly when `k = −1 − (t + e)` and, for `k < 0`,
/// `5^−k` divides `m'`. A shortest form has at most 17 significant digits, so the exact
/// expansion (`m'·5^(k+1)` digits, for `k ≥ 0`) may have at most 18: `k + 1 ≤ 25`.
pub(crate) fn halfway_places(x: f64) -> Option<i32> {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1 << 52) - 1);
    let (m, e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | 1 << 52, biased - 1075)
    };
    if m == 0 {
        return None;
    }
    let t = m.trailing_zeros() as i32;
    let k = -1 - (t + e);
    // m' < 2^53 < 5^23.
    let whole = k >= 0 || (-k <= 22 && (m >> t).is_multiple_of(5u64.pow((-k) as u32)));
    (k < 25 && whole).then_some(k)
}

/// The decimal places of the last digit of `ryu`'s text (`-1.25` → 2, `1200.0` → −2,
/// `1.5e-7` → 8, `1e22` → −22).
pub(crate) fn places(text: &str) -> i32 {
    let (mantissa, exp) = match text.split_once('e') {
        Some((m, e)) => (m, e.parse::<i32>().expect("ryu writes an integer exponent")),
        None => (text, 0),
    };
    let whole = |int: &str| -((int.len() - int.trim_end_matches('0').len()) as i32);
    let frac = match mantissa.split_once('.') {
        Some((int, "0")) => whole(int),
        Some((_, frac)) => frac.len() as i32,
        None => whole(mantissa),
    };
    frac - exp
}
