//! Contact mechanics of the whole car against published values and closed forms.

use std::f64::consts::PI;

use vehicle_model::full_car::contact::{elliptic_ke, hertz_semi_axes, kalker_c11_c22, Creep};
use vehicle_model::full_car::FullCarParams;

/// Complete elliptic integrals at k = 1/√2 against Abramowitz & Stegun (Table 17.1, m = 0.5):
/// K = 1.854074677, E = 1.350643881, printed to ten digits.
#[test]
fn elliptic_integrals_meet_the_tabulated_values() {
    let (k, e) = elliptic_ke(1.0 / 2f64.sqrt());
    assert!((k - 1.854_074_677).abs() < 1e-9, "K = {k}");
    assert!((e - 1.350_643_881).abs() < 1e-9, "E = {e}");
}

/// Hertz's coefficients m and n (a = m·s, b = n·s with s = [3π/4 · P(k1 + k2)/(A + B)]^⅓,
/// k = (1 − ν²)/(πE), cos θ = (B − A)/(A + B)) as tabulated in Timoshenko & Goodier,
/// *Theory of Elasticity*, 1951, §140 (three decimals): the solver's semi-axes must give them
/// within one unit of the last digit.
#[test]
fn hertz_ellipse_meets_the_tabulated_coefficients() {
    let (young, nu, p) = (2.1e11, 0.3, 50e3);
    for (theta, m, n) in [
        (30.0_f64, 2.731, 0.493),
        (40.0, 2.136, 0.567),
        (50.0, 1.754, 0.641),
        (60.0, 1.486, 0.717),
        (80.0, 1.128, 0.893),
    ] {
        let c = theta.to_radians().cos();
        // A + B = 4 1/m, A ≤ B.
        let (a_c, b_c) = (2.0 * (1.0 - c), 2.0 * (1.0 + c));
        let (ax, ay) = hertz_semi_axes(a_c, b_c, p, young, nu);
        let k = (1.0 - nu * nu) / (PI * young);
        let s = (0.75 * PI * p * 2.0 * k / (a_c + b_c)).cbrt();
        assert!(
            (ax / s - m).abs() < 1e-3,
            "θ {theta}: m {} against {m}",
            ax / s
        );
        assert!(
            (ay / s - n).abs() < 1e-3,
            "θ {theta}: n {} against {n}",
            ay / s
        );
        // Swapping the curvatures swaps the axes.
        let (bx, by) = hertz_semi_axes(b_c, a_c, p, young, nu);
        assert!((bx - ay).abs() < 1e-12 && (by - ax).abs() < 1e-12);
    }
}

/// Nearly equal curvatures (through the elliptic branch) give the sphere's
/// a = (3PR/(4E*))^⅓, R = 1/(2A) (Johnson, *Contact Mechanics*, eq. 4.22), within the
/// O(B/A − 1) = 1e-6 the ellipse differs by.
#[test]
fn nearly_circular_contact_is_the_spheres() {
    let (young, nu, p, r): (f64, f64, f64, f64) = (2.1e11, 0.3, 60e3, 0.4);
    let e_star = young / (2.0 * (1.0 - nu * nu));
    let a_circle = (3.0 * p * r / (4.0 * e_star)).cbrt();
    let (ax, ay) = hertz_semi_axes(0.5 / r, 0.5 / r * (1.0 + 1e-6), p, young, nu);
    assert!((ax / a_circle - 1.0).abs() < 2e-6, "{ax} vs {a_circle}");
    assert!((ay / a_circle - 1.0).abs() < 2e-6, "{ay} vs {a_circle}");
}

/// Kalker's coefficients: the a/b → 0 limits C11 → π²/(4(1 − ν)), C22 → π²/4 (Kalker 1967;
/// the table's first row, a/b = 0.1, lies within 2 % of them), the circle's entries of the
/// table at ν = 0.25 (C11 = 4.12, C22 = 3.67), and ν = 0 where C11 = C22 for every ratio.
#[test]
fn kalker_coefficients_meet_their_limits() {
    for nu in [0.0, 0.25] {
        let (c11, c22) = kalker_c11_c22(0.1, 1.0, nu);
        let lim11 = PI * PI / (4.0 * (1.0 - nu));
        let lim22 = PI * PI / 4.0;
        assert!(
            (c11 / lim11 - 1.0).abs() < 0.02,
            "ν {nu}: C11 {c11} vs {lim11}"
        );
        assert!(
            (c22 / lim22 - 1.0).abs() < 0.03,
            "ν {nu}: C22 {c22} vs {lim22}"
        );
    }
    let (c11, c22) = kalker_c11_c22(1.0, 1.0, 0.25);
    assert!((c11 - 4.12).abs() < 1e-12 && (c22 - 3.67).abs() < 1e-12);
    for ratio in [0.15, 0.55, 1.0, 1.7, 4.0, 8.0] {
        let (c11, c22) = kalker_c11_c22(ratio, 1.0, 0.0);
        assert!((c11 - c22).abs() < 1e-12, "a/b {ratio}: {c11} {c22}");
    }
    // Interpolation between ν = 0.25 and 0.5 at the circle: halfway is the mean.
    let (c11, _) = kalker_c11_c22(1.0, 1.0, 0.375);
    assert!((c11 - 0.5 * (4.12 + 5.20)).abs() < 1e-12);
}

/// The car's creep coefficients: f = G·a·b·C with the ellipse and table above, recomputed
/// here from the Hertz semi-axes; the 6-12 MN range is a plausibility bound for a 60 kN
/// wheel load on a 0.46 m wheel (an order-of-magnitude guard, not a validation).
#[test]
fn creep_coefficients_of_the_car() {
    let p = FullCarParams::default();
    let q0 = p.static_wheel_load();
    let c = Creep::new(q0, p.r0, p.rail_crown_radius, p.young, p.poisson, 1.0);
    let (a, b) = hertz_semi_axes(
        0.5 / p.r0,
        0.5 / p.rail_crown_radius,
        q0,
        p.young,
        p.poisson,
    );
    assert_eq!((c.a, c.b), (a, b));
    // The wheel's rolling radius (0.46 m) is larger than the rail crown's (0.3 m): the
    // ellipse is longer along the rail.
    assert!(a > b);
    let g = p.young / (2.0 * (1.0 + p.poisson));
    let (c11, c22) = kalker_c11_c22(a, b, p.poisson);
    assert!((c.f11 - g * a * b * c11).abs() < 1e-6 * c.f11);
    assert!((c.f22 - g * a * b * c22).abs() < 1e-6 * c.f22);
    assert!(c.f11 > 6e6 && c.f11 < 12e6, "f11 {}", c.f11);
    assert!(c.f22 > 6e6 && c.f22 < 12e6, "f22 {}", c.f22);
}

/// The default parameters pass their checks; a negative mass, a Poisson's ratio above 0.5
/// and a wheelbase longer than the bogie spacing are each reported under their field, once.
#[test]
fn full_car_parameters_are_checked() {
    assert!(FullCarParams::default()
        .validate("vehicle")
        .errors
        .is_empty());
    let bad = FullCarParams {
        m_w: -1.0,
        poisson: 0.6,
        a: 2.0,
        b: 3.0,
        ..FullCarParams::default()
    };
    let fields: Vec<String> = bad
        .validate("vehicle")
        .errors
        .iter()
        .map(|e| e.field.clone())
        .collect();
    for f in ["vehicle.m_w", "vehicle.poisson", "vehicle.b"] {
        assert!(fields.iter().any(|x| x == f), "{f} not in {fields:?}");
    }
    assert_eq!(fields.len(), 3, "{fields:?}");
}
