//! Event location: the first root of a segment's Taylor series in τ, by Newton kept in a
//! bracket on the whole polynomial, or on the monotone pieces of its cubic part and polished
//! on the whole.

/// Order of the Taylor series.
pub(super) const ORDER: usize = 5;

/// A polynomial Σ c_k τ^k of degree [`ORDER`] (degree 3 in the tests of [`reach`]).
pub(super) type Poly = [f64; ORDER + 1];

#[inline]
pub(super) fn eval(c: &Poly, t: f64) -> f64 {
    let mut x = c[ORDER];
    for k in (0..ORDER).rev() {
        x = c[k] + t * x;
    }
    x
}

#[inline]
fn slope(c: &Poly, t: f64) -> f64 {
    let mut x = ORDER as f64 * c[ORDER];
    for k in (1..ORDER).rev() {
        x = k as f64 * c[k] + t * x;
    }
    x
}

/// The cubic part c0 + c1 τ + c2 τ² + c3 τ³ of a polynomial.
#[inline]
fn cubic(c: &Poly, t: f64) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * c[3]))
}

#[inline]
fn cubic_slope(c: &Poly, t: f64) -> f64 {
    c[1] + t * (2.0 * c[2] + t * 3.0 * c[3])
}

/// The direction a polynomial leaves its starting value in: the sign of its first non-zero
/// coefficient after c0 (0 if it stays).
#[inline]
pub(super) fn leaving(c: &Poly) -> f64 {
    c[1..]
        .iter()
        .find(|x| **x != 0.0)
        .map_or(0.0, |x| x.signum())
}

/// The first τ in [0, h] at which polynomial `c` reaches `level` travelling in direction
/// `dir` (+1 upwards, −1 downwards); `None` if it does not within h. One already beyond the
/// level, or on it and moving on, reaches it at once. The crossing is found on the cubic part
/// (monotone pieces, safeguarded Newton) and polished by Newton on the whole polynomial; the
/// higher terms are below 1e-6 of the cubic ones over a segment.
#[inline]
pub(super) fn reach(c: &Poly, level: f64, dir: f64, h: f64) -> Option<f64> {
    let g0 = dir * (c[0] - level);
    let mut bound = 0.0;
    for k in (1..=ORDER).rev() {
        bound = (bound + c[k].abs()) * h;
    }
    if g0 + bound < 0.0 {
        return None;
    }
    // The usual case: the slope keeps the sign of c1 over [0, h] (its change is bounded by
    // Σ k |c_k| h^(k−1) < |c1|), so g is monotone: Newton on the whole polynomial from the
    // linear estimate, kept in the bracket.
    let mut dslope = 0.0;
    for k in (2..=ORDER).rev() {
        dslope = dslope * h + k as f64 * c[k].abs();
    }
    dslope *= h;
    if dslope < c[1].abs() {
        if g0 > 0.0 || (g0 == 0.0 && dir * c[1] > 0.0) {
            return Some(0.0);
        }
        if dir * c[1] <= 0.0 || dir * (eval(c, h) - level) <= 0.0 {
            return None;
        }
        // Newton converges quadratically here (|c2| τ ≪ |c1|): after a step of 1e-10 s the
        // error left is below 1e-16 s.
        let t0 = (-g0 / (dir * c[1])).min(h);
        return Some(root(
            |t| dir * (eval(c, t) - level),
            |t| dir * slope(c, t),
            (0.0, h),
            t0,
            1e-10,
        ));
    }
    let t = reach_cubic(c, level, dir, h)?;
    if t == 0.0 {
        return Some(0.0);
    }
    let mut t1 = t;
    for _ in 0..2 {
        let d = slope(c, t1);
        if d == 0.0 {
            break;
        }
        t1 -= (eval(c, t1) - level) / d;
    }
    Some(if t1 > 0.0 && t1 <= h && (t1 - t).abs() < 1e-9 {
        t1
    } else {
        t
    })
}

fn reach_cubic(c: &Poly, level: f64, dir: f64, h: f64) -> Option<f64> {
    let g = |t: f64| dir * (cubic(c, t) - level);
    let g0 = g(0.0);
    if g0 > 0.0 || (g0 == 0.0 && dir * leaving(c) > 0.0) {
        return Some(0.0);
    }
    // Monotone pieces: split at the turning points (roots of the slope) inside (0, h).
    let mut cuts = [h; 3];
    let mut n = 0;
    let (a, b, cc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut push = |t: f64| {
        if t > 0.0 && t < h {
            cuts[n] = t;
            n += 1;
        }
    };
    if a != 0.0 {
        let disc = b * b - 4.0 * a * cc;
        if disc >= 0.0 {
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            if q != 0.0 {
                push(q / a);
                push(cc / q);
            } else {
                push(0.0);
            }
        }
    } else if b != 0.0 {
        push(-cc / b);
    }
    if n == 2 && cuts[0] > cuts[1] {
        cuts.swap(0, 1);
    }
    cuts[n] = h;
    let mut lo = 0.0;
    for &hi in &cuts[..=n] {
        // Strictly past the level: a cubic that only touches it (or stays on it) goes on.
        let (glo, ghi) = (g(lo), g(hi));
        if ghi > 0.0 {
            let t0 = lo + (hi - lo) * (-glo / (ghi - glo));
            let dg = |t: f64| dir * cubic_slope(c, t);
            return Some(root(g, dg, (lo, hi), t0, 1e-14));
        }
        lo = hi;
    }
    None
}

/// The root of monotone `g` (slope `dg`) in `[lo, hi]` with g(lo) ≤ 0 ≤ g(hi), by Newton
/// from `t` kept in the bracket, until a step is below `tol` (s).
fn root(
    g: impl Fn(f64) -> f64,
    dg: impl Fn(f64) -> f64,
    (mut lo, mut hi): (f64, f64),
    mut t: f64,
    tol: f64,
) -> f64 {
    for _ in 0..60 {
        let gt = g(t);
        if gt == 0.0 {
            return t;
        }
        if gt > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let step = gt / dg(t);
        let next = t - step;
        if next > lo && next < hi {
            if step.abs() <= tol {
                return next;
            }
            t = next;
        } else {
            if hi - lo <= 1e-14 {
                return hi;
            }
            t = 0.5 * (lo + hi);
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(c: [f64; 4]) -> Poly {
        let mut x = [0.0; ORDER + 1];
        x[..4].copy_from_slice(&c);
        x
    }

    #[test]
    fn reach_finds_the_first_crossing_of_a_cubic() {
        // Rising line: 2 + 3τ reaches 5 at τ = 1.
        let t = reach(&p([2.0, 3.0, 0.0, 0.0]), 5.0, 1.0, 2.0).unwrap();
        assert!((t - 1.0).abs() < 1e-13);
        assert_eq!(reach(&p([2.0, 3.0, 0.0, 0.0]), 5.0, 1.0, 0.5), None);
        // (τ − 1)(τ − 2)(τ − 3) = τ³ − 6τ² + 11τ − 6 reaches 0 upwards first at 1; its negative
        // reaches 0 downwards first at 1 and is beyond −1 downwards... never (it starts at 6).
        let c = p([-6.0, 11.0, -6.0, 1.0]);
        assert!((reach(&c, 0.0, 1.0, 4.0).unwrap() - 1.0).abs() < 1e-12);
        let neg = c.map(|x| -x);
        assert!((reach(&neg, 0.0, -1.0, 4.0).unwrap() - 1.0).abs() < 1e-12);
        // Beyond the level already: reached at once.
        assert_eq!(reach(&neg, 0.0, 1.0, 4.0), Some(0.0));
        let down = reach(&p([0.0, -1.0, 0.0, 0.0]), -0.5, -1.0, 1.0).unwrap();
        assert!((down - 0.5).abs() < 1e-13);
        // Starting on the level moving away: not reached; moving through: at once.
        assert_eq!(reach(&p([1.0, -1.0, 0.0, 0.0]), 1.0, 1.0, 1.0), None);
        assert_eq!(reach(&p([1.0, 1.0, 0.0, 0.0]), 1.0, 1.0, 1.0), Some(0.0));
        // A parabola that turns back before the level: never reached; one that touches later.
        assert_eq!(reach(&p([0.0, 2.0, -1.0, 0.0]), 1.5, 1.0, 3.0), None);
        let t = reach(&p([0.0, -1.0, 1.0, 0.0]), 2.0, 1.0, 5.0).unwrap();
        assert!((t - 2.0).abs() < 1e-12, "{t}");
        // Up to a local maximum below the level, down, then up through it: τ³ − 6τ² + 11τ − 6
        // has its maximum 0.385 at τ = 1.42 and reaches 1 again at τ = 3.32.
        let t = reach(&c, 1.0, 1.0, 4.0).unwrap();
        assert!((eval(&c, t) - 1.0).abs() < 1e-12 && t > 3.0, "{t}");
        assert_eq!(reach(&c, 0.5, 1.0, 3.0), None);
    }
}
