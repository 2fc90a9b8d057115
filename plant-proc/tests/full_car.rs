//! The plant stepping the whole car (`vehicle.model = "full"`): at rest on straight smooth
//! track nothing moves and every wheel carries its static load with no lateral force; on a
//! steady curve the rails' lateral forces on the four wheelsets add up to the car's mass times
//! its uncompensated acceleration, and the wheel loads to its weight.

use plant_proc::{Plant, PlantSettings, TrackParams, VehicleParams};
use tiltsim_protocol::Participant;
use vehicle_model::full_car::FullCarParams;
use vehicle_model::{VehicleModel, G};

fn settings(track: TrackParams) -> PlantSettings {
    PlantSettings {
        vehicle: VehicleParams {
            model: VehicleModel::Full,
            ..VehicleParams::default()
        },
        track,
        dt_s: 1e-3,
        seed: 7,
        ..PlantSettings::default()
    }
}

/// The car's total mass: body, two bogie frames, four wheelsets (kg).
fn total_mass(p: &FullCarParams) -> f64 {
    p.m_c + 2.0 * p.m_b + 4.0 * p.m_w
}

/// Straight smooth track (radius 1e9 m, no cant, no irregularity), no bar angle: after 2 s
/// every state is zero, every ΣY and Y is zero and every Q is Q_0 = Mg/8, to rounding.
#[test]
fn at_rest_on_straight_smooth_track_the_safety_quantities_are_zero() {
    let track = TrackParams {
        radius_m: 1e9,
        cant_deg: 0.0,
        ..TrackParams::default()
    };
    let mut plant = Plant::new(&settings(track));
    let p = plant.full_car().unwrap().car.p.clone();
    let q0 = total_mass(&p) * G / 8.0;
    let mut out = plant.initial_output();
    for _ in 0..2000 {
        out = plant.step(&tiltsim_protocol::msg::ToPlant {
            delta_a: 0.0,
            ..Default::default()
        });
    }
    // The curve's 1e-9 1/m gives forces of order m·v²·κ ≈ 1e-4 N.
    for j in 0..4 {
        let f = &out.car[5 * j..5 * j + 5];
        for (k, y) in f[..3].iter().enumerate() {
            assert!(y.abs() < 1e-2, "wheelset {j} lateral force {k}: {y} N");
        }
        for q in &f[3..5] {
            assert!(
                (q - q0).abs() < 1e-6 * q0,
                "wheelset {j}: Q {q} N, Q0 {q0} N"
            );
        }
    }
    assert!(out.x.iter().all(|v| v.abs() < 1e-8), "{:?}", out.x);
    assert!(out.car[20..].iter().all(|a| a.abs() < 1e-6));
}

/// A 1000 m curve with 6° cant, long enough to settle (2 km), 162 km/h, no bar angle. The
/// whole car in steady curving: the lateral forces of the rails on it balance its
/// centripetal acceleration less gravity's share along the canted track plane,
/// ΣΣY = M (V²/R − g θ_o) (the model is linear in the cant: θ_o, not sin θ_o), and the
/// wheel loads add up to Mg. Checked 35 s into the curve, the transients (slowest: the
/// reservoir's roll, seconds) gone to well under 0.1 %.
#[test]
fn on_a_steady_curve_the_rails_carry_the_uncompensated_acceleration() {
    let track = TrackParams {
        curve_m: 2000.0,
        ..TrackParams::default()
    };
    let v = track.speed();
    let (r, cant) = (track.radius_m, track.cant_deg.to_radians());
    let t_end = (track.straight_before_m + track.transition_m) / v + 35.0;
    let mut plant = Plant::new(&settings(track));
    let m = total_mass(&plant.full_car().unwrap().car.p);
    let mut out = plant.initial_output();
    for _ in 0..(t_end / 1e-3).round() as usize {
        out = plant.step(&tiltsim_protocol::msg::ToPlant::default());
    }
    assert!(out.curvature == 1.0 / r, "in the curve: {}", out.curvature);
    let sum_y: f64 = (0..4).map(|j| out.car[5 * j]).sum();
    let hand = m * (v * v / r - G * cant);
    assert!(
        (sum_y - hand).abs() < 1e-3 * hand.abs(),
        "ΣΣY {sum_y} N against M(V²/R − gθ) = {hand} N"
    );
    let sum_q: f64 = (0..4)
        .map(|j| out.car[5 * j + 3] + out.car[5 * j + 4])
        .sum();
    assert!(
        (sum_q - m * G).abs() < 1e-9 * m * G,
        "ΣQ {sum_q} N against Mg"
    );
    // Each wheel's Y is half its wheelset's ΣY away from the flanges (one creep coefficient
    // for both wheels).
    for j in 0..4 {
        let f = &out.car[5 * j..5 * j + 5];
        assert!((f[1] + f[2] - f[0]).abs() < 1e-9 * f[0].abs().max(1.0));
    }
}
