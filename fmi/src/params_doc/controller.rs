//! The controller (`controller_proc::ControllerSettings` and its sections) and the values it
//! receives beside them (`ControllerInit`).

use super::Row;

/// `(name, unit, description)`, as [`super`] describes them.
pub(super) const CONTROLLER: &[Row] = &[
    // `[controller]`, section 3.
    (
        "controller.mode",
        "",
        "Controller mode: passive, pi, lqg or mpc",
    ),
    (
        "controller.rho",
        "1",
        "Reduction ρ of the non-tilting lateral acceleration (eq 18)",
    ),
    (
        "controller.tilt_inverse",
        "",
        "How the tilt command inverts eq 13: small-angle (eq 18 as printed) or exact",
    ),
    (
        "controller.period_s",
        "s",
        "Controller period; a multiple of the base tick",
    ),
    (
        "controller.u_max_deg",
        "deg",
        "Bar command limit |δ_a,cmd|: the actuator's range",
    ),
    (
        "controller.pi.kp",
        "1",
        "Proportional gain K_p of the PI, rad/rad (Table 3)",
    ),
    (
        "controller.pi.ki",
        "1/s",
        "Integral gain K_i of the PI (Table 3)",
    ),
    (
        "controller.lqg.q_diag",
        "",
        "Diagonal entry of the LQI state weight Q_w (eq 24)",
    ),
    ("controller.lqg.r_w", "", "LQI input weight R_w (eq 24)"),
    (
        "controller.lqg.limit_command",
        "",
        "Clamp the LQG command to u_max_deg (conditional integration); false is the paper's LQI",
    ),
    (
        "controller.mpc.horizon_p",
        "",
        "MPC prediction horizon p (steps)",
    ),
    (
        "controller.mpc.horizon_m",
        "",
        "MPC control horizon M (moves)",
    ),
    (
        "controller.mpc.output_weight",
        "",
        "MPC output weight λ_ξ (on rad²)",
    ),
    (
        "controller.mpc.rate_weight",
        "",
        "MPC input-rate weight λ_Δu (on rad²)",
    ),
    (
        "controller.mpc.du_max_deg",
        "deg",
        "Largest MPC move |Δu| per period",
    ),
    (
        "controller.mpc.theta_v_max_deg",
        "deg",
        "Soft MPC output limit |θ_v|",
    ),
    (
        "controller.mpc.slack_weight",
        "",
        "MPC weight λ_ε on the squared slack (rad²) of the soft output limit",
    ),
    (
        "controller.mpc.preview",
        "",
        "Feed the MPC the track database's future reference over the horizon (not the paper's)",
    ),
    (
        "controller.mpc.max_iter",
        "",
        "Iteration limit of the MPC's QP solver (Clarabel)",
    ),
    (
        "controller.kalman.w_n",
        "",
        "Diagonal entry of the Kalman filter's process noise intensity W_n (eq 17)",
    ),
    (
        "controller.kalman.v_n",
        "",
        "Kalman measurement noise design value V_n (eq 16): rad²·s (LQG), rad² per sample (MPC)",
    ),
    (
        "controller.kalman.disturbance_var",
        "rad2",
        "MPC only: variance per sample of the integrated output disturbance d",
    ),
    (
        "controller.kalman.track_input",
        "",
        "Feed the track database's curvature and cant to the estimator's model; off in the paper",
    ),
    (
        "controller.localisation.bias_m",
        "m",
        "Constant error of the believed position; positive believes the vehicle further on",
    ),
    (
        "controller.localisation.noise_std_m",
        "m",
        "Standard deviation of a Gaussian localisation error added to the bias",
    ),
    (
        "controller.localisation.hold_s",
        "s",
        "How long each localisation noise sample is held",
    ),
    // Values the controller receives beside its sections (`ControllerInit`; `seed` is with
    // the plant's).
    (
        "input_shape",
        "",
        "Command shape the MPC's prediction assumes (actuator.command_shaping): hold or ramp",
    ),
];
