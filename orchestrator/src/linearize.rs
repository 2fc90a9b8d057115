//! `tiltsim linearize SCENARIO`: the controllers' design model as JSON (continuous and
//! discrete matrices, eigenvalues with natural frequencies and damping) and, for the LQG and
//! MPC modes, the gains the controller will run with.

use controller_proc::design::{modes_of, rows, LinearModel};
use controller_proc::{Lqg, Mode, Mpc};
use serde_json::{json, Value};

use crate::scenario::Scenario;

/// The report for scenario `s`.
pub fn report(s: &Scenario) -> Result<Value, String> {
    let v = s.track.speed();
    let m = LinearModel::new(&s.vehicle, v);
    let c = &s.controller;
    let period = c.period_s;
    let d = m.discretise(period);
    let zd: Vec<Value> =
        d.a.complex_eigenvalues()
            .iter()
            .map(|z| json!({"re": z.re, "im": z.im, "modulus": z.norm()}))
            .collect();
    let mut out = json!({
        "scenario": s.name,
        "speed_m_s": v,
        "states": ["y_v (m)", "theta_v (rad)", "y_b (m)", "theta_b (rad)", "dy_v (m/s)",
                   "dtheta_v (rad/s)", "dy_b (m/s)", "dtheta_b (rad/s)", "theta_r (rad)"],
        "input": "delta_a (rad)",
        "disturbances": ["1/R (1/m)", "theta_o (rad)", "dtheta_o (rad/s)",
                         "ddtheta_o (rad/s^2)", "y_o (m)", "dy_o (m/s)"],
        "output": "theta_v (rad)",
        "continuous": {
            "A": rows(&m.a), "B": rows(&m.b), "G": rows(&m.g), "C": rows(&m.c),
            "modes": modes_of(&m.a),
        },
        "discrete": {
            "period_s": period, "method": "zero-order hold",
            "A": rows(&d.a), "B": rows(&d.b), "G": rows(&d.g), "C": rows(&d.c),
            "eigenvalues": zd,
        },
    });
    match c.mode {
        Mode::Lqg => {
            let l = Lqg::new(&m, &c.lqg, &c.kalman, period).map_err(|e| e.to_string())?;
            let g = &l.design;
            let cl = &g.a_i - &g.b_i * &g.k_op;
            out["lqg"] = json!({
                "K_op": rows(&g.k_op),
                "K_est": rows(&g.k_est),
                "care_residual_control": g.residual_k,
                "care_residual_filter": g.residual_e,
                "closed_loop_modes": modes_of(&cl),
                "estimator_modes": modes_of(&(&m.a - &g.k_est * &m.c)),
                "discrete_loop_spectral_radius":
                    controller_proc::linalg::spectral_radius(&l.closed_loop()),
            });
        }
        Mode::Mpc => {
            let mpc = Mpc::new(
                &m,
                &c.mpc,
                &c.kalman,
                period,
                c.u_max_deg,
                s.controller_init().input_shape,
            )
            .map_err(|e| e.to_string())?;
            out["mpc"] = json!({
                "prediction_input_shape": mpc.input_shape,
                "L_est": rows(&mpc.l_est),
                "Theta": rows(&mpc.theta),
                "hessian": rows(&mpc.h),
            });
        }
        _ => {}
    }
    Ok(out)
}
