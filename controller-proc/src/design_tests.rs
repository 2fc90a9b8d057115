//! Checks of the LQG and MPC designs against closed-form results: the Riccati residuals and
//! stable loops of the LQG, and the MPC against its closed forms along the paper's drive,
//! with the QP rows it leaves out.

use super::*;
use crate::linalg::{spectral_abscissa, spectral_radius};

fn model() -> LinearModel {
    LinearModel::new(&VehicleParams::default(), TrackParams::default().speed())
}

/// One update of the MPC's closed loop along the paper's drive, before the MPC steps.
struct DriveUpdate<'a> {
    step: usize,
    /// The previous command u(k−1) (rad).
    u_prev: f64,
    /// The free response of the update (from the filtered measurement).
    f: Vec<f64>,
    /// The references over the horizon.
    r: &'a [f64],
}

/// Runs `mpc` (horizon 5, period `period`) in closed loop with the discretised vehicle
/// along the paper's track at ρ = 0.50, the reference held over the horizon and a small
/// deterministic measurement noise; `each` sees every update before the MPC steps, and
/// gets the command it applied. Returns the number of updates.
fn paper_drive(
    mpc: &mut Mpc,
    period: f64,
    mut each: impl FnMut(&mut Mpc, &DriveUpdate),
    mut applied: impl FnMut(&mpc::MpcUpdate),
) -> usize {
    let m = model();
    let track = TrackParams::default();
    let ctrl = Controller::new(&ControllerInit {
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
    let d = m.discretise(period);
    let v = track.speed();
    let mut x = nalgebra::DMatrix::zeros(9, 1);
    let mut u_prev = 0.0;
    let n = (track.length() / v / period) as usize;
    for step in 0..n {
        let pos = v * period * step as f64;
        let r = vec![ctrl.reference_at(pos); 5];
        let w = vec![ctrl.track_input_at(pos); 5];
        let xi = x[(1, 0)] + 1e-3 * ((step * 7) as f64).sin();
        let f = mpc.free_response(&mpc.filter(xi), &w);
        each(
            mpc,
            &DriveUpdate {
                step,
                u_prev,
                f,
                r: &r,
            },
        );
        let u = mpc.step(&mpc::MpcInput { xi, r: &r, w: &w });
        applied(&u);
        u_prev = u.u;
        let wk = nalgebra::DMatrix::from_column_slice(6, 1, &w[0]);
        x = &d.a * &x + &d.b * u.u + &d.g * wk;
    }
    n
}

#[test]
fn lqg_riccati_residuals_vanish_and_its_loops_are_stable() {
    let m = model();
    let lqg = Lqg::new(
        &m,
        &LqgSettings::default(),
        &KalmanSettings::default(),
        1e-3,
    )
    .unwrap();
    let d = &lqg.design;
    // Residuals relative to ‖Q‖: double precision with condition numbers of ~1e6 leaves
    // about 1e-10.
    assert!(d.residual_k < 1e-9, "eq 25 residual {}", d.residual_k);
    assert!(d.residual_e < 1e-9, "eq 28 residual {}", d.residual_e);
    // P_k, P_e symmetric positive definite / semi-definite.
    assert!(d.p_k.symmetric_eigenvalues().min() > 0.0);
    assert!(d.p_e.symmetric_eigenvalues().min() > -1e-12 * d.p_e.norm());
    // Continuous LQI loop Π_I − B_I K_op and the filter Π − K_est Ψ: Re λ < 0.
    let a_cl = &d.a_i - &d.b_i * &d.k_op;
    assert!(spectral_abscissa(&a_cl) < 0.0);
    assert!(spectral_abscissa(&(&m.a - &d.k_est * &m.c)) < 0.0);
    // The discrete loop actually run (plant, filter at T = 1 ms, forward-Euler integrator).
    let rho = spectral_radius(&lqg.closed_loop());
    assert!(rho < 1.0, "discrete LQG loop spectral radius {rho}");
    // Integral gain: for a scalar integrator weight q_I and R_w = 1 the LQI integral gain
    // tends to √q_I when the plant is fast compared with the integrator; here within 10 %.
    let ki = -d.k_op[(0, 9)];
    assert!((ki / 1000f64.sqrt() - 1.0).abs() < 0.1, "K_I = {ki}");
    eprintln!("K_op = {}", d.k_op);
    eprintln!("K_est = {}", d.k_est.transpose());
}

#[test]
fn mpc_meets_its_closed_form_in_closed_loop() {
    // The MPC in closed loop with the discretised vehicle along the paper's track at
    // ρ = 0.50 (the benchmark's drive, one pass). Wherever the unconstrained optimum
    // Δu* = −H⁻¹g keeps every constraint with room to spare it is the QP's optimum, and the
    // first move Clarabel returns must match it. Measured with the fitted settings: p50
    // 3.5e-9 rad, max 4.8e-6 rad; with Clarabel's equilibration and its 1e-8 tolerances the
    // same loop gives 2.8e-8 and 3.3e-5 (module notes of `mpc`).
    let period = 0.05;
    let mut mpc = Mpc::new(
        &model(),
        &MpcSettings::default(),
        &KalmanSettings::default(),
        period,
        3.5,
        InputShape::Hold,
    )
    .unwrap();
    let mut errors = Vec::new();
    let n = paper_drive(
        &mut mpc,
        period,
        |mpc, at| {
            let star = mpc.unconstrained(&at.f, at.r);
            let more: Vec<f64> = star.iter().map(|d| d * (1.0 + 1e-3)).collect();
            if mpc.keeps_constraints(at.u_prev, &at.f, &star)
                && mpc.keeps_constraints(at.u_prev, &at.f, &more)
            {
                let (du, _, ok) = mpc.solve(&at.f, at.r);
                assert!(ok, "step {}: an unconstrained QP must solve", at.step);
                errors.push((du[0] - star[0]).abs());
            }
        },
        |_| {},
    );
    // Both kinds of update occur: the limits bind in the curve transitions.
    assert!(
        errors.len() > 50 && errors.len() < n,
        "{} of {n}",
        errors.len()
    );
    errors.sort_by(f64::total_cmp);
    let (p50, max) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    assert!(p50 < 1e-8, "p50 {p50:e} rad");
    assert!(max < 1e-5, "max {max:e} rad");
}

#[test]
fn mpc_leaves_out_only_rows_that_cannot_bind() {
    // The paper's drive at ρ = 0.50 in closed loop, twice: with the paper's soft output
    // limit (6°), where the input limit binds in the curves, and with it lowered to 1.5°,
    // where the output limit binds (at 2.5° it never does). Where `rows_needed`
    // lets an update leave rows out, the full QP must give the same moves (both are
    // Clarabel's optimum of one problem to its 1e-10 gap: at most 1e-5 rad, the bound of
    // `mpc_meets_its_closed_form_in_closed_loop`). Where it keeps the output rows, the
    // update's prediction must keep the limit up to the slack its weight allows: a slack ε
    // costs λ_ε ε² against the tracking cost, here ε ≲ 1e-5 rad; 1e-4 rad is the bound.
    let period = 0.05;
    let (mut gaps, mut counts, mut binding) = (Vec::new(), [0; 3], [0; 3]);
    for theta_v_max_deg in [6.0, 1.5] {
        let s = MpcSettings {
            theta_v_max_deg,
            ..Default::default()
        };
        let (y_max, u_max) = (s.theta_v_max_deg.to_radians(), 3.5f64.to_radians());
        let k = KalmanSettings::default();
        let mut mpc = Mpc::new(&model(), &s, &k, period, 3.5, InputShape::Hold).unwrap();
        let last = std::cell::Cell::new(QpRows::Full);
        let inputs_binding = std::cell::Cell::new(0);
        paper_drive(
            &mut mpc,
            period,
            |mpc, at| {
                let (f, r, step) = (&at.f, at.r, at.step);
                let rows = mpc.rows_needed(f);
                counts[rows as usize] += 1;
                last.set(rows);
                let (du, _, ok) = mpc.solve(f, r);
                assert!(ok, "step {step}");
                let (du_full, _, ok) = mpc.solve_with(f, r, QpRows::Full);
                assert!(ok, "step {step}");
                if rows == QpRows::Full {
                    assert_eq!(du, du_full, "step {step}: the full QP, solved twice");
                    let worst = (0..5)
                        .map(|i| {
                            (f[i] + mpc.theta[(i, 0)] * du[0] + mpc.theta[(i, 1)] * du[1]).abs()
                        })
                        .fold(0.0, f64::max);
                    assert!(worst <= y_max + 1e-4, "step {step}: |ξ| {worst} > {y_max}");
                    // Whether the limit binds, so that leaving its rows out would have
                    // mattered.
                    if worst > y_max - 1e-6 {
                        binding[0] += 1;
                    }
                } else {
                    gaps.push((du[0] - du_full[0]).abs().max((du[1] - du_full[1]).abs()));
                }
            },
            // Whether an input-level limit binds where those rows are kept.
            |u| {
                if last.get() == QpRows::Inputs && u.u.abs() > u_max - 1e-9 {
                    inputs_binding.set(inputs_binding.get() + 1);
                }
            },
        );
        binding[1] += inputs_binding.get();
    }
    eprintln!("updates per form (full, inputs, moves) {counts:?}, binding {binding:?}");
    // Every form occurs, and the limits they keep bind in some of their updates.
    assert!(counts.iter().all(|&c| c > 20), "{counts:?}");
    assert!(binding[0] > 5 && binding[1] > 5, "{binding:?}");
    gaps.sort_by(f64::total_cmp);
    let (p50, max) = (gaps[gaps.len() / 2], gaps[gaps.len() - 1]);
    eprintln!("|Δu − Δu_full| p50 {p50:e}, max {max:e} rad");
    assert!(p50 < 1e-8 && max < 1e-5, "p50 {p50:e}, max {max:e} rad");
}

#[test]
fn one_move_mpc_meets_its_clamped_closed_form() {
    // With p = M = 1 the QP is one-dimensional, and where the soft output row cannot bind
    // its optimum is the unconstrained one, Δu* = −θ λ_ξ (f − r) / (θ² λ_ξ + λ_Δu),
    // clamped to the moves the hard limits allow: |Δu| ≤ Δu_max, |u(k−1) + Δu| ≤ u_max.
    // That holds with every constraint active or not, so it checks the constrained optima
    // exactly. Along the paper's drive at ρ = 0.50, both the reduced QP an update solves
    // and the full QP must meet it; measured p50 2.3e-10 and 3.9e-10, max 1.1e-6 and
    // 2.6e-6 rad (an interior point near an active bound); bounds as in
    // `mpc_meets_its_closed_form_in_closed_loop`.
    let period = 0.05;
    let s = MpcSettings {
        horizon_p: 1,
        horizon_m: 1,
        ..Default::default()
    };
    let (lam, lam_du) = (s.output_weight, s.rate_weight);
    let (du_max, u_max) = (s.du_max_deg.to_radians(), 3.5f64.to_radians());
    let k = KalmanSettings::default();
    let mut mpc = Mpc::new(&model(), &s, &k, period, 3.5, InputShape::Hold).unwrap();
    let (mut reduced, mut full, mut clamped) = (Vec::new(), Vec::new(), 0);
    paper_drive(
        &mut mpc,
        period,
        |mpc, at| {
            assert_ne!(mpc.rows_needed(&at.f), QpRows::Full, "step {}", at.step);
            let th = mpc.theta[(0, 0)];
            let star = -th * lam * (at.f[0] - at.r[0]) / (th * th * lam + lam_du);
            let lo = (-du_max).max(-u_max - at.u_prev);
            let hi = du_max.min(u_max - at.u_prev);
            let exact = star.clamp(lo, hi);
            if exact != star {
                clamped += 1;
            }
            let (du, _, ok) = mpc.solve(&at.f, at.r);
            assert!(ok, "step {}", at.step);
            reduced.push((du[0] - exact).abs());
            let (du, _, ok) = mpc.solve_with(&at.f, at.r, QpRows::Full);
            assert!(ok, "step {}", at.step);
            full.push((du[0] - exact).abs());
        },
        |_| {},
    );
    // The limits bind in some updates and not in others.
    assert!(clamped > 20 && clamped < reduced.len() - 20, "{clamped}");
    for (what, e) in [("reduced", &mut reduced), ("full", &mut full)] {
        e.sort_by(f64::total_cmp);
        let (p50, max) = (e[e.len() / 2], e[e.len() - 1]);
        assert!(
            p50 < 1e-8 && max < 1e-5,
            "{what}: p50 {p50:e}, max {max:e} rad"
        );
    }
}

#[test]
fn unconstrained_mpc_equals_its_closed_form() {
    let m = model();
    let s = MpcSettings::default();
    let mut mpc = Mpc::new(
        &m,
        &s,
        &KalmanSettings::default(),
        0.05,
        3.5,
        InputShape::Hold,
    )
    .unwrap();
    eprintln!("L_est = {}", mpc.l_est.transpose());
    // A state and reference where no constraint binds: the QP optimum must equal
    // Δu* = −(ΘᵀΛΘ + Λ_Δu)⁻¹ ΘᵀΛ (f − r).
    let mut x = nalgebra::DMatrix::zeros(10, 1);
    x[(1, 0)] = 0.002;
    let w = vec![[0.0; 6]; 5];
    let f = mpc.free_response(&x, &w);
    let r = vec![0.0025; 5];
    let exact = mpc.unconstrained(&f, &r);
    assert!(exact.iter().all(|v| v.abs() < 0.5f64.to_radians()));
    let (du, iters, ok) = mpc.solve(&f, &r);
    assert!(ok && iters > 0);
    // Clarabel stops at a duality gap of ~1e-8: the inactive constraints still pull the
    // interior-point iterate by about gap/slack, 1e-5 relative here. 1e-3 relative
    // (5e-6 rad, 3e-4°) is far below anything the bar can resolve.
    for (a, b) in du.iter().zip(&exact) {
        assert!((a - b).abs() < 1e-3 * b.abs() + 1e-9, "{a} vs {b}");
    }
    // A large step: the move is capped at Δu_max exactly.
    let r = vec![0.05; 5];
    let (du, _, ok) = mpc.solve(&f, &r);
    assert!(ok);
    assert!(
        (du[0] - 0.5f64.to_radians()).abs() < 1e-7,
        "{}",
        du[0].to_degrees()
    );
    mpc.set_previous(3.4f64.to_radians());
    let (du, _, _) = mpc.solve(&f, &r);
    assert!(
        du[0] <= 0.1f64.to_radians() + 1e-7,
        "u limit: {}",
        du[0].to_degrees()
    );
    // 0.75° below the limit: the first move is free, the second may take only the rest,
    // so the rows of u(k+1) must be kept although those of u(k) cannot bind.
    mpc.set_previous(2.75f64.to_radians());
    assert_eq!(mpc.rows_needed(&f), QpRows::Inputs);
    let (du, _, ok) = mpc.solve(&f, &r);
    assert!(ok);
    let (first, both) = (du[0].to_degrees(), (du[0] + du[1]).to_degrees());
    assert!((first - 0.5).abs() < 1e-5, "first move {first}°");
    assert!(
        (both - 0.75).abs() < 1e-5,
        "u(k+1) − u(k−1) = {both}°, not 0.75°"
    );
    // Far from every limit only the move rows are left.
    mpc.set_previous(0.0);
    assert_eq!(mpc.rows_needed(&f), QpRows::Moves);
}
