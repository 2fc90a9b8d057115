//! Physics of the plant against values derived independently of the simulation.

use nalgebra::{Matrix5, Vector5};
use plant_proc::{Plant, PlantSettings};
use vehicle_model::vehicle::ix;
use vehicle_model::{TrackParams, Vehicle, VehicleParams, G};

/// Static equilibrium on a steady curve, solved by hand from the force and moment balances of
/// model-notes (eqs 9-12, A.2 with every rate zero): unknowns [y_v, θ_v, y_b, θ_b, θ_r].
fn static_equilibrium(p: &VehicleParams, v: f64, kappa: f64, cant: f64) -> Vector5<f64> {
    // Δs = y_v − h1 θ_v − y_b − h2 θ_b ; Δp = y_b − h3 θ_b ; ψ = θ_v − θ_b
    let ds = [1.0, -p.h1, -1.0, -p.h2, 0.0];
    let dp = [0.0, 0.0, 1.0, -p.h3, 0.0];
    let psi = [0.0, 1.0, 0.0, -1.0, 0.0];
    let air = [0.0, 1.0, 0.0, 0.0, -1.0]; // θ_v − θ_r
    let f = p.m_v * (G * cant - v * v * kappa); // net quasi-static lateral load on the body
    let fb = p.m_b * (G * cant - v * v * kappa);
    let mut a = Matrix5::zeros();
    let mut b = Vector5::zeros();
    for j in 0..5 {
        // body lateral: 2 k_sy Δs = f
        a[(0, j)] = 2.0 * p.k_sy * ds[j];
        // body roll: 2 h1 k_sy Δs + m_v g (y_v − y_b) − k_vr ψ − 2 d1² (k_az ψ + k_sz (θ_v − θ_r)) = 0
        let yvyb = [1.0, 0.0, -1.0, 0.0, 0.0][j];
        a[(1, j)] = 2.0 * p.h1 * p.k_sy * ds[j] + p.m_v * G * yvyb
            - p.k_vr * psi[j]
            - 2.0 * p.d1 * p.d1 * (p.k_az * psi[j] + p.k_sz * air[j]);
        // bogie lateral: 2 k_py Δp − 2 k_sy Δs = fb
        a[(2, j)] = 2.0 * p.k_py * dp[j] - 2.0 * p.k_sy * ds[j];
        // bogie roll: 2 h2 k_sy Δs + 2 h3 k_py Δp + k_vr ψ + 2 d1² (…) − 2 d2² k_pz θ_b = 0
        let thb = [0.0, 0.0, 0.0, 1.0, 0.0][j];
        a[(3, j)] = 2.0 * p.h2 * p.k_sy * ds[j]
            + 2.0 * p.h3 * p.k_py * dp[j]
            + p.k_vr * psi[j]
            + 2.0 * p.d1 * p.d1 * (p.k_az * psi[j] + p.k_sz * air[j])
            - 2.0 * p.d2 * p.d2 * p.k_pz * thb;
        // reservoir: k_sz (θ_v − θ_r) − k_rz (θ_r − θ_b) = 0
        a[(4, j)] = p.k_sz * air[j] - p.k_rz * [0.0, 0.0, 0.0, -1.0, 1.0][j];
    }
    b[0] = f;
    b[2] = fb;
    a.lu().solve(&b).expect("equilibrium system is regular")
}

fn long_curve() -> PlantSettings {
    let mut s = PlantSettings {
        dt_s: 1e-3,
        seed: 3,
        ..Default::default()
    };
    s.sensor.theta_v_noise_std_rad = 0.0;
    s.track = TrackParams {
        straight_before_m: 10.0,
        curve_m: 3000.0,
        ..TrackParams::default()
    };
    s
}

#[test]
fn passive_vehicle_settles_at_the_closed_form_equilibrium_on_the_steady_curve() {
    let s = long_curve();
    let v = s.track.speed();
    let (kappa, cant) = (1.0 / s.track.radius_m, s.track.cant_deg.to_radians());
    let eq = static_equilibrium(&s.vehicle, v, kappa, cant);

    let mut plant = Plant::new(&s);
    // 10 m straight + 108 m transition, then 40 s on the steady curve.
    let steps = ((118.0 / v + 40.0) / s.dt_s) as usize;
    for _ in 0..steps {
        plant.advance(0.0);
    }
    let x = plant.state();
    let sim = [
        x[ix::Y_V],
        x[ix::TH_V],
        x[ix::Y_B],
        x[ix::TH_B],
        x[ix::TH_R],
    ];
    for (i, name) in ["y_v", "theta_v", "y_b", "theta_b", "theta_r"]
        .iter()
        .enumerate()
    {
        // After 40 s every mode has decayed by more than e^-10 (slowest |Re λ| > 0.5 s⁻¹,
        // checked below), so the simulation must agree with the solve to 1e-4 relative.
        let tol = 1e-4 * eq[i].abs().max(1e-5);
        assert!(
            (sim[i] - eq[i]).abs() < tol,
            "{name}: simulated {} vs closed form {}",
            sim[i],
            eq[i]
        );
    }
    // The body rolls outwards (negative) and the passengers feel the paper's ~1.18 m/s²
    // (section 2.3, Fig. 8; read off a plot, so ±0.03 m/s²).
    assert!(eq[1] < 0.0);
    let out = plant.output();
    let a_closed = Vehicle::new(s.vehicle.clone(), v).lateral_acceleration(eq[1], kappa, cant);
    assert!((out.lat_acc - a_closed).abs() < 1e-5);
    assert!(
        (a_closed - 1.18).abs() < 0.03,
        "steady-curve lateral acceleration {a_closed} m/s²"
    );
}

#[test]
fn every_mode_of_the_vehicle_is_stable_and_the_primary_lateral_mode_is_where_physics_puts_it() {
    let veh = Vehicle::new(VehicleParams::default(), 45.0);
    let ss = veh.state_space();
    let eig = ss.a.complex_eigenvalues();
    let slowest = eig.iter().map(|l| -l.re).fold(f64::INFINITY, f64::min);
    assert!(
        slowest > 0.5,
        "slowest decay rate {slowest} s⁻¹; eigenvalues {eig:?}"
    );
    // Bogie lateral mode on the primary springs: ω ≈ sqrt(2 k_py / m_b) ≈ 167 rad/s.
    let p = VehicleParams::default();
    let w = (2.0 * p.k_py / p.m_b).sqrt();
    let found = eig
        .iter()
        .any(|l| (l.norm() - w).abs() / w < 0.15 && l.im.abs() > 0.0);
    assert!(found, "no mode near {w} rad/s in {eig:?}");
}

#[test]
fn state_space_matches_the_simulation_model() {
    let veh = Vehicle::new(VehicleParams::default(), 45.0);
    let ss = veh.state_space();
    let x = vehicle_model::vehicle::State::from_fn(|i, _| {
        0.01 * (i as f64 + 1.0) * if i % 2 == 0 { 1.0 } else { -1.0 }
    });
    let w = vehicle_model::TrackInput {
        curvature: 1e-3,
        cant: 0.1,
        cant_acc: 0.3,
        ..Default::default()
    };
    let f = veh.deriv(&x, 0.02, &w);
    let wv = nalgebra::SVector::<f64, 6>::from_column_slice(&[
        w.curvature,
        w.cant,
        w.cant_rate,
        w.cant_acc,
        w.y_o,
        w.dy_o,
    ]);
    let lin = ss.a * x + ss.b * 0.02 + ss.g * wv;
    assert!((f - lin).norm() < 1e-9 * f.norm());
}

#[test]
fn rk4_at_one_millisecond_agrees_with_a_four_times_finer_step() {
    let run = |dt: f64| {
        let mut s = PlantSettings {
            dt_s: dt,
            seed: 11,
            ..Default::default()
        };
        s.sensor.theta_v_noise_std_rad = 0.0;
        s.track.irregularity.amplitude_deg = 0.6;
        let mut plant = Plant::new(&s);
        let n = (16.8 / dt).round() as usize;
        let every = (1e-3 / dt).round() as usize;
        let mut th = Vec::new();
        for i in 0..n {
            plant.advance(0.0);
            if (i + 1) % every == 0 {
                th.push(plant.state()[ix::TH_V]);
            }
        }
        th
    };
    let coarse = run(1e-3);
    let fine = run(2.5e-4);
    let peak = fine.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let err = coarse
        .iter()
        .zip(&fine)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    // The irregularity's quintic blend has a discontinuous third derivative at its knots,
    // which costs RK4 some order; the 1 ms error must still be 100x below the 1 mrad sensor
    // noise (measured: 7e-7 rad on a 0.04 rad peak).
    assert!(err < 1e-5, "max |Δθ_v| = {err} rad (peak {peak})");
}

/// The spectrum track's alignment and cross-level, sampled through `Track::at` as the plant
/// sees them, have the ERRI B176 spectrum they were drawn from. Estimator: Welch's averaged
/// periodogram, Hann window, 512 m segments without overlap, 8 seeds of a 60 km straight
/// (936 segments). Each segment's periodogram at one frequency is S·χ²₂/2 (mean S, standard
/// deviation S) for a Gaussian process, so the average of K independent ones has a relative
/// standard deviation 1/√K = 3.3 %; the tolerance is 5 of those plus 2 % for the Hann
/// window's smoothing of a spectrum falling as Ω⁻² to Ω⁻⁴ over its ±2-bin main lobe
/// (relative bias ≈ p(p+1)/2·(σ_W/Ω)² with σ_W ≈ 0.6 bin: below 1.5 % at the longest
/// wavelength tested). Outside the band [3, 150] m the estimate is below 1 % of the formula.
#[test]
fn spectrum_track_has_the_erri_spectrum_it_was_drawn_from() {
    use vehicle_model::spectrum::{alignment_psd, cross_level_psd, Level};
    use vehicle_model::{IrregularityModel, Track};
    let mut p = TrackParams {
        straight_before_m: 60_000.0,
        cant_deg: 0.0,
        ..Default::default()
    };
    p.irregularity.model = IrregularityModel::Spectrum;
    p.irregularity.level = Some(Level::High);
    assert!(p.validate("track").errors.is_empty());
    let (seg, ds) = (2048usize, 0.25);
    let wavelengths = [2.0, 4.0, 8.0, 16.0, 32.0, 64.0];
    let omegas: Vec<f64> = wavelengths
        .iter()
        .map(|l| std::f64::consts::TAU / l)
        .collect();
    let win: Vec<f64> = (0..seg)
        .map(|n| 0.5 * (1.0 - (std::f64::consts::TAU * n as f64 / seg as f64).cos()))
        .collect();
    let w2: f64 = win.iter().map(|w| w * w).sum();
    let mut sum = vec![[0.0f64; 2]; omegas.len()];
    let mut k = 0usize;
    for seed in 1..=8 {
        let t = Track::new(&p, seed);
        let n_seg = (p.straight_before_m / ds) as usize / seg;
        for j in 0..n_seg {
            let x: Vec<(f64, f64)> = (0..seg)
                .map(|n| {
                    let pt = t.at((j * seg + n) as f64 * ds);
                    (pt.y_o, pt.cant)
                })
                .collect();
            for (i, &om) in omegas.iter().enumerate() {
                let (mut ar, mut ai, mut cr, mut ci) = (0.0, 0.0, 0.0, 0.0);
                for (n, (&(y, c), w)) in x.iter().zip(&win).enumerate() {
                    let ph = om * n as f64 * ds;
                    let (s, co) = ph.sin_cos();
                    ar += w * y * co;
                    ai -= w * y * s;
                    cr += w * c * co;
                    ci -= w * c * s;
                }
                // One-sided density in rad/m: S(Ω) = G(f)/π with G the two-sided density in
                // cycles per metre, G = Δs·|X|²/Σw².
                sum[i][0] += ds * (ar * ar + ai * ai) / (std::f64::consts::PI * w2);
                sum[i][1] += ds * (cr * cr + ci * ci) / (std::f64::consts::PI * w2);
            }
            k += 1;
        }
    }
    assert_eq!(k, 936);
    let tol = 5.0 / (k as f64).sqrt() + 0.02;
    for (i, (&om, &l)) in omegas.iter().zip(&wavelengths).enumerate() {
        let est = [sum[i][0] / k as f64, sum[i][1] / k as f64];
        let formula = [
            alignment_psd(Level::High, om),
            cross_level_psd(Level::High, om),
        ];
        for c in 0..2 {
            let ratio = est[c] / formula[c];
            if l < 3.0 {
                assert!(ratio < 0.01, "λ = {l} m outside the band: ratio {ratio}");
            } else {
                assert!(
                    (ratio - 1.0).abs() < tol,
                    "λ = {l} m, {}: estimate {:.4e}, formula {:.4e} (ratio {ratio:.3}, tol {tol:.3})",
                    ["alignment", "cross-level"][c],
                    est[c],
                    formula[c]
                );
            }
        }
    }
}

/// Beyond the clearance the bump stops carry the load the spring cannot: on a steady curve
/// taken too fast for the free play, the body's lateral balance (eq 9 with every rate zero)
/// is 2·(k_sy·Δs + F_stop(Δs)) = m_v·(g·θ_o − v²/R), a scalar equation solved here by
/// bisection with the stop's characteristic written out, and the simulated vehicle settles
/// there.
#[test]
fn the_bump_stops_hold_the_body_where_the_lateral_balance_says() {
    let p = VehicleParams::default();
    let v = 200.0 / 3.6;
    let (kappa, cant) = (1.0 / 1000.0, 6f64.to_radians());
    // Without stops the spring alone would have to deflect past the clearance.
    let linear = static_equilibrium(&p, v, kappa, cant);
    let ds_linear = linear[0] - p.h1 * linear[1] - linear[2] - p.h2 * linear[3];
    assert!(ds_linear.abs() > p.bump_stop_m + 0.01, "{ds_linear}");
    let load = p.m_v * (G * cant - v * v * kappa) / 2.0;
    let stop = |d: f64| {
        let into = d.abs() - 0.060;
        if into > 0.0 {
            d.signum() * (1.0e6 * into + 1.0e10 * into.powi(3))
        } else {
            0.0
        }
    };
    let balance = |d: f64| p.k_sy * d + stop(d) - load;
    let (mut lo, mut hi) = (ds_linear.min(0.0), ds_linear.max(0.0));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if balance(lo) * balance(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let want = 0.5 * (lo + hi);
    assert!(want.abs() > p.bump_stop_m && want.abs() < ds_linear.abs());

    let veh = Vehicle::new(p.clone(), v);
    let w = vehicle_model::TrackInput {
        curvature: kappa,
        cant,
        ..Default::default()
    };
    let mut x = vehicle_model::vehicle::State::zeros();
    let dt = 1e-3;
    for _ in 0..60_000 {
        let k1 = veh.deriv(&x, 0.0, &w);
        let k2 = veh.deriv(&(x + k1 * (dt / 2.0)), 0.0, &w);
        let k3 = veh.deriv(&(x + k2 * (dt / 2.0)), 0.0, &w);
        let k4 = veh.deriv(&(x + k3 * dt), 0.0, &w);
        x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0);
    }
    let ds = x[ix::Y_V] - p.h1 * x[ix::TH_V] - x[ix::Y_B] - p.h2 * x[ix::TH_B];
    // Settled (the slowest mode, the airspring reservoir, decays in a few seconds) to well
    // under a micrometre of the balance.
    assert!((ds - want).abs() < 1e-6, "simulated {ds}, balance {want}");
    assert!(
        (p.bump_stop_force(ds) - stop(ds)).abs() < 1e-6,
        "the model's characteristic"
    );
}
