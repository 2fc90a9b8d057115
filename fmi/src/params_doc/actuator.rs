//! The actuator (`actuator_proc::ActuatorSettings`, `BldcParams`, `DcLinkParams`) and the
//! values it receives beside them (`ActuatorInit`).

use super::Row;

/// `(name, unit, description)`, as [`super`] describes them.
pub(super) const ACTUATOR: &[Row] = &[
    // Values the actuator receives beside its section (`ActuatorInit`).
    (
        "k_vr",
        "N.m/rad",
        "Anti-roll bar stiffness k_vr, from the vehicle parameters",
    ),
    (
        "command_period_s",
        "s",
        "Period at which the controller sends new set-points, for the command shaping",
    ),
    // `[actuator]`.
    (
        "actuator.model",
        "",
        "Actuator model: bldc (switched drive), bldc-averaged or ideal (δ_a = δ_a,cmd)",
    ),
    (
        "actuator.command_shaping",
        "",
        "How a new set-point is applied between controller updates: hold or ramp",
    ),
    // `[actuator.bldc]`, Tables 1-2 and eq 1.
    (
        "actuator.bldc.v_dc",
        "V",
        "Supply voltage V_app: the rectifier's no-load DC-link voltage (Table 2)",
    ),
    ("actuator.bldc.r_s", "Ohm", "Stator phase resistance R_s"),
    ("actuator.bldc.l_s", "H", "Stator phase inductance L_s"),
    ("actuator.bldc.b_f", "N.m.s/rad", "Viscous friction B_f"),
    ("actuator.bldc.j_rot", "kg.m2", "Rotor inertia J_rot"),
    (
        "actuator.bldc.k_t",
        "N.m/A",
        "Torque constant k_t with two phases conducting",
    ),
    ("actuator.bldc.poles", "", "Number of poles N_p"),
    ("actuator.bldc.n_r", "1", "Harmonic gearbox ratio n_r"),
    ("actuator.bldc.l1", "m", "Bar lever L1 (eq 1)"),
    ("actuator.bldc.l2", "m", "Bar lever L2 (eq 1)"),
    (
        "actuator.bldc.speed_kp",
        "N.m.s/rad",
        "Proportional gain of the speed PI, on the motor shaft (Table 1)",
    ),
    (
        "actuator.bldc.speed_ki",
        "N.m/rad",
        "Integral gain of the speed PI, parallel form (Table 1)",
    ),
    (
        "actuator.bldc.torque_limit_nm",
        "N.m",
        "Torque limit of the speed PI (Table 1)",
    ),
    ("actuator.bldc.current_limit_a", "A", "Phase current limit"),
    (
        "actuator.bldc.position_gain",
        "1/s",
        "Position loop gain K_θ: ω_ref = K_θ (θ_m,ref − θ_m)",
    ),
    (
        "actuator.bldc.speed_limit_fraction",
        "1",
        "Speed limit as a fraction of the no-load speed V_dc/k_t",
    ),
    (
        "actuator.bldc.control_period_s",
        "s",
        "Period of the position and speed loops; a multiple of the electrical step",
    ),
    (
        "actuator.bldc.hysteresis_a",
        "A",
        "Hysteresis band of the current controller, full width",
    ),
    (
        "actuator.bldc.stroke_deg",
        "deg",
        "Bar stroke: commands are clamped to ±stroke and the bar stops mechanically there",
    ),
    (
        "actuator.bldc.dt_switched_s",
        "s",
        "Electrical integration step of the switched model (the event-driven one's fallback step)",
    ),
    (
        "actuator.bldc.switched_integration",
        "",
        "Integration of the switched model: event (closed form between events) or fixed-step",
    ),
    (
        "actuator.bldc.dt_averaged_s",
        "s",
        "Integration step of the averaged model",
    ),
    (
        "actuator.bldc.gear_efficiency",
        "1",
        "Efficiency η of the harmonic gearbox, both directions; 1 is the paper's lossless gear",
    ),
    (
        "actuator.bldc.gear_loss_speed_rad_s",
        "rad/s",
        "Motor speed over which the gear's loss builds up from zero to its full value",
    ),
    (
        "actuator.bldc.continuous_torque_nm",
        "N.m",
        "Continuous (thermal) torque rating of the motor, checked against the run's RMS torque",
    ),
    // `[actuator.dc_link]`, Fig. 4.
    (
        "actuator.dc_link.capacitance_f",
        "F",
        "DC-link capacitance C",
    ),
    (
        "actuator.dc_link.supply_resistance_ohm",
        "Ohm",
        "Supply (line and transformer) resistance seen by the rectifier R_s",
    ),
    (
        "actuator.dc_link.chopper_on_v",
        "V",
        "Braking chopper switch-on voltage",
    ),
    (
        "actuator.dc_link.chopper_off_v",
        "V",
        "Braking chopper switch-off voltage, below the switch-on voltage",
    ),
    (
        "actuator.dc_link.chopper_resistance_ohm",
        "Ohm",
        "Braking resistor R_ch",
    ),
    (
        "actuator.dc_link.overvoltage_trip_v",
        "V",
        "DC-link voltage above which the inverter's gates are blocked",
    ),
    (
        "actuator.dc_link.aux_power_w",
        "W",
        "Power the auxiliary load draws at the supply voltage V_app; 0: none",
    ),
];
