//! `tiltsim linearize SCENARIO`: the controllers' design model as JSON (continuous and
//! discrete matrices, eigenvalues with natural frequencies and damping) and, for the LQG and
//! MPC modes, the gains the controller will run with.

use actuator_proc::ActuatorModel;
use controller_proc::design::{modes_of, rows, LinearModel};
use controller_proc::pi_loop::{ActuatorLag, PiLoop};
use controller_proc::{Lqg, Mode, Mpc};
use serde_json::{json, Value};

use tiltsim_scenario::scenario::Scenario;

/// Targets of `tiltsim linearize --design-pi`.
#[derive(Debug, Clone, Copy)]
pub struct PiTargets {
    /// Phase margin (deg).
    pub phase_margin_deg: f64,
    /// Gain margin (dB).
    pub gain_margin_db: f64,
    /// Integral time K_p/K_i (s).
    pub ti_s: f64,
}

/// The PI loop of scenario `s`: its vehicle, its actuator's closed-loop response and its
/// sampling delays (controller-proc `pi_loop`).
pub fn pi_loop(s: &Scenario) -> PiLoop {
    let m = LinearModel::new(s.controller_vehicle(), s.track.speed());
    let b = &s.actuator.bldc;
    let lag = match s.actuator.model {
        ActuatorModel::Ideal => ActuatorLag::Ideal,
        ActuatorModel::Bldc | ActuatorModel::BldcAveraged => ActuatorLag::Drive {
            position_gain: b.position_gain,
            speed_kp: b.speed_kp,
            speed_ki: b.speed_ki,
            j_rot: b.j_rot,
        },
    };
    PiLoop::new(m, lag, s.controller.period_s, s.run.dt_s)
}

/// Why a report could not be made.
#[derive(Debug, thiserror::Error)]
pub enum LinearizeError {
    /// The scenario's controller has no design (a Riccati equation or the QP set-up failed).
    #[error("{0}")]
    Design(controller_proc::linalg::DesignError),
    /// No PI reaches the requested margins.
    #[error("no PI with integral time {ti_s} s reaches a phase margin of {pm_deg}° and a gain margin of {gm_db} dB")]
    NoPi {
        /// Integral time (s).
        ti_s: f64,
        /// Phase-margin target (deg).
        pm_deg: f64,
        /// Gain-margin target (dB).
        gm_db: f64,
    },
}

impl From<controller_proc::linalg::DesignError> for LinearizeError {
    fn from(e: controller_proc::linalg::DesignError) -> Self {
        LinearizeError::Design(e)
    }
}

/// The gains of the scenario's controller, under their key of the report.
fn controller_gains(
    s: &Scenario,
    m: &LinearModel,
) -> Result<Option<(&'static str, Value)>, LinearizeError> {
    let c = &s.controller;
    let period = c.period_s;
    Ok(match c.mode {
        Mode::Lqg => {
            let l = Lqg::new(m, &c.lqg, &c.kalman, period)?;
            let g = &l.design;
            let cl = &g.a_i - &g.b_i * &g.k_op;
            Some((
                "lqg",
                json!({
                    "K_op": rows(&g.k_op),
                    "K_est": rows(&g.k_est),
                    "care_residual_control": g.residual_k,
                    "care_residual_filter": g.residual_e,
                    "closed_loop_modes": modes_of(&cl),
                    "estimator_modes": modes_of(&(&m.a - &g.k_est * &m.c)),
                    "discrete_loop_spectral_radius":
                        controller_proc::linalg::spectral_radius(&l.closed_loop()),
                }),
            ))
        }
        Mode::Mpc => {
            let mpc = Mpc::new(
                m,
                &c.mpc,
                &c.kalman,
                period,
                c.u_max_deg,
                s.controller_init().input_shape,
            )?;
            Some((
                "mpc",
                json!({
                    "prediction_input_shape": mpc.input_shape,
                    "L_est": rows(&mpc.l_est),
                    "Theta": rows(&mpc.theta),
                    "hessian": rows(&mpc.h),
                }),
            ))
        }
        Mode::Pi => {
            let l = pi_loop(s);
            Some((
                "pi_loop",
                json!({
                    "kp": c.pi.kp,
                    "ki": c.pi.ki,
                    "actuator": l.actuator,
                    "delay_s": l.delay_s,
                    "margins": l.margins(c.pi.kp, c.pi.ki),
                    "note": "linear loop; the drive's rate limit (speed_limit_fraction) is not in it",
                }),
            ))
        }
        Mode::Passive => None,
    })
}

/// The report for scenario `s`, with a PI designed for `design` when given.
pub fn report(s: &Scenario, design: Option<PiTargets>) -> Result<Value, LinearizeError> {
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
    if let Some((key, gains)) = controller_gains(s, &m)? {
        out[key] = gains;
    }
    if let Some(t) = design {
        let l = pi_loop(s);
        let d = l
            .design(t.phase_margin_deg, t.gain_margin_db, t.ti_s)
            .ok_or(LinearizeError::NoPi {
                ti_s: t.ti_s,
                pm_deg: t.phase_margin_deg,
                gm_db: t.gain_margin_db,
            })?;
        out["pi_design"] = json!(d);
    }
    Ok(out)
}
