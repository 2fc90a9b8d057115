//! Units of the FMU variables: the unit of every scenario value a participant's FMU exposes as a
//! parameter (from [`crate::params_doc`]), and the SI definition of every unit name used (FMI's
//! `<UnitDefinitions>`).

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
    ("N", (1, 1, -2, 0, 0, 1.0)),
    ("km/h", (0, 1, -1, 0, 0, 1.0 / 3.6)),
    ("rad", (0, 0, 0, 0, 1, 1.0)),
    ("rad2", (0, 0, 0, 0, 2, 1.0)),
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

/// Unit of the parameter `name` (a scenario value as the participant receives it, with or
/// without its array index): `Some("")` for values that have no unit (counts, switches,
/// choices, weights of states with different units; see [`crate::params_doc`]), `None` for a
/// name the table does not know (a test keeps the table complete).
pub fn param_unit(name: &str) -> Option<&'static str> {
    crate::params_doc::unit(name)
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
        assert_eq!(
            param_unit("controller.kalman.disturbance_var"),
            Some("rad2")
        );
        assert_eq!(param_unit("comfort.positions[1].height_m"), Some("m"));
        assert_eq!(param_unit("controller.mode"), Some(""));
        assert_eq!(param_unit("vehicle.nothing"), None);
    }
}
