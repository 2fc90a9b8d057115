//! The whole car on a steady curve and against the half vehicle, from balances written here.

use nalgebra::{Complex, DMatrix, DVector, Matrix3, Vector3};
use vehicle_model::full_car::inputs::uniform;
use vehicle_model::full_car::outputs::{passengers, wheel_forces};
use vehicle_model::full_car::wheelset::WheelsetModel;
use vehicle_model::full_car::{input_col, ix, FullCar, FullCarParams, WheelsetInput, NW, NX};
use vehicle_model::{Vehicle, VehicleParams, G};

const V: f64 = 45.0; // 162 km/h, the paper's speed
const KAPPA: f64 = 1.0 / 1000.0;

fn curve(cant: f64) -> WheelsetInput {
    WheelsetInput {
        curvature: KAPPA,
        cant,
        ..Default::default()
    }
}

/// Body and bogie roll and the reservoir on a steady curve from the force and moment
/// balances of one bogie's share, by hand: the secondary lateral force carries half the
/// body's in-plane load a = gθ − V²κ, the primary carries that and the bogie's; then body
/// roll, bogie roll and the reservoir in a 3×3 system. Returns (Δs, φ_c, φ_b).
fn roll_by_hand(p: &FullCarParams, a: f64) -> (f64, f64, f64) {
    let f_s = 0.5 * p.m_c * a; // both sides of one bogie
    let ds = f_s / (2.0 * p.k_sy);
    let f_p = f_s + p.m_b * a; // four axleboxes
    let (d1s, d2s) = (p.d1 * p.d1, p.d2 * p.d2);
    // unknowns [φ_c, φ_b, θ_r]; bar and airspring moment on the bogie:
    // k_vr (φ_c − φ_b) + 2 d1² (k_az (φ_c − φ_b) + k_sz (φ_c − θ_r))
    let roll = [
        p.k_vr + 2.0 * d1s * (p.k_az + p.k_sz),
        -p.k_vr - 2.0 * d1s * p.k_az,
        -2.0 * d1s * p.k_sz,
    ];
    // body: h1 f_s + (m_c/2) g (Δs + h1 φ_c + h2 φ_b) − roll = 0
    let w = 0.5 * p.m_c * G;
    let body = [w * p.h1 - roll[0], w * p.h2 - roll[1], -roll[2]];
    // bogie: h2 f_s + roll + h3 f_p − 2 · 2 d2² k_pz φ_b = 0
    let bogie = [roll[0], roll[1] - 4.0 * d2s * p.k_pz, roll[2]];
    // reservoir: k_sz (φ_c − θ_r) − k_rz (θ_r − φ_b) = 0
    let res = [p.k_sz, p.k_rz, -p.k_sz - p.k_rz];
    let m = Matrix3::from_row_slice(&[
        body[0], body[1], body[2], bogie[0], bogie[1], bogie[2], res[0], res[1], res[2],
    ]);
    let rhs = Vector3::new(-p.h1 * f_s - w * ds, -p.h2 * f_s - p.h3 * f_p, 0.0);
    let s = m.lu().solve(&rhs).unwrap();
    (ds, s[0], s[1])
}

/// Steady curve R = 1000 m, cant 6°, 162 km/h: the model's static solution (A x + B u = 0
/// with the leading wheelsets on their flanges) against the hand balances, which hold
/// whichever wheelsets take the lateral load: body and bogie roll (1e-3 relative: the two bogies' secondary
/// forces differ by the yaw springs' share, about 1e-4), the secondary deflection seen from
/// the state with the chord's versine a²κ/2, the total lateral force on the rails against
/// the whole mass times the cant deficiency acceleration (1e-9), and the passengers' lateral
/// acceleration against the linearised eq 13, V²κ − g(θ_o + φ_c) (1e-9), and the nonlinear
/// eq 13 within 0.01 m/s² (cubic terms of a 7° angle).
#[test]
fn steady_curve_meets_the_hand_balances() {
    let p = FullCarParams::default();
    let car = FullCar::new(p.clone());
    let cant = 6f64.to_radians();
    let x = car.steady_state(V, [0.0; 2], curve(cant));
    let a = G * cant - V * V * KAPPA;
    let (ds, phi_c, phi_b) = roll_by_hand(&p, a);
    assert!(
        (x[ix::PHI_C] / phi_c - 1.0).abs() < 1e-3,
        "φ_c {} vs {phi_c}",
        x[ix::PHI_C]
    );
    for i in 0..2 {
        let xb = x[ix::phi_b(i)];
        assert!((xb / phi_b - 1.0).abs() < 1e-3, "φ_b{i} {xb} vs {phi_b}");
        let d = p.bogie_x(i);
        let seen = x[ix::Y_C] + d * x[ix::PSI_C]
            - d * d * KAPPA / 2.0
            - p.h1 * x[ix::PHI_C]
            - x[ix::y_b(i)]
            - p.h2 * xb;
        assert!((seen / ds - 1.0).abs() < 1e-3, "Δs{i} {seen} vs {ds}");
    }
    let m_total = p.m_c + 2.0 * p.m_b + 4.0 * p.m_w;
    let eq = car.equations(V);
    let w = uniform(curve(cant));
    let f = wheel_forces(&eq, x.as_slice(), &w);
    let sum: f64 = f.iter().map(|f| f.sum_y).sum();
    assert!(
        (sum / (-m_total * a) - 1.0).abs() < 1e-9,
        "ΣY {sum} vs {}",
        -m_total * a
    );
    let places = [(p.a, 0.0), (0.0, 0.0), (-p.a, 0.0)];
    for pass in passengers(&eq, x.as_slice(), [0.0; 2], &w, &places) {
        let lin = V * V * KAPPA - G * (cant + x[ix::PHI_C]);
        assert!(
            (pass.lateral_acc - lin).abs() < 1e-9,
            "{} vs {lin}",
            pass.lateral_acc
        );
        let half = Vehicle::new(VehicleParams::default(), V);
        let eq13 = half.lateral_acceleration(x[ix::PHI_C], KAPPA, cant);
        assert!((pass.lateral_acc - eq13).abs() < 0.01);
    }
    println!(
        "steady curve: φ_c {:.4}° (hand {:.4}°), φ_b {:.4}°, Δs {:.2} mm, passenger {:.4} m/s²",
        x[ix::PHI_C].to_degrees(),
        phi_c.to_degrees(),
        phi_b.to_degrees(),
        ds * 1e3,
        V * V * KAPPA - G * (cant + x[ix::PHI_C])
    );
}

/// Wheel loads on the steady curve: the sum over wheelsets of l0 (Q_− − Q_+) against the
/// overturning moment about the rails written here, the in-plane load at each c.o.g. height
/// plus each weight times its lateral offset from the track (the body's c.o.g. from the chord
/// between its bogies, a²κ/2 inside the track at its centre). The model leaves out the
/// bogie's weight offset from its wheelsets (about 1.5 mm under 21 t): tolerance 1.5 %.
#[test]
fn wheel_load_transfer_balances_the_overturning_moment() {
    let p = FullCarParams::default();
    let car = FullCar::new(p.clone());
    let cant = 6f64.to_radians();
    let x = car.steady_state(V, [0.0; 2], curve(cant));
    let demand = V * V * KAPPA - G * cant; // outwards, towards −y
    let y_body = x[ix::Y_C] - p.a * p.a * KAPPA / 2.0;
    let y_bogies: f64 = (0..2).map(|i| x[ix::y_b(i)]).sum();
    let y_wheelsets: f64 = (0..NW).map(|j| x[ix::y_w(j)]).sum();
    let hand = demand * (p.m_c * p.h_gv + 2.0 * p.m_b * p.h_gb + 4.0 * p.m_w * p.r0)
        - G * (p.m_c * y_body + p.m_b * y_bogies + p.m_w * y_wheelsets);
    let f = wheel_forces(&car.equations(V), x.as_slice(), &uniform(curve(cant)));
    let model: f64 = f.iter().map(|f| p.l0 * (f.q_minus - f.q_plus)).sum();
    println!("overturning moment: model {model:.0} N·m, hand {hand:.0} N·m");
    assert!(
        (model / hand - 1.0).abs() < 0.015,
        "model {model}, hand {hand}"
    );
    let q0 = p.static_wheel_load();
    for w in f {
        assert!((w.q_plus + w.q_minus - 2.0 * q0).abs() < 1e-6 * q0);
    }
}

/// A free wheelset (no suspension) on a steady curve rolls at y = −r0 l0 κ/λ, towards the
/// outer rail, whatever the cant (the rolling radius difference then matches the curve), and
/// takes the lateral load with a yaw angle ψ = −m_w (gθ − V²κ)/(2 f22): exact.
#[test]
fn free_wheelset_takes_the_rolling_radius_offset() {
    let p = FullCarParams::default();
    let ws = WheelsetModel::new(p.clone(), 0.0, 0.0);
    let (a, b) = ws.state_space(V);
    let a = DMatrix::from_column_slice(4, 4, a.as_slice());
    for cant in [V * V * KAPPA / G, 0.0, 6f64.to_radians()] {
        let u = DVector::from_column_slice(&[KAPPA, cant, 0.0]);
        let bu = DMatrix::from_column_slice(4, 3, b.as_slice()) * u;
        let x = a.clone().lu().solve(&(-bu)).unwrap();
        let y = -p.r0 * p.l0 * KAPPA / p.conicity;
        let psi = -p.m_w * (G * cant - V * V * KAPPA) / (2.0 * ws.car.creep.f22);
        assert!((x[0] / y - 1.0).abs() < 1e-9, "y {} vs {y}", x[0]);
        assert!(
            (x[1] - psi).abs() < 1e-12 + 1e-9 * psi.abs(),
            "ψ {} vs {psi}",
            x[1]
        );
    }
}

/// Frequency response (jωI − A)⁻¹ B u of `out` for the cant θ_o = e^{jωt} everywhere:
/// columns for θ_o, θ̇_o = jω θ_o and θ̈_o = −ω² θ_o.
fn cant_response(a: &DMatrix<f64>, cols: [DVector<f64>; 3], out: usize, w: f64) -> Complex<f64> {
    let n = a.nrows();
    let j = Complex::new(0.0, w);
    let m = DMatrix::from_fn(n, n, |r, c| {
        let d = if r == c { j } else { Complex::new(0.0, 0.0) };
        d - Complex::new(a[(r, c)], 0.0)
    });
    let rhs = DVector::from_fn(n, |r, _| {
        Complex::new(cols[0][r], 0.0) + j * cols[1][r] + j * j * cols[2][r]
    });
    m.lu().solve(&rhs).unwrap()[out]
}

/// The half-vehicle limit: the whole car built on the half vehicle's parameters, its
/// wheelsets held to the rails by a lateral stiffness of 10¹² N/m (the half vehicle's primary
/// springs end on the track), the same cant at every wheelset (no delay, so neither yaw nor
/// the trailing bogie differ) and no curvature. Each bogie then carries half of a body of
/// twice the half mass and inertia through the same elements: the body's roll response to
/// the cant equals the half vehicle's θ_v at every frequency. The held wheelsets still move
/// F/10¹² m, 1e-5 of the primary deflection: tolerance 1e-4 of the static gain.
#[test]
fn symmetric_car_on_held_wheelsets_rolls_as_the_half_vehicle() {
    let half = VehicleParams::default();
    let mut p = FullCarParams::from_half(&half);
    p.k_gy = 1e12;
    let car = FullCar::new(p);
    let ss = car.state_space(V);
    let a = DMatrix::from_column_slice(NX, NX, ss.a.as_slice());
    let col =
        |k: usize| DVector::from_fn(NX, |r, _| (0..NW).map(|j| ss.b[(r, input_col(j, k))]).sum());
    let hv = Vehicle::new(half, V).state_space();
    let ah = DMatrix::from_column_slice(9, 9, hv.a.as_slice());
    let gcol = |k: usize| DVector::from_fn(9, |r, _| hv.g[(r, k)]);
    let static_gain = cant_response(&ah, [gcol(1), gcol(2), gcol(3)], 1, 0.0).re;
    for f_hz in [0.0, 0.1, 0.3, 0.7, 1.0, 1.5, 3.0, 10.0] {
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let full = cant_response(&a, [col(2), col(3), col(4)], ix::PHI_C, w);
        let halfv = cant_response(&ah, [gcol(1), gcol(2), gcol(3)], 1, w);
        println!("{f_hz} Hz: car {full:.6}, half vehicle {halfv:.6}");
        assert!(
            (full - halfv).norm() < 1e-4 * static_gain.abs(),
            "{f_hz} Hz: car {full}, half vehicle {halfv}"
        );
    }
}
