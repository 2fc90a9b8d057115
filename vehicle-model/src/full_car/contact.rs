//! Wheel-rail contact: the Hertzian contact ellipse and Kalker's linear creep coefficients.
//!
//! * Hertz (Johnson, *Contact Mechanics*, 1985, §4.2, eqs 4.37-4.39): for relative curvatures
//!   A ≤ B the ellipse's semi-axis a (along A's direction) ≥ b, e² = 1 − b²/a², and
//!   B/A = [E(e)/(1 − e²) − K(e)] / [K(e) − E(e)], P = (2/3)π a b p_0,
//!   A = (p_0/E*)(b/(e²a²))[K(e) − E(e)], so a³ = 3P[K(e) − E(e)] / (2π A E* e²), with
//!   1/E* = 2(1 − ν²)/E for wheel and rail of one material.
//! * Kalker (Kalker 1967, thesis TH Delft, table reproduced in Kalker, *Three-dimensional
//!   elastic bodies in rolling contact*, 1990, and Garg & Dukkipati, *Dynamics of Railway
//!   Vehicle Systems*, 1984, ch. 5): f11 = G a b C11, f22 = G a b C22 (N), G = E/(2(1 + ν)),
//!   C_ij from the table at the ellipse's ratio and ν, interpolated linearly.

/// Complete elliptic integrals K(k) and E(k) of the first and second kind, modulus k < 1,
/// by the arithmetic-geometric mean (Abramowitz & Stegun 17.6).
pub fn elliptic_ke(k: f64) -> (f64, f64) {
    let (mut a, mut b) = (1.0_f64, (1.0 - k * k).sqrt());
    let mut c = k;
    let mut sum = 0.5 * c * c;
    let mut pow = 0.5;
    for _ in 0..40 {
        if c.abs() < 1e-16 {
            break;
        }
        let an = 0.5 * (a + b);
        c = 0.5 * (a - b);
        b = (a * b).sqrt();
        a = an;
        pow *= 2.0;
        sum += pow * c * c;
    }
    let kk = std::f64::consts::PI / (2.0 * a);
    (kk, kk * (1.0 - sum))
}

/// Semi-axes of the Hertzian contact ellipse (m): `(along_x, along_y)` for relative
/// curvatures `ax` (rolling direction) and `ay` (lateral) (1/m), normal load `p` (N),
/// Young's modulus `e` (Pa) and Poisson's ratio `nu`, both bodies of one material.
pub fn hertz_semi_axes(ax: f64, ay: f64, p: f64, e: f64, nu: f64) -> (f64, f64) {
    let e_star = e / (2.0 * (1.0 - nu * nu));
    let (small, large) = if ax <= ay { (ax, ay) } else { (ay, ax) };
    let ratio = large / small;
    // B/A as a function of the eccentricity rises from 1 (e → 0) without bound (e → 1).
    let curv_ratio = |ecc: f64| {
        let (k, ee) = elliptic_ke(ecc);
        (ee / (1.0 - ecc * ecc) - k) / (k - ee)
    };
    if ratio <= 1.0 + 1e-9 {
        // Circular contact: (K − E)/e² → π/4, a³ = 3P/(8 A E*) = 3PR/(4E*) with A = 1/(2R).
        let r = (3.0 * p / (8.0 * small * e_star)).cbrt();
        return (r, r);
    }
    let (mut lo, mut hi) = (1e-9_f64, 1.0 - 1e-12);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if curv_ratio(mid) < ratio {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let ecc = 0.5 * (lo + hi);
    let (k, ee) = elliptic_ke(ecc);
    let major =
        (3.0 * p * (k - ee) / (2.0 * std::f64::consts::PI * small * e_star * ecc * ecc)).cbrt();
    let minor = major * (1.0 - ecc * ecc).sqrt();
    // The major axis lies along the direction of the smaller relative curvature.
    if ax <= ay {
        (major, minor)
    } else {
        (minor, major)
    }
}

/// Kalker's table: (key, C11 at ν = 0, 0.25, 0.5, C22 at ν = 0, 0.25, 0.5). Rows with
/// a ≤ b are keyed by g = a/b, rows with a > b by 2 − b/a (so the key grows with a/b).
#[allow(clippy::approx_constant)] // 3.14 is a table entry, not π
const KALKER: [(f64, [f64; 3], [f64; 3]); 19] = [
    (0.1, [2.51, 3.31, 4.85], [2.51, 2.52, 2.53]),
    (0.2, [2.59, 3.37, 4.81], [2.59, 2.63, 2.66]),
    (0.3, [2.68, 3.44, 4.80], [2.68, 2.75, 2.81]),
    (0.4, [2.78, 3.53, 4.82], [2.78, 2.88, 2.98]),
    (0.5, [2.88, 3.62, 4.83], [2.88, 3.01, 3.14]),
    (0.6, [2.98, 3.72, 4.91], [2.98, 3.14, 3.31]),
    (0.7, [3.09, 3.81, 4.97], [3.09, 3.28, 3.48]),
    (0.8, [3.19, 3.91, 5.05], [3.19, 3.41, 3.65]),
    (0.9, [3.29, 4.01, 5.12], [3.29, 3.54, 3.82]),
    (1.0, [3.40, 4.12, 5.20], [3.40, 3.67, 3.98]),
    (2.0 - 0.9, [3.51, 4.22, 5.30], [3.51, 3.81, 4.16]),
    (2.0 - 0.8, [3.65, 4.36, 5.42], [3.65, 3.99, 4.39]),
    (2.0 - 0.7, [3.82, 4.54, 5.58], [3.82, 4.21, 4.67]),
    (2.0 - 0.6, [4.06, 4.78, 5.80], [4.06, 4.50, 5.04]),
    (2.0 - 0.5, [4.37, 5.10, 6.11], [4.37, 4.90, 5.56]),
    (2.0 - 0.4, [4.84, 5.57, 6.57], [4.84, 5.48, 6.31]),
    (2.0 - 0.3, [5.57, 6.34, 7.34], [5.57, 6.40, 7.51]),
    (2.0 - 0.2, [6.96, 7.78, 8.82], [6.96, 8.14, 9.79]),
    (2.0 - 0.1, [10.7, 11.7, 12.9], [10.7, 12.8, 16.0]),
];

fn interp_nu(c: &[f64; 3], nu: f64) -> f64 {
    let nu = nu.clamp(0.0, 0.5);
    if nu <= 0.25 {
        c[0] + (c[1] - c[0]) * nu / 0.25
    } else {
        c[1] + (c[2] - c[1]) * (nu - 0.25) / 0.25
    }
}

/// Kalker's coefficients (C11, C22) for semi-axes `a` (rolling direction) and `b` (lateral)
/// and Poisson's ratio `nu`, interpolated linearly in the table's key and in ν; the ratio is
/// held within the table (0.1 ≤ a/b ≤ 10).
pub fn kalker_c11_c22(a: f64, b: f64, nu: f64) -> (f64, f64) {
    let key = if a <= b { a / b } else { 2.0 - b / a };
    let key = key.clamp(KALKER[0].0, KALKER[KALKER.len() - 1].0);
    let i = KALKER
        .windows(2)
        .position(|w| key <= w[1].0)
        .unwrap_or(KALKER.len() - 2);
    let (k0, c11a, c22a) = KALKER[i];
    let (k1, c11b, c22b) = KALKER[i + 1];
    let t = (key - k0) / (k1 - k0);
    let lerp = |x: f64, y: f64| x + (y - x) * t;
    (
        lerp(interp_nu(&c11a, nu), interp_nu(&c11b, nu)),
        lerp(interp_nu(&c22a, nu), interp_nu(&c22b, nu)),
    )
}

/// Linear creep coefficients of one wheel (N) and the contact they came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Creep {
    /// Longitudinal creep coefficient f11 (N).
    pub f11: f64,
    /// Lateral creep coefficient f22 (N).
    pub f22: f64,
    /// Contact semi-axis along the rolling direction a (m).
    pub a: f64,
    /// Contact semi-axis across b (m).
    pub b: f64,
}

impl Creep {
    /// Coefficients at normal load `q` (N) for wheel radius `r0` (conical tread, flat across),
    /// rail crown radius `r_rail`, material `e`, `nu`, scaled by `factor`.
    pub fn new(q: f64, r0: f64, r_rail: f64, e: f64, nu: f64, factor: f64) -> Self {
        let (a, b) = hertz_semi_axes(0.5 / r0, 0.5 / r_rail, q, e, nu);
        let (c11, c22) = kalker_c11_c22(a, b, nu);
        let g = e / (2.0 * (1.0 + nu));
        Creep {
            f11: factor * g * a * b * c11,
            f22: factor * g * a * b * c22,
            a,
            b,
        }
    }
}
