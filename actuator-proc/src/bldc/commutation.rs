//! The trapezoidal back-EMF shapes of Fig. 5 (eqs 6-8) and the six-step commutation table
//! derived from them.

/// Trapezoidal back-EMF shape f(θ) of Fig. 5: ±1 over 120°, linear over 60°.
#[inline]
pub fn trapezoid(theta: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_6, TAU};
    let t = theta.rem_euclid(TAU);
    if t < FRAC_PI_6 {
        t / FRAC_PI_6
    } else if t < 5.0 * FRAC_PI_6 {
        1.0
    } else if t < 7.0 * FRAC_PI_6 {
        1.0 - (t - 5.0 * FRAC_PI_6) / FRAC_PI_6
    } else if t < 11.0 * FRAC_PI_6 {
        -1.0
    } else {
        -1.0 + (t - 11.0 * FRAC_PI_6) / FRAC_PI_6
    }
}

/// f on an angle already reduced to [0, 2π).
#[inline]
fn trapezoid_reduced(t: f64) -> f64 {
    use std::f64::consts::FRAC_PI_6;
    let u = t * (1.0 / FRAC_PI_6); // 0 … 12
    if u < 1.0 {
        u
    } else if u < 5.0 {
        1.0
    } else if u < 7.0 {
        6.0 - u
    } else if u < 11.0 {
        -1.0
    } else {
        u - 12.0
    }
}

/// Shapes of the three phases and the commutation sector, with one angle reduction (the
/// switched model's inner loop).
#[inline]
pub fn shapes_and_sector(theta_e: f64) -> ([f64; 3], usize) {
    shapes_and_sector_reduced(theta_e.rem_euclid(std::f64::consts::TAU))
}

/// [`shapes_and_sector`] of an angle already in [0, 2π).
#[inline]
pub(super) fn shapes_and_sector_reduced(t: f64) -> ([f64; 3], usize) {
    use std::f64::consts::{FRAC_PI_3, FRAC_PI_6, TAU};
    let wrap = |x: f64| {
        if x >= TAU {
            x - TAU
        } else if x < 0.0 {
            x + TAU
        } else {
            x
        }
    };
    let f = [
        trapezoid_reduced(t),
        trapezoid_reduced(wrap(t + SHIFT[1])),
        trapezoid_reduced(wrap(t + SHIFT[2])),
    ];
    let sec = ((wrap(t - FRAC_PI_6) * (1.0 / FRAC_PI_3)) as usize).min(5);
    (f, sec)
}

/// Phase shifts of eqs 6-8: a at 0, b at −2π/3, c at +2π/3.
pub const SHIFT: [f64; 3] = [
    0.0,
    -2.0 * std::f64::consts::FRAC_PI_3,
    2.0 * std::f64::consts::FRAC_PI_3,
];

/// Back-EMF shapes of the three phases at electrical angle `theta_e`.
#[inline]
pub fn shapes(theta_e: f64) -> [f64; 3] {
    [
        trapezoid(theta_e + SHIFT[0]),
        trapezoid(theta_e + SHIFT[1]),
        trapezoid(theta_e + SHIFT[2]),
    ]
}

/// Six-step commutation: for each 60° sector starting at 30° electrical, the phase driven
/// positive and the one driven negative for positive torque (the third is off). Derived from
/// the back-EMF shapes at the sector centres: + where f = +1, − where f = −1.
pub fn commutation_table() -> [(usize, usize); 6] {
    std::array::from_fn(|k| {
        let centre = std::f64::consts::FRAC_PI_6 + std::f64::consts::FRAC_PI_3 * (k as f64 + 0.5);
        let f = shapes(centre);
        let plus = (0..3).find(|&i| f[i] > 0.99).unwrap_or(0);
        let minus = (0..3).find(|&i| f[i] < -0.99).unwrap_or(1);
        (plus, minus)
    })
}

/// The commutation sector (0-5) of electrical angle `theta_e`.
#[inline]
pub fn sector(theta_e: f64) -> usize {
    let t = (theta_e - std::f64::consts::FRAC_PI_6).rem_euclid(std::f64::consts::TAU);
    ((t / std::f64::consts::FRAC_PI_3) as usize).min(5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commutation_gives_positive_torque_in_every_sector() {
        let table = commutation_table();
        // Each sector drives two distinct phases.
        for (k, &(p, m)) in table.iter().enumerate() {
            assert_ne!(p, m);
            let centre =
                std::f64::consts::FRAC_PI_6 + std::f64::consts::FRAC_PI_3 * (k as f64 + 0.5);
            assert_eq!(sector(centre), k);
            // A positive current command (+I into p, out of m) anywhere in the sector,
            // including its edges, gives T = λ(f_p − f_m) I ≥ k_t I · (1/2 … 1) > 0.
            for frac in [0.001, 0.25, 0.5, 0.75, 0.999] {
                let th =
                    std::f64::consts::FRAC_PI_6 + std::f64::consts::FRAC_PI_3 * (k as f64 + frac);
                let f = shapes(th);
                let t = 3.575 * (f[p] - f[m]) * 10.0;
                assert!(t > 0.0, "sector {k} at {frac}: torque {t}");
                assert!(
                    (t - 71.5).abs() < 1e-9,
                    "flat tops over the whole sector: {t}"
                );
            }
        }
        let mut plus = [0; 3];
        for (p, _) in table {
            plus[p] += 1;
        }
        assert_eq!(plus, [2, 2, 2], "every phase conducts positive for 120°");
    }

    #[test]
    fn fast_shapes_agree_with_the_definition() {
        for k in -2000..2000 {
            let th = k as f64 * 0.0137;
            let (f, sec) = shapes_and_sector(th);
            let g = shapes(th);
            for x in 0..3 {
                assert!((f[x] - g[x]).abs() < 1e-12, "{th}: {f:?} vs {g:?}");
            }
            assert_eq!(sec, sector(th));
        }
    }
}
