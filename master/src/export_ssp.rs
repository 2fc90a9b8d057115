//! A scenario as an SSP 1.0 system for other co-simulation masters: its three participants as
//! FMI 2.0 FMUs (`resources/ROLE.fmu`, each stepping at any whole multiple of the base tick)
//! and `SystemStructure.ssd`, which connects them as the lock-step master does ([`WIRING`])
//! and gives every FMU the scenario's values as its parameter set and the base tick as its
//! step. The directory zipped is an `.ssp` package.
//!
//! A Jacobi master (libcosim's fixed-step algorithm, FMPy's container) running the system at
//! the base tick computes what `tiltsim run --master jacobi` computes: every participant is
//! given the others' outputs of the tick before, and the controller computes on its own ticks
//! and holds its outputs between (tests/outside/fmpy/fmi.rs compares them bit for bit).

use std::path::{Path, PathBuf};

use cosim::msg::ScalarType;
use cosim::Role;
use tiltsim_fmi::description::FmiVersion;
use tiltsim_fmi::layout::Stepping;
use tiltsim_fmi::ssd::{Component, Connection, Connector, ConnectorType, System};
use tiltsim_scenario::links::{LinkEffects, LINK_NAMES};
use tiltsim_scenario::scenario::Scenario;

use crate::export_fmu::{export, ExportError, Exported, FmuOptions};

/// The file name of the system structure in the output directory.
pub const SSD_FILE: &str = "SystemStructure.ssd";

/// One connection of the system: an output of one participant to an input of another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wire {
    /// The participant whose output it is.
    pub from: Role,
    /// The output (a reply field, as the FMU names it).
    pub output: &'static str,
    /// The participant whose input it is.
    pub to: Role,
    /// The input (a request field).
    pub input: &'static str,
}

const fn wire(from: Role, output: &'static str, to: Role, input: &'static str) -> Wire {
    Wire {
        from,
        output,
        to,
        input,
    }
}

/// Every input of every participant and the output that feeds it: the requests the lock-step
/// master composes each tick (`engine::algorithm`), without link effects.
pub const WIRING: [Wire; 6] = [
    // The plant: the achieved bar angle (link `bar_angle`).
    wire(Role::Actuator, "delta_a", Role::Plant, "delta_a"),
    // The actuator: the command (link `actuator_command`) and the twist (link `bar_twist`).
    wire(
        Role::Controller,
        "delta_a_cmd",
        Role::Actuator,
        "delta_a_cmd",
    ),
    wire(Role::Plant, "psi", Role::Actuator, "psi"),
    // The controller: the plant's time and position, and the measurement (link `measurement`).
    wire(Role::Plant, "t", Role::Controller, "t"),
    wire(Role::Plant, "s", Role::Controller, "s"),
    wire(
        Role::Plant,
        "theta_v_meas",
        Role::Controller,
        "theta_v_meas",
    ),
];

/// What was written.
#[derive(Debug, Clone)]
pub struct ExportedSsp {
    /// `DIR/SystemStructure.ssd`.
    pub ssd: PathBuf,
    /// The FMUs, in [`Role::ALL`] order.
    pub fmus: Vec<PathBuf>,
    /// Number of connections.
    pub connections: usize,
    /// The base tick every FMU is stepped with (s).
    pub step_s: f64,
    /// The scenario's duration (s), the default experiment's stop time.
    pub stop_s: f64,
}

/// The first setting of `s` an SSP system cannot carry: a link effect, a scheduled fault or an
/// FMU participant; as (field, value, what is allowed).
fn unsupported(s: &Scenario) -> Option<(String, String, String)> {
    for (name, fx) in LINK_NAMES.iter().zip(s.links.all()) {
        if fx.is_identity() {
            continue;
        }
        let (now, none) = (
            serde_json::to_value(fx).unwrap_or_default(),
            serde_json::to_value(LinkEffects::default()).unwrap_or_default(),
        );
        let key = now
            .as_object()
            .and_then(|m| m.iter().find(|(k, v)| none.get(k.as_str()) != Some(*v)))
            .map_or_else(
                || ("delay_ticks".to_string(), String::new()),
                |(k, v)| (k.clone(), v.to_string()),
            );
        return Some((
            format!("links.{name}.{}", key.0),
            key.1,
            "none: an SSP system connects outputs to inputs directly, without tiltsim's link effects (run them with `tiltsim run`)".into(),
        ));
    }
    if let Some(f) = s.faults.schedule.first() {
        return Some((
            "faults.schedule".into(),
            format!("{} of the {} at {} s", f.action, f.participant, f.at_s),
            "none: process faults are tiltsim's own, an SSP system has none".into(),
        ));
    }
    for role in Role::ALL {
        if let Some(p) = s.participants.get(role) {
            return Some((
                format!("participants.{role}.fmu"),
                format!("{:?}", p.fmu.display().to_string()),
                "none: export-ssp writes tiltsim's own participants; put that FMU in the SSP system by hand".into(),
            ));
        }
    }
    None
}

/// Writes scenario `s` as an SSP system into `dir`: `dir/SystemStructure.ssd` and
/// `dir/resources/ROLE.fmu` (FMI 2.0), with the FMU library `library` (see
/// [`crate::export_fmu::library_candidates`]).
pub fn export_ssp(
    s: &Scenario,
    dir: &Path,
    library: Option<&Path>,
) -> Result<ExportedSsp, ExportError> {
    if let Some((field, value, allowed)) = unsupported(s) {
        return Err(ExportError::NotInSsp {
            field,
            value,
            allowed,
        });
    }
    let res = dir.join("resources");
    std::fs::create_dir_all(&res).map_err(|source| ExportError::Io {
        path: res.clone(),
        source,
    })?;
    let options = FmuOptions {
        version: FmiVersion::V2,
        stepping: Stepping::Tick,
        library,
    };
    let mut components = Vec::new();
    let mut fmus = Vec::new();
    for role in Role::ALL {
        let file = format!("{}.fmu", role.name());
        let path = res.join(&file);
        let e = export(s, role, &path, &options)?;
        components.push(component(s, role, &e, &file));
        fmus.push(path);
    }
    let connections: Vec<Connection> = WIRING
        .iter()
        .map(|w| Connection {
            from: (w.from.name().to_string(), w.output.to_string()),
            to: (w.to.name().to_string(), w.input.to_string()),
        })
        .collect();
    let system = System {
        name: s.name.clone(),
        description: format!(
            "tiltsim scenario `{}`: {} (plant, actuator and controller as FMI 2.0 FMUs; a Jacobi master at {} s computes what `tiltsim run --master jacobi` computes)",
            s.name, s.description, s.run.dt_s
        ),
        base_step_s: s.run.dt_s,
        stop_s: s.duration(),
        components,
        connections,
    };
    let text =
        tiltsim_fmi::ssd::write_ssd(&system).map_err(|e| ExportError::Layout(e.to_string()))?;
    let ssd = dir.join(SSD_FILE);
    tiltsim_rundir::files::write_atomic(&ssd, text).map_err(|source| ExportError::Io {
        path: ssd.clone(),
        source,
    })?;
    Ok(ExportedSsp {
        ssd,
        fmus,
        connections: system.connections.len(),
        step_s: s.run.dt_s,
        stop_s: s.duration(),
    })
}

/// The SSD's component of `role`, exported as `e` to `resources/{file}`: its connectors
/// (inputs, then outputs) and parameters.
fn component(s: &Scenario, role: Role, e: &Exported, file: &str) -> Component {
    let kind = |t: ScalarType| match t {
        ScalarType::F64 => ConnectorType::Real,
        ScalarType::U32 => ConnectorType::Integer,
    };
    let connector = |output: bool| {
        move |v: &cosim::msg::ScalarInfo| Connector {
            name: v.name.clone(),
            output,
            ty: kind(v.ty),
        }
    };
    let mut connectors: Vec<Connector> = e.layout.inputs.iter().map(connector(false)).collect();
    connectors.extend(e.layout.outputs.iter().map(connector(true)));
    Component {
        name: role.name().to_string(),
        source: format!("resources/{file}"),
        connectors,
        parameters: e
            .layout
            .params
            .iter()
            .map(|p| (p.name.clone(), p.value.clone()))
            .collect(),
        step_s: s.run.dt_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_input_of_every_participant_is_fed_by_one_output_of_another() {
        for role in Role::ALL {
            let (inputs, _) = tiltsim_fmi::layout::io(role);
            for i in &inputs {
                let feeds: Vec<_> = WIRING
                    .iter()
                    .filter(|w| w.to == role && w.input == i.name)
                    .collect();
                assert_eq!(feeds.len(), 1, "{role}.{}", i.name);
                let w = feeds[0];
                assert_ne!(w.from, role, "{role}.{} is fed by itself", i.name);
                let (_, outputs) = tiltsim_fmi::layout::io(w.from);
                let out = outputs.iter().find(|o| o.name == w.output);
                assert!(out.is_some(), "{}.{} is not an output", w.from, w.output);
                assert_eq!(out.map(|o| o.ty), Some(i.ty), "{role}.{}", i.name);
            }
            assert_eq!(
                WIRING.iter().filter(|w| w.to == role).count(),
                inputs.len(),
                "{role}"
            );
        }
    }

    #[test]
    fn settings_an_ssp_system_cannot_carry_are_named() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/paper-mpc.toml");
        let base = Scenario::load(&path).unwrap();
        assert_eq!(unsupported(&base), None);
        let mut s = base.clone();
        s.links.actuator_command.delay_ticks = 49;
        let (field, value, allowed) = unsupported(&s).unwrap();
        assert_eq!(field, "links.actuator_command.delay_ticks");
        assert_eq!(value, "49");
        assert!(allowed.contains("link effects"), "{allowed}");
        let mut s = base.clone();
        s.links.measurement.noise_std = 0.01;
        assert_eq!(unsupported(&s).unwrap().0, "links.measurement.noise_std");
        // A fault is named as the scenario file writes its action.
        let mut s = base.clone();
        s.faults
            .schedule
            .push(tiltsim_scenario::faults::ScheduledFault {
                participant: Role::Controller,
                action: tiltsim_scenario::faults::FaultAction::Kill,
                at_s: 8.0,
                stall_s: 0.0,
            });
        let (field, value, _) = unsupported(&s).unwrap();
        assert_eq!(
            (field.as_str(), value.as_str()),
            ("faults.schedule", "kill of the controller at 8 s")
        );
    }
}
