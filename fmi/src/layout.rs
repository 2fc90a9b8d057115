//! The variables of a participant's FMU: its request sample's scalars as inputs, its reply's as
//! outputs, and the scenario values it is built from as parameters, each with a value
//! reference. The exporter writes `modelDescription.xml` from this layout and the FMU's library
//! rebuilds the same layout from the same settings, so the two always agree.

use serde_json::Value;
use tiltsim_protocol::msg::{
    FromActuator, FromController, FromPlant, ScalarInfo, ScalarType, Scalars,
};
use tiltsim_protocol::msg::{ToActuator, ToController, ToPlant};
use tiltsim_protocol::Role;

use crate::params_doc::param_description;
use crate::units::param_unit;

/// The request and reply sample types of a role.
pub trait Samples: Send + 'static {
    /// Request.
    type In: Scalars;
    /// Reply.
    type Out: Scalars;
    /// The role.
    const ROLE: Role;
}

/// Plant samples.
pub struct PlantIo;
impl Samples for PlantIo {
    type In = ToPlant;
    type Out = FromPlant;
    const ROLE: Role = Role::Plant;
}
/// Actuator samples.
pub struct ActuatorIo;
impl Samples for ActuatorIo {
    type In = ToActuator;
    type Out = FromActuator;
    const ROLE: Role = Role::Actuator;
}
/// Controller samples.
pub struct ControllerIo;
impl Samples for ControllerIo {
    type In = ToController;
    type Out = FromController;
    const ROLE: Role = Role::Controller;
}

/// The request and reply scalars of `role`.
pub fn io(role: Role) -> (Vec<ScalarInfo>, Vec<ScalarInfo>) {
    match role {
        Role::Plant => (ToPlant::scalar_info(), FromPlant::scalar_info()),
        Role::Actuator => (ToActuator::scalar_info(), FromActuator::scalar_info()),
        Role::Controller => (ToController::scalar_info(), FromController::scalar_info()),
    }
}

/// One step of the path from the settings' root to a value.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    /// An object member.
    Key(String),
    /// An array element.
    Index(usize),
}

/// The value of a parameter.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// A real number.
    F64(f64),
    /// A non-negative integer.
    U64(u64),
    /// A negative integer.
    I64(i64),
    /// A switch.
    Bool(bool),
    /// A choice (`mode = "mpc"`) or other text.
    Str(String),
}

impl ParamValue {
    /// The value as settings JSON.
    pub fn to_json(&self) -> Value {
        match self {
            ParamValue::F64(v) => {
                serde_json::Number::from_f64(*v).map_or(Value::Null, Value::Number)
            }
            ParamValue::U64(v) => Value::from(*v),
            ParamValue::I64(v) => Value::from(*v),
            ParamValue::Bool(v) => Value::Bool(*v),
            ParamValue::Str(v) => Value::String(v.clone()),
        }
    }
    /// FMI 3 type name of the variable.
    pub fn fmi3_type(&self) -> &'static str {
        match self {
            ParamValue::F64(_) => "Float64",
            ParamValue::U64(_) => "UInt64",
            ParamValue::I64(_) => "Int64",
            ParamValue::Bool(_) => "Boolean",
            ParamValue::Str(_) => "String",
        }
    }
}

/// A scenario value the participant is built from, exposed as an FMU parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    /// Dotted name (`vehicle.m_v`, `controller.kalman.w_n[2]`).
    pub name: String,
    /// Where it sits in the settings.
    pub path: Vec<Seg>,
    /// Its value in the scenario.
    pub value: ParamValue,
    /// Unit (`""` where none; only reals have one).
    pub unit: &'static str,
    /// What it is ([`param_description`]; `""` for a name the table does not know).
    pub description: &'static str,
}

/// What a value reference points at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// The independent variable, time.
    Time,
    /// Request scalar `i`.
    Input(usize),
    /// Reply scalar `i`.
    Output(usize),
    /// Parameter `i`.
    Param(usize),
}

/// Every variable of a role's FMU.
#[derive(Debug, Clone)]
pub struct Layout {
    /// The role.
    pub role: Role,
    /// Request scalars (FMU inputs), value references `1..`.
    pub inputs: Vec<ScalarInfo>,
    /// Reply scalars (FMU outputs), after the inputs.
    pub outputs: Vec<ScalarInfo>,
    /// Parameters, after the outputs.
    pub params: Vec<Param>,
}

/// Why settings could not be laid out.
#[derive(Debug, thiserror::Error)]
pub enum LayoutError {
    /// A real value whose name has no unit in [`crate::units`].
    #[error("parameter `{0}` has no unit in tiltsim's table")]
    NoUnit(String),
}

impl Layout {
    /// The layout of `role`'s FMU built from `settings` (the participant's settings JSON).
    pub fn new(role: Role, settings: &Value) -> Result<Layout, LayoutError> {
        let (inputs, outputs) = io(role);
        let mut params = Vec::new();
        flatten(settings, &mut Vec::new(), &mut String::new(), &mut params)?;
        Ok(Layout {
            role,
            inputs,
            outputs,
            params,
        })
    }

    /// What value reference `vr` points at.
    pub fn slot(&self, vr: u32) -> Option<Slot> {
        let (ni, no, np) = (self.inputs.len(), self.outputs.len(), self.params.len());
        let v = vr as usize;
        match v {
            0 => Some(Slot::Time),
            _ if v <= ni => Some(Slot::Input(v - 1)),
            _ if v <= ni + no => Some(Slot::Output(v - 1 - ni)),
            _ if v <= ni + no + np => Some(Slot::Param(v - 1 - ni - no)),
            _ => None,
        }
    }

    /// Value reference of input `i`.
    pub fn input_vr(&self, i: usize) -> u32 {
        (1 + i) as u32
    }
    /// Value reference of output `i`.
    pub fn output_vr(&self, i: usize) -> u32 {
        (1 + self.inputs.len() + i) as u32
    }
    /// Value reference of parameter `i`.
    pub fn param_vr(&self, i: usize) -> u32 {
        (1 + self.inputs.len() + self.outputs.len() + i) as u32
    }

    /// The inputs (indices into [`Layout::inputs`]) that output `i` depends on directly, at one
    /// communication point (FMI's `dependencies` of the output). None, for every role: an FMU's
    /// outputs are its participant's latest reply, which only a step replaces
    /// (`Participant::step` takes the inputs held over the step and answers with the outputs at
    /// its end, functions of the state), so an input set at a communication point changes no
    /// output before the next step. `tiltsim-fmu`'s tests observe this on every role's library.
    pub fn direct_inputs(&self, i: usize) -> &'static [usize] {
        debug_assert!(i < self.outputs.len(), "output {i}");
        &[]
    }

    /// The settings with every parameter set to `values` (in [`Layout::params`] order).
    pub fn settings_with(&self, base: &Value, values: &[ParamValue]) -> Value {
        let mut v = base.clone();
        for (p, x) in self.params.iter().zip(values) {
            if let Some(slot) = locate(&mut v, &p.path) {
                *slot = x.to_json();
            }
        }
        v
    }
}

/// The communication period of `role` in its settings: the plant's and actuator's `dt_s`, the
/// controller's `controller.period_s`.
pub fn period_of(role: Role, settings: &Value) -> Option<f64> {
    match role {
        Role::Plant | Role::Actuator => settings.get("dt_s")?.as_f64(),
        Role::Controller => settings.get("controller")?.get("period_s")?.as_f64(),
    }
}

/// The scalar type as FMI 3 names it.
pub fn fmi3_scalar_type(t: ScalarType) -> &'static str {
    match t {
        ScalarType::F64 => "Float64",
        ScalarType::U32 => "UInt32",
    }
}

fn locate<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    let mut cur = v;
    for s in path {
        cur = match s {
            Seg::Key(k) => cur.get_mut(k.as_str())?,
            Seg::Index(i) => cur.get_mut(*i)?,
        };
    }
    Some(cur)
}

fn flatten(
    v: &Value,
    path: &mut Vec<Seg>,
    name: &mut String,
    out: &mut Vec<Param>,
) -> Result<(), LayoutError> {
    let value = match v {
        Value::Object(m) => {
            for (k, x) in m {
                let len = name.len();
                if !name.is_empty() {
                    name.push('.');
                }
                name.push_str(k);
                path.push(Seg::Key(k.clone()));
                flatten(x, path, name, out)?;
                path.pop();
                name.truncate(len);
            }
            return Ok(());
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let len = name.len();
                name.push_str(&format!("[{i}]"));
                path.push(Seg::Index(i));
                flatten(x, path, name, out)?;
                path.pop();
                name.truncate(len);
            }
            return Ok(());
        }
        Value::Null => return Ok(()),
        Value::Bool(b) => ParamValue::Bool(*b),
        Value::String(s) => ParamValue::Str(s.clone()),
        Value::Number(n) => {
            if let Some(u) = n.as_u64() {
                ParamValue::U64(u)
            } else if let Some(i) = n.as_i64() {
                ParamValue::I64(i)
            } else {
                ParamValue::F64(n.as_f64().unwrap_or(f64::NAN))
            }
        }
    };
    let unit = match value {
        ParamValue::F64(_) => param_unit(name).ok_or_else(|| LayoutError::NoUnit(name.clone()))?,
        _ => "",
    };
    out.push(Param {
        name: name.clone(),
        path: path.clone(),
        value,
        unit,
        description: param_description(name).unwrap_or(""),
    });
    Ok(())
}

/// Which communication steps an exported FMU takes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stepping {
    /// Any whole multiple of the base tick, down to one tick: the participant computes on its
    /// own period (the ticks the lock-step master steps it on) and holds its outputs between
    /// (`canHandleVariableCommunicationStepSize = true`, `fixedInternalStepSize` = the tick).
    #[default]
    Tick,
    /// Whole multiples of the participant's own period only, from a multiple of it
    /// (`canHandleVariableCommunicationStepSize = false`, `fixedInternalStepSize` = the period).
    Period,
}

impl Stepping {
    /// The name on the command line and in `resources/tiltsim.json`.
    pub fn name(self) -> &'static str {
        match self {
            Stepping::Tick => "tick",
            Stepping::Period => "period",
        }
    }
}

/// `resources/tiltsim.json` of an exported FMU: what the library builds its participant from.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FmuConfig {
    /// The role.
    pub role: Role,
    /// The run's base step (s): a communication point `t` is tick `round(t / dt_s)`.
    pub dt_s: f64,
    /// Which communication steps the FMU takes.
    #[serde(default)]
    pub stepping: Stepping,
    /// The participant's settings, exactly as its process receives them.
    pub settings: Value,
}

/// The period of `role` in whole base ticks of `dt_s` (at least 1), as the lock-step master
/// counts it; `None` when the settings give no period or it is not a whole number of ticks.
pub fn period_ticks(role: Role, settings: &Value, dt_s: f64) -> Option<u64> {
    let p = period_of(role, settings)?;
    let n = (p / dt_s).round();
    (n >= 1.0 && (p - n * dt_s).abs() <= 1e-9 * p).then_some(n as u64)
}

/// The instantiation token of an FMU whose `resources/tiltsim.json` holds `config`: a GUID
/// form of its SHA-256, so a library is never run with another FMU's description.
pub fn token(config: &[u8]) -> String {
    use sha2::Digest;
    let d = sha2::Sha256::digest(config);
    let h: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &h[0..8],
        &h[8..12],
        &h[12..16],
        &h[16..20],
        &h[20..32]
    )
}
