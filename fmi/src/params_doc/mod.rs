//! What every FMU parameter is: the unit and a one-sentence description of every scenario
//! value a participant receives, by its dotted name (`vehicle.m_v`, `controller.kalman.v_n`).
//!
//! The descriptions follow the doc comments of the settings structs the values come from
//! (`VehicleParams`, `TrackParams`, `SensorParams`, `BldcParams`, `DcLinkParams`,
//! `ControllerSettings` and its sections, the participants' `…Init`), with the paper's symbols
//! (docs/model.md). The unit is `""` where a value has none: counts, switches, choices, and
//! weights of states with different units. Two physical values have no single unit and are
//! written without one: `controller.kalman.w_n`, intensities of track inputs of different
//! units, and `controller.kalman.v_n`, rad²·s for the LQG's continuous filter and rad² per
//! sample for the MPC's (the mode is a parameter too); their descriptions say so.

mod actuator;
mod controller;
mod vehicle;

/// A parameter: its dotted name without array indices, its unit (a name of
/// [`crate::units::UNIT_DEFS`], or `""`), and what it is.
type Row = (&'static str, &'static str, &'static str);

/// Every table of parameters.
const TABLES: [&[Row]; 3] = [vehicle::VEHICLE, actuator::ACTUATOR, controller::CONTROLLER];

/// The entries of the arrays whose entries mean different things: the LQI weights over
/// z = [y_v, θ_v, y_b, θ_b, ẏ_v, θ̇_v, ẏ_b, θ̇_b, θ_r, x_I] (eq 24) and the process noise
/// intensities over ω = [1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o] (eq 17, docs/model.md D12).
const ELEMENTS: &[(&str, &str)] = &[
    (
        "controller.lqg.q_diag[0]",
        "LQI weight Q_w on the carbody lateral displacement y_v (eq 24)",
    ),
    (
        "controller.lqg.q_diag[1]",
        "LQI weight Q_w on the carbody roll θ_v (eq 24)",
    ),
    (
        "controller.lqg.q_diag[2]",
        "LQI weight Q_w on the bogie lateral displacement y_b (eq 24)",
    ),
    (
        "controller.lqg.q_diag[3]",
        "LQI weight Q_w on the bogie roll θ_b (eq 24)",
    ),
    (
        "controller.lqg.q_diag[4]",
        "LQI weight Q_w on the carbody lateral velocity ẏ_v (eq 24)",
    ),
    (
        "controller.lqg.q_diag[5]",
        "LQI weight Q_w on the carbody roll rate θ̇_v (eq 24)",
    ),
    (
        "controller.lqg.q_diag[6]",
        "LQI weight Q_w on the bogie lateral velocity ẏ_b (eq 24)",
    ),
    (
        "controller.lqg.q_diag[7]",
        "LQI weight Q_w on the bogie roll rate θ̇_b (eq 24)",
    ),
    (
        "controller.lqg.q_diag[8]",
        "LQI weight Q_w on the airspring reservoir roll θ_r (eq 24)",
    ),
    (
        "controller.lqg.q_diag[9]",
        "LQI weight Q_w on the integrator x_I of r − ξ (eq 24)",
    ),
    (
        "controller.kalman.w_n[0]",
        "Kalman process noise intensity W_n on the track curvature 1/R (eq 17)",
    ),
    (
        "controller.kalman.w_n[1]",
        "Kalman process noise intensity W_n on the cant θ_o (eq 17)",
    ),
    (
        "controller.kalman.w_n[2]",
        "Kalman process noise intensity W_n on θ̇_o (eq 17): no effect, Γ has no θ̇_o column",
    ),
    (
        "controller.kalman.w_n[3]",
        "Kalman process noise intensity W_n on the cant acceleration θ̈_o (eq 17)",
    ),
    (
        "controller.kalman.w_n[4]",
        "Kalman process noise intensity W_n on the lateral track alignment y_o (eq 17)",
    ),
    (
        "controller.kalman.w_n[5]",
        "Kalman process noise intensity W_n on the lateral alignment rate ẏ_o (eq 17)",
    ),
];

/// `name` without its array indices: `controller.kalman.w_n[3]` → `controller.kalman.w_n`,
/// `comfort.positions[1].height_m` → `comfort.positions.height_m`.
fn without_indices(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    let mut depth = 0usize;
    for c in name.chars() {
        match c {
            '[' => depth += 1,
            ']' => depth = depth.saturating_sub(1),
            c if depth == 0 => out.push(c),
            _ => {}
        }
    }
    out
}

/// The row of parameter `name`.
fn row(name: &str) -> Option<&'static Row> {
    let base = without_indices(name);
    TABLES.iter().flat_map(|t| t.iter()).find(|r| r.0 == base)
}

/// Unit of the parameter `name` (with or without its array index): `Some("")` for a value
/// without one, `None` for a name the tables do not know.
pub(crate) fn unit(name: &str) -> Option<&'static str> {
    row(name).map(|r| r.1)
}

/// What the parameter `name` is, in one short sentence with the paper's symbol where it has
/// one (`"Half carbody mass m_v"`); `None` for a name the tables do not know.
pub fn param_description(name: &str) -> Option<&'static str> {
    if let Some((_, d)) = ELEMENTS.iter().find(|(n, _)| *n == name) {
        return Some(d);
    }
    row(name).map(|r| r.2)
}

#[cfg(test)]
mod tests;
