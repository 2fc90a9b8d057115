//! Modes and stability of the whole car against eigen-analyses written here independently:
//! hand-built mass and stiffness matrices, Klingel's formula and the Routh-Hurwitz criterion.

use nalgebra::{DMatrix, Matrix2};
use vehicle_model::full_car::wheelset::WheelsetModel;
use vehicle_model::full_car::{FullCar, FullCarParams, NX};
use vehicle_model::G;

fn eigenvalues(a: &DMatrix<f64>) -> Vec<nalgebra::Complex<f64>> {
    a.complex_eigenvalues().iter().copied().collect()
}

fn car_eigenvalues(car: &FullCar, v: f64) -> Vec<nalgebra::Complex<f64>> {
    let ss = car.state_space(v);
    eigenvalues(&DMatrix::from_column_slice(NX, NX, ss.a.as_slice()))
}

/// The body on its secondary suspension with the bogies held (their masses and inertias
/// 10⁶ times larger), undamped, the airspring's series branch off (k_sz = 0): body yaw
/// ω² = (4 k_sy a² + 4 k_sx d1²)/I_cz, and lateral and roll from the 2×2 problem
/// M q̈ + K q = 0, q = [y, φ], M = diag(m_c, I_cx),
/// K = [[4k_sy, −4k_sy h1], [−4k_sy h1 − m_c g, 4k_sy h1² + 2(k_vr + 2d1²k_az)]]
/// (two bogies, two sides each; the body's weight over its displaced support, as the half
/// vehicle's eq 10 has it). Each must be an undamped eigenvalue of the model within 1e-4
/// (the held bogies move m_c/M_b ≈ 2e-5 as much as the body).
#[test]
fn body_modes_on_the_secondary_suspension_meet_the_hand_built_problem() {
    let mut p = FullCarParams::default();
    for m in [&mut p.m_b, &mut p.i_bx, &mut p.i_bz] {
        *m *= 1e6;
    }
    (p.c_sy, p.c_yd, p.c_vr, p.k_sz) = (0.0, 0.0, 0.0, 0.0);
    let car = FullCar::new(p.clone());
    let eig = car_eigenvalues(&car, 40.0);

    let k_phi = p.k_vr + 2.0 * p.d1 * p.d1 * p.k_az;
    let m = Matrix2::new(p.m_c, 0.0, 0.0, p.i_cx);
    let k = Matrix2::new(
        4.0 * p.k_sy,
        -4.0 * p.k_sy * p.h1,
        -4.0 * p.k_sy * p.h1 - p.m_c * G,
        4.0 * p.k_sy * p.h1 * p.h1 + 2.0 * k_phi,
    );
    let mk = m.try_inverse().unwrap() * k;
    let (tr, det) = (mk.trace(), mk.determinant());
    let disc = (tr * tr - 4.0 * det).sqrt();
    let expected = [
        ((4.0 * p.k_sy * p.a * p.a + 4.0 * p.k_sx * p.d1 * p.d1) / p.i_cz).sqrt(),
        (0.5 * (tr - disc)).sqrt(),
        (0.5 * (tr + disc)).sqrt(),
    ];
    for w in expected {
        let near = eig
            .iter()
            .min_by(|a, b| (a.im - w).hypot(a.re).total_cmp(&(b.im - w).hypot(b.re)))
            .unwrap();
        assert!(
            (near.im / w - 1.0).abs() < 1e-4 && near.re.abs() < 1e-4 * w,
            "expected {w:.5} rad/s, nearest eigenvalue {near}"
        );
    }
    println!(
        "body modes (Hz): yaw {:.4}, lower sway {:.4}, upper sway {:.4}",
        expected[0] / (2.0 * std::f64::consts::PI),
        expected[1] / (2.0 * std::f64::consts::PI),
        expected[2] / (2.0 * std::f64::consts::PI)
    );
}

/// Klingel's kinematic wavelength L = 2π √(r0 l0 / λ) of a free wheelset (no suspension)
/// from the wheelset model's eigenvalues at low speed: the slow complex pair λ = σ ± iω gives
/// L = 2πV/ω. Inertia shifts ω by O(m V²/f22) ≈ 1e-7 at 1 m/s: tolerance 1e-4.
#[test]
fn free_wheelset_runs_at_klingels_wavelength() {
    let p = FullCarParams::default();
    let klingel = 2.0 * std::f64::consts::PI * (p.r0 * p.l0 / p.conicity).sqrt();
    let ws = WheelsetModel::new(p.clone(), 0.0, 0.0);
    for v in [0.5, 1.0, 2.0] {
        let (a, _) = ws.state_space(v);
        let eig = eigenvalues(&DMatrix::from_column_slice(4, 4, a.as_slice()));
        let slow = eig
            .iter()
            .filter(|l| l.im > 0.0)
            .min_by(|a, b| a.norm().total_cmp(&b.norm()))
            .expect("an oscillating mode");
        let wavelength = 2.0 * std::f64::consts::PI * v / slow.im;
        assert!(
            (wavelength / klingel - 1.0).abs() < 1e-4,
            "V {v}: {wavelength} m against Klingel's {klingel} m"
        );
    }
    println!("Klingel wavelength {klingel:.4} m");
}

/// Routh-Hurwitz margin of the wheelset on springs, from its characteristic polynomial
/// (m s² + c_y s + k_y)(I s² + c_ψ s + k_ψ) + 4 f11 f22 l0 λ / r0, c_y = 2f22/V,
/// c_ψ = 2 f11 l0²/V: stable while a3 a2 a1 − a1² a4 − a3² a0 > 0.
fn hurwitz_margin(p: &FullCarParams, f11: f64, f22: f64, k_y: f64, k_psi: f64, v: f64) -> f64 {
    let (m, i) = (p.m_w, p.i_wz);
    let (cy, cpsi) = (2.0 * f22 / v, 2.0 * f11 * p.l0 * p.l0 / v);
    let a4 = m * i;
    let a3 = m * cpsi + cy * i;
    let a2 = m * k_psi + cy * cpsi + k_y * i;
    let a1 = cy * k_psi + k_y * cpsi;
    let a0 = k_y * k_psi + 4.0 * f11 * f22 * p.l0 * p.conicity / p.r0;
    (a3 * a2 * a1 - a1 * a1 * a4 - a3 * a3 * a0) / (a3 * a2 * a1)
}

/// The wheelset on lateral and yaw springs: the critical speed by bisection on the model's
/// largest real eigenvalue part against bisection on the Routh-Hurwitz margin of its
/// characteristic polynomial, written here from the equations of Wickens (2003, ch. 3).
/// Both bisect to 1 mm/s: tolerance 1e-4 relative.
#[test]
fn restrained_wheelset_critical_speed_meets_routh_hurwitz() {
    let p = FullCarParams::default();
    for (k_y, k_psi) in [(1.0e6, 2.0e6), (4.0e6, 1.0e6), (0.5e6, 8.0e6)] {
        let ws = WheelsetModel::new(p.clone(), k_y, k_psi);
        let (f11, f22) = (ws.car.creep.f11, ws.car.creep.f22);
        let model = ws
            .critical_speed(1.0, 2000.0, 1e-3)
            .expect("a critical speed");
        let (mut lo, mut hi) = (1.0, 2000.0);
        assert!(hurwitz_margin(&p, f11, f22, k_y, k_psi, lo) > 0.0);
        assert!(hurwitz_margin(&p, f11, f22, k_y, k_psi, hi) < 0.0);
        while hi - lo > 1e-3 {
            let mid = 0.5 * (lo + hi);
            if hurwitz_margin(&p, f11, f22, k_y, k_psi, mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let hand = 0.5 * (lo + hi);
        assert!(
            (model / hand - 1.0).abs() < 1e-4,
            "k_y {k_y}, k_ψ {k_psi}: model {model} m/s, Routh-Hurwitz {hand} m/s"
        );
        println!("k_y {k_y:e} k_psi {k_psi:e}: model {model:.3} m/s, Routh-Hurwitz {hand:.3} m/s");
    }
}

/// Largest real part of the eigenvalues of M q̈ + C q̇ + K q = 0 (first-order form).
fn max_re_second_order(m: &DMatrix<f64>, c: &DMatrix<f64>, k: &DMatrix<f64>) -> f64 {
    let n = m.nrows();
    let minv = m.clone().try_inverse().unwrap();
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    a.view_mut((0, n), (n, n))
        .copy_from(&DMatrix::identity(n, n));
    a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * k));
    a.view_mut((n, n), (n, n)).copy_from(&(-&minv * c));
    eigenvalues(&a)
        .iter()
        .map(|l| l.re)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// One bogie under a fixed body, lateral and yaw only, assembled element by element:
/// q = [y_b, ψ_b, y_w1, ψ_w1, y_w2, ψ_w2]; each spring or damper adds k·e eᵀ for its
/// deflection e·q; the creep forces add their damping and the non-symmetric coupling of
/// the lateral creep to yaw (−2 f22) and of the rolling radius difference to yaw
/// (2 f11 l0 λ / r0).
fn bogie_max_re(p: &FullCarParams, f11: f64, f22: f64, v: f64) -> f64 {
    let n = 6;
    let mut m = DMatrix::zeros(n, n);
    for (i, val) in [p.m_b, p.i_bz, p.m_w, p.i_wz, p.m_w, p.i_wz]
        .iter()
        .enumerate()
    {
        m[(i, i)] = *val;
    }
    let (mut c, mut k) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
    let mut element = |e: [f64; 6], stiff: f64, damp: f64| {
        let e = DMatrix::from_row_slice(n, 1, &e);
        k += &e * e.transpose() * stiff;
        c += &e * e.transpose() * damp;
    };
    element([1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 2.0 * p.k_sy, 2.0 * p.c_sy);
    let yaw_s = 2.0 * p.k_sx * p.d1 * p.d1;
    let yaw_d = 2.0 * p.c_yd * p.d_yd * p.d_yd;
    element([0.0, 1.0, 0.0, 0.0, 0.0, 0.0], yaw_s, yaw_d);
    let yaw_p = 2.0 * p.k_px * p.d_px * p.d_px;
    element([1.0, p.b, -1.0, 0.0, 0.0, 0.0], 2.0 * p.k_py, 2.0 * p.c_py);
    element([1.0, -p.b, 0.0, 0.0, -1.0, 0.0], 2.0 * p.k_py, 2.0 * p.c_py);
    element([0.0, -1.0, 0.0, 1.0, 0.0, 0.0], yaw_p, 0.0);
    element([0.0, -1.0, 0.0, 0.0, 0.0, 1.0], yaw_p, 0.0);
    for (y, psi) in [(2, 3), (4, 5)] {
        c[(y, y)] += 2.0 * f22 / v;
        c[(psi, psi)] += 2.0 * f11 * p.l0 * p.l0 / v;
        k[(y, psi)] -= 2.0 * f22;
        k[(psi, y)] += 2.0 * f11 * p.l0 * p.conicity / p.r0;
    }
    max_re_second_order(&m, &c, &k)
}

/// The whole car's hunting speed with the body held (mass and inertias 10⁴ times larger) and
/// every suspension height zero (so roll leaves lateral and yaw alone) against a bogie on a
/// fixed body assembled here element by element (`bogie_max_re`), both by bisection to
/// 1 cm/s; the held body moves m_b/(10⁴ m_c) ≈ 1e-5 as much as the bogie: tolerance 1e-3.
/// Then the default car's own critical speed, above the paper's 162 km/h.
#[test]
fn car_hunting_speed_meets_an_independent_bogie_model() {
    let mut p = FullCarParams::default();
    for m in [&mut p.m_c, &mut p.i_cx, &mut p.i_cz] {
        *m *= 1e4;
    }
    (p.h1, p.h2, p.h3) = (0.0, 0.0, 0.0);
    p.h_gb = p.r0; // primary lateral at axle height, as h3 = 0 with the bogie c.o.g. there
                   // Creep coefficients at the default car's wheel load, not the heavy body's.
    let creep = FullCar::new(FullCarParams::default()).creep;
    let mut car = FullCar::new(p.clone());
    car.creep = creep;
    let model = car
        .critical_speed(20.0, 200.0, 0.01)
        .expect("car critical speed");
    let (mut lo, mut hi) = (20.0, 200.0);
    assert!(bogie_max_re(&p, creep.f11, creep.f22, lo) < 0.0);
    assert!(bogie_max_re(&p, creep.f11, creep.f22, hi) > 0.0);
    while hi - lo > 0.01 {
        let mid = 0.5 * (lo + hi);
        if bogie_max_re(&p, creep.f11, creep.f22, mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let hand = 0.5 * (lo + hi);
    println!("held body: car {model:.3} m/s, bogie model {hand:.3} m/s");
    assert!(
        (model / hand - 1.0).abs() < 1e-3,
        "car {model}, bogie {hand}"
    );

    let car = FullCar::new(FullCarParams::default());
    let vc = car
        .critical_speed(20.0, 200.0, 0.01)
        .expect("default car critical speed");
    assert!(car.max_real_part(vc - 0.05) < 0.0 && car.max_real_part(vc + 0.05) > 0.0);
    assert!(vc > 162.0 / 3.6, "critical speed {vc} m/s");
    println!(
        "default car critical speed {vc:.2} m/s = {:.1} km/h",
        vc * 3.6
    );
}
