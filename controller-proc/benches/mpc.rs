//! MPC solve time: the full controller update (Kalman filter, free response, Clarabel QP) in
//! closed loop with the discretised vehicle through the paper's ρ = 0.50 case, where the input
//! constraint is active, so both inactive and active QPs are timed.
//!
//! Then its accuracy: the same closed loop once more, where every update's QP whose
//! unconstrained optimum Δu* = −H⁻¹g (closed form) keeps every constraint, so is the optimum,
//! is also solved outside the timed update and its first move compared with Δu₀*.
//!
//! Update times are also given by the form of the QP solved (`Mpc::rows_needed`), after a
//! second timed pass with the soft output limit lowered to 1.5°, where it binds in the curves
//! and the full QP is solved (the paper's 6° never binds on this drive).
//!
//! `cargo bench -p controller-proc --bench mpc`

use std::time::Instant;

use controller_proc::mpc::MpcInput;
use controller_proc::{
    ControllerInit, ControllerSettings, InputShape, KalmanSettings, LinearModel, Mode, Mpc,
    MpcSettings, QpRows,
};
use vehicle_model::{TrackParams, VehicleParams};

const PERIOD: f64 = 0.05;
const REPEATS: usize = 30;
/// The paper's soft output limit |θ_v| (deg), and one low enough to bind on this drive.
const PAPER_LIMIT: f64 = 6.0;
const BINDING_LIMIT: f64 = 1.5;
const QP_FORMS: [QpRows; 3] = [QpRows::Full, QpRows::Inputs, QpRows::Moves];

/// What one closed-loop pass measured.
#[derive(Default)]
struct Pass {
    /// Update times (µs).
    times: Vec<f64>,
    /// Clarabel iterations.
    iterations: Vec<f64>,
    /// Update times (µs) by the form of the QP solved, in the order of `QP_FORMS`.
    by_form: [Vec<f64>; 3],
    /// |Δu₀ − Δu₀*| (rad) on the QPs whose unconstrained optimum Δu* (closed form) keeps
    /// every constraint, so is the optimum.
    interior: Vec<f64>,
}

/// Runs the MPC of `preview` in closed loop along the paper's track at ρ = 0.50; with `check`,
/// every QP with no constraint active is also solved and compared with its closed form.
fn pass(
    model: &LinearModel,
    preview: bool,
    theta_v_max_deg: f64,
    rep: usize,
    check: bool,
    out: &mut Pass,
) {
    let track = TrackParams::default();
    let v = track.speed();
    let s = MpcSettings {
        preview,
        theta_v_max_deg,
        ..Default::default()
    };
    let k = KalmanSettings::default();
    let mut mpc = Mpc::new(model, &s, &k, PERIOD, 3.5, InputShape::Hold).unwrap();
    // The tilt command of the paper's track at ρ = 0.50, from the controller's own reference
    // generator.
    let ctrl = controller_proc::Controller::new(&ControllerInit {
        controller: ControllerSettings {
            mode: Mode::Passive,
            rho: 0.5,
            ..Default::default()
        },
        track: track.clone(),
        vehicle: VehicleParams::default(),
        input_shape: InputShape::Hold,
        seed: 0,
    })
    .unwrap();
    let d = model.discretise(PERIOD);
    let mut x = nalgebra::DMatrix::zeros(9, 1);
    let mut u_prev = 0.0;
    let n = (track.length() / v / PERIOD) as usize;
    for k in 0..n {
        let pos = v * PERIOD * k as f64;
        let r: Vec<f64> = (1..=5)
            .map(|i| {
                ctrl.reference_at(if preview {
                    pos + v * PERIOD * i as f64
                } else {
                    pos
                })
            })
            .collect();
        let w = vec![ctrl.track_input_at(pos); 5];
        let xi = x[(1, 0)] + 1e-3 * ((k * 7 + rep) as f64).sin();
        if check {
            // The QP the update below solves: same filtered state, free response, u(k−1).
            let f = mpc.free_response(&mpc.filter(xi), &w);
            let star = mpc.unconstrained(&f, &r);
            // Strictly inside (0.1 % more move still keeps every constraint).
            let more: Vec<f64> = star.iter().map(|d| d * (1.0 + 1e-3)).collect();
            if mpc.keeps_constraints(u_prev, &f, &star) && mpc.keeps_constraints(u_prev, &f, &more)
            {
                let (got, _, ok) = mpc.solve(&f, &r);
                assert!(ok, "an interior QP must solve");
                out.interior.push((got[0] - star[0]).abs());
            }
        }
        // The form the update below solves (outside the timed update).
        let rows = mpc.rows_needed(&mpc.free_response(&mpc.filter(xi), &w));
        let t0 = Instant::now();
        let u = mpc.step(&MpcInput { xi, r: &r, w: &w });
        let us = t0.elapsed().as_secs_f64() * 1e6;
        out.times.push(us);
        out.by_form[QP_FORMS.iter().position(|&f| f == rows).unwrap()].push(us);
        out.iterations.push(u.iterations as f64);
        u_prev = u.u;
        let wk = nalgebra::DMatrix::from_column_slice(6, 1, &w[0]);
        x = &d.a * &x + &d.b * u.u + &d.g * wk;
    }
}

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let model = LinearModel::new(&VehicleParams::default(), TrackParams::default().speed());
    let mut timed = Pass::default();
    for preview in [false, true] {
        for rep in 0..REPEATS {
            pass(&model, preview, PAPER_LIMIT, rep, false, &mut timed);
        }
    }
    println!(
        "MPC update (filter + QP), {} solves: p50 {:.1} us, p99 {:.1} us, max {:.1} us; Clarabel iterations p50 {:.0}, max {:.0}",
        timed.times.len(),
        pct(&mut timed.times, 0.5),
        pct(&mut timed.times, 0.99),
        pct(&mut timed.times, 1.0),
        pct(&mut timed.iterations, 0.5),
        pct(&mut timed.iterations, 1.0)
    );
    // The same drive with the output limit binding in the curves, so that the full QP is timed.
    for preview in [false, true] {
        for rep in 0..REPEATS {
            pass(&model, preview, BINDING_LIMIT, rep, false, &mut timed);
        }
    }
    println!("by form, both passes (the second with |θ_v| ≤ {BINDING_LIMIT}°):");
    for (form, times) in QP_FORMS.iter().zip(timed.by_form.iter_mut()) {
        if times.is_empty() {
            println!("  {form:?} QP: no updates");
        } else {
            println!(
                "  {form:?} QP: {} updates, p50 {:.1} us, p99 {:.1} us",
                times.len(),
                pct(times, 0.5),
                pct(times, 0.99)
            );
        }
    }
    let mut checked = Pass::default();
    for preview in [false, true] {
        for rep in 0..REPEATS {
            pass(&model, preview, PAPER_LIMIT, rep, true, &mut checked);
        }
    }
    let e = &mut checked.interior;
    println!(
        "accuracy against the closed form, {} QPs with no constraint active: |Δu0 − Δu0*| p50 {:.1e} rad, p99 {:.1e} rad, max {:.1e} rad",
        e.len(),
        pct(e, 0.5),
        pct(e, 0.99),
        pct(e, 1.0)
    );
}
