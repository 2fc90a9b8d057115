//! Units of the FMU variables: the unit of every scenario value a participant's FMU exposes as a
//! parameter, and the SI definition of every unit name used (FMI's `<UnitDefinitions>`).

/// SI base-unit exponents of a unit, with FMI's `factor` (value in SI = factor · value):
/// `(kg, m, s, A, rad, factor)`.
type Base = (i8, i8, i8, i8, i8, f64);

/// Every unit name a tiltsim FMU uses, with its definition in SI base units.
pub const UNIT_DEFS: &[(&str, Base)] = &[
    ("1", (0, 0, 0, 0, 0, 1.0)),
    ("s", (0, 0, 1, 0, 0, 1.0)),
    ("1/s", (0, 0, -1, 0, 0, 1.0)),
    ("m", (0, 1, 0, 0, 0, 1.0)),
    ("1/m", (0, -1, 0, 0, 0, 1.0)),
    ("m/s", (0, 1, -1, 0, 0, 1.0)),
    ("m/s2", (0, 1, -2, 0, 0, 1.0)),
    ("km/h", (0, 1, -1, 0, 0, 1.0 / 3.6)),
    ("rad", (0, 0, 0, 0, 1, 1.0)),
    ("deg", (0, 0, 0, 0, 1, core::f64::consts::PI / 180.0)),
    ("rad/s", (0, 0, -1, 0, 1, 1.0)),
    ("kg", (1, 0, 0, 0, 0, 1.0)),
    ("kg.m2", (1, 2, 0, 0, 0, 1.0)),
    ("N/m", (1, 0, -2, 0, 0, 1.0)),
    ("N/m3", (1, -2, -2, 0, 0, 1.0)),
    ("N.s/m", (1, 0, -1, 0, 0, 1.0)),
    ("N.m", (1, 2, -2, 0, 0, 1.0)),
    ("N.m/rad", (1, 2, -2, 0, -1, 1.0)),
    ("N.m.s/rad", (1, 2, -1, 0, -1, 1.0)),
    ("N.m/A", (1, 2, -2, -1, 0, 1.0)),
    ("A", (0, 0, 0, 1, 0, 1.0)),
    ("V", (1, 2, -3, -1, 0, 1.0)),
    ("W", (1, 2, -3, 0, 0, 1.0)),
    ("Ohm", (1, 2, -3, -2, 0, 1.0)),
    ("H", (1, 2, -2, -2, 0, 1.0)),
    ("F", (-1, -2, 4, 2, 0, 1.0)),
];

/// Unit of the parameter `name` (a scenario value as the participant receives it, arrays
/// without their index): `Some("")` for values that have no single unit (weights and
/// variances of mixed states), `None` for a name this table does not know (a test keeps the
/// table complete).
pub fn param_unit(name: &str) -> Option<&'static str> {
    let base = name.split('[').next().unwrap_or(name);
    let leaf = base.rsplit('.').next().unwrap_or(base);
    let group = base.strip_suffix(leaf).unwrap_or("");
    Some(match (group, leaf) {
        ("vehicle.", "m_v" | "m_b") => "kg",
        ("vehicle.", "i_vr" | "i_br") => "kg.m2",
        ("vehicle.", "k_az" | "k_sz" | "k_rz" | "k_sy" | "k_pz" | "k_py") => "N/m",
        ("vehicle.", "c_rz" | "c_sy" | "c_pz" | "c_py") => "N.s/m",
        ("vehicle.", "k_vr") | ("", "k_vr") => "N.m/rad",
        ("vehicle.", "c_vr") => "N.m.s/rad",
        ("vehicle.", "d1" | "d2" | "h1" | "h2" | "h3" | "h_gv" | "h_gb" | "bump_stop_m") => "m",
        ("vehicle.", "k_bump") => "N/m",
        ("vehicle.", "k3_bump") => "N/m3",
        ("track.", "speed_kmh") => "km/h",
        ("track.", "cant_deg") | ("track.irregularity.", "amplitude_deg") => "deg",
        ("track.", _) | ("track.irregularity.", _) if leaf.ends_with("_m") => "m",
        ("sensor.", "theta_v_noise_std_rad") => "rad",
        ("sensor.", "noise_hold_s") => "s",
        ("", "dt_s" | "command_period_s") => "s",
        ("actuator.bldc.", "v_dc") => "V",
        ("actuator.bldc.", "r_s") => "Ohm",
        ("actuator.bldc.", "l_s") => "H",
        ("actuator.bldc.", "b_f" | "speed_kp") => "N.m.s/rad",
        ("actuator.bldc.", "j_rot") => "kg.m2",
        ("actuator.bldc.", "k_t") => "N.m/A",
        ("actuator.bldc.", "n_r" | "speed_limit_fraction") => "1",
        ("actuator.bldc.", "l1" | "l2") => "m",
        ("actuator.bldc.", "speed_ki") => "N.m/rad",
        ("actuator.bldc.", "torque_limit_nm" | "continuous_torque_nm") => "N.m",
        ("actuator.bldc.", "gear_efficiency") => "1",
        ("actuator.bldc.", "gear_loss_speed_rad_s") => "rad/s",
        ("actuator.bldc.", "current_limit_a" | "hysteresis_a") => "A",
        ("actuator.bldc.", "position_gain") => "1/s",
        ("actuator.bldc.", "control_period_s" | "dt_switched_s" | "dt_averaged_s") => "s",
        ("actuator.bldc.", "stroke_deg") => "deg",
        ("actuator.dc_link.", "capacitance_f") => "F",
        ("actuator.dc_link.", "supply_resistance_ohm" | "chopper_resistance_ohm") => "Ohm",
        ("actuator.dc_link.", "chopper_on_v" | "chopper_off_v" | "overvoltage_trip_v") => "V",
        ("actuator.dc_link.", "aux_power_w") => "W",
        ("controller.", "rho") => "1",
        ("controller.", "period_s") => "s",
        ("controller.", "u_max_deg") => "deg",
        ("controller.pi.", "kp") => "1",
        ("controller.pi.", "ki") => "1/s",
        ("controller.mpc.", "du_max_deg" | "theta_v_max_deg") => "deg",
        ("controller.localisation.", "bias_m" | "noise_std_m") => "m",
        ("controller.localisation.", "hold_s") => "s",
        // The heights and offsets of `[[comfort.positions]]` (an array of tables).
        ("comfort.", "positions") => "m",
        // Weights and noise variances of states with different units.
        ("controller.lqg.", "q_diag" | "r_w") => "",
        ("controller.mpc.", "output_weight" | "rate_weight" | "slack_weight") => "",
        ("controller.kalman.", "w_n" | "v_n" | "disturbance_var") => "",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_names_are_defined_once() {
        for (i, (n, _)) in UNIT_DEFS.iter().enumerate() {
            assert!(UNIT_DEFS[..i].iter().all(|(m, _)| m != n), "{n} twice");
        }
        assert_eq!(param_unit("vehicle.m_v"), Some("kg"));
        assert_eq!(param_unit("track.transition_m"), Some("m"));
        assert_eq!(param_unit("controller.kalman.w_n[3]"), Some(""));
        assert_eq!(param_unit("vehicle.nothing"), None);
    }
}
