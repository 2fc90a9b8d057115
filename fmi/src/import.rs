//! Any FMI 2.0 / 3.0 co-simulation FMU as a tiltsim participant: the scenario's settings
//! (`[participants.<role>]`), their check against the FMU's description, and the participant
//! that steps the FMU exactly where the native model would step.

use std::collections::BTreeMap;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tiltsim_protocol::msg::{Message, ScalarType, ScalarValue, Scalars};
use tiltsim_protocol::{Participant, Role};

use crate::archive::{read_description, Unpacked};
use crate::binding::{IntType, Slave, Value};
use crate::description::{ModelDescription, VarDesc, VarKind};
use crate::layout::{io, Samples};

/// `[participants.<role>]`: an FMU in place of the native participant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FmuSettings {
    /// The FMU file (relative paths are relative to the scenario file).
    pub fmu: PathBuf,
    /// Request field (`theta_v_meas`, `x[3]`) → FMU input variable. Fields not listed go to
    /// the input of the same name where the FMU has one.
    #[serde(default)]
    pub inputs: BTreeMap<String, String>,
    /// Reply field → FMU output variable. Fields not listed come from the output of the same
    /// name where the FMU has one, and are 0 otherwise.
    #[serde(default)]
    pub outputs: BTreeMap<String, String>,
    /// FMU parameter → value, set before initialisation.
    #[serde(default)]
    pub parameters: BTreeMap<String, serde_json::Value>,
    /// Shared libraries loaded (globally, `RTLD_GLOBAL`) before the FMU's own, for FMUs that
    /// expect their host to provide a runtime: pythonfmu's FMUs need
    /// `preload = ["libpython3.11.so.1.0"]` outside a Python process.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub preload: Vec<String>,
}

/// How a sample scalar travels to or from an FMU variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Binding {
    /// Index of the scalar in the sample's flat list.
    pub scalar: usize,
    /// Scalar's name.
    pub field: String,
    /// The FMU variable's value reference.
    pub vr: u32,
    /// The FMU variable's name.
    pub var: String,
    /// Its integer type, `None` for a real.
    pub int: Option<IntType>,
}

/// The settings checked against the FMU: what is exchanged with which variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Inputs set before each step.
    pub inputs: Vec<Binding>,
    /// Outputs read after each step.
    pub outputs: Vec<Binding>,
    /// Reply fields no FMU output provides (recorded as 0).
    pub missing_outputs: Vec<String>,
    /// What the description lacks of what tiltsim relies on, said before the run (the run
    /// goes ahead).
    pub warnings: Vec<String>,
    /// Parameters: value reference, kind, value.
    pub params: Vec<(u32, VarKind, Value, String)>,
}

fn int_type(k: VarKind) -> Option<IntType> {
    match k {
        VarKind::Int32 => Some(IntType::I32),
        VarKind::UInt32 => Some(IntType::U32),
        VarKind::Int64 => Some(IntType::I64),
        VarKind::UInt64 => Some(IntType::U64),
        _ => None,
    }
}

fn fits(ty: ScalarType, v: &VarDesc) -> bool {
    match ty {
        ScalarType::F64 => v.kind == VarKind::Real,
        ScalarType::U32 => int_type(v.kind).is_some(),
    }
}

fn type_word(ty: ScalarType) -> &'static str {
    match ty {
        ScalarType::F64 => "a real (FMI 2 `Real`, FMI 3 `Float64`)",
        ScalarType::U32 => "an integer (FMI 2 `Integer`, FMI 3 `Int32`/`UInt32`/`Int64`/`UInt64`)",
    }
}

/// A setting the FMU cannot take: the key under `[participants.<role>]`, its value and what
/// is allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanError {
    /// Key (`fmu`, `outputs.delta_a_cmd`, `parameters.K`).
    pub field: String,
    /// Its value as written.
    pub value: String,
    /// What is allowed there, and why this is not.
    pub allowed: String,
}

impl core::fmt::Display for PlanError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "`{}` = {}: allowed {}",
            self.field, self.value, self.allowed
        )
    }
}

fn names_of(md: &ModelDescription, causality: &str) -> String {
    let v: Vec<&str> = md
        .vars
        .iter()
        .filter(|v| v.causality == causality)
        .map(|v| v.name.as_str())
        .collect();
    if v.is_empty() {
        format!("it has no {causality}s")
    } else {
        format!("its {causality}s: {}", v.join(", "))
    }
}

/// Checks `settings` for `role` with communication period `period_s` against the FMU's
/// description.
pub fn plan(
    role: Role,
    settings: &FmuSettings,
    md: &ModelDescription,
    period_s: f64,
) -> Result<Plan, PlanError> {
    check_stepping(role, settings, md, period_s)?;
    let (ins, outs) = io(role);
    let (inputs, _) = bind(role, md, "inputs", &ins, &settings.inputs, "input")?;
    let (outputs, missing_outputs) = bind(role, md, "outputs", &outs, &settings.outputs, "output")?;
    if outputs.is_empty() {
        let names: Vec<&str> = outs.iter().map(|s| s.name.as_str()).collect();
        return Err(PlanError {
            field: "outputs".into(),
            value: "{}".into(),
            allowed: format!(
                "a mapping of at least one of the {role}'s reply fields ({}) to an FMU output ({})",
                names.join(", "),
                names_of(md, "output")
            ),
        });
    }
    let params = parameters(settings, md)?;
    let warnings = warnings(role, md, period_s, &outputs);
    Ok(Plan {
        inputs,
        outputs,
        missing_outputs,
        warnings,
        params,
    })
}

/// What the description lacks of what tiltsim relies on but can do without: the outputs it
/// reads declared in `<ModelStructure>`, a `<DefaultExperiment>` saying which step the FMU was
/// made for, a step it declares it can take.
fn warnings(role: Role, md: &ModelDescription, period_s: f64, outputs: &[Binding]) -> Vec<String> {
    let mut w = Vec::new();
    match &md.structure_outputs {
        None => w.push(format!(
            "its modelDescription.xml has no <ModelStructure>: the outputs tiltsim reads ({}) are not declared as outputs with their dependencies",
            outputs.iter().map(|b| b.var.as_str()).collect::<Vec<_>>().join(", ")
        )),
        Some(listed) => {
            let absent: Vec<&str> = outputs
                .iter()
                .filter(|b| !listed.contains(&b.vr))
                .map(|b| b.var.as_str())
                .collect();
            if !absent.is_empty() {
                w.push(format!(
                    "its <ModelStructure> does not list {} among its <Outputs>, which FMI requires of every output",
                    absent.join(", ")
                ));
            }
        }
    }
    if !md.has_default_experiment {
        w.push(format!(
            "its modelDescription.xml has no <DefaultExperiment>: nothing says which step it was made for; tiltsim steps it every {period_s} s (the {role}'s period)"
        ));
    }
    if let Some(h) = md
        .default_step
        .filter(|h| *h > 0.0 && md.fixed_step.is_none())
    {
        let n = period_s / h;
        let whole = (n - n.round()).abs() <= 1e-9 * n.max(1.0) && n.round() >= 1.0;
        if !md.variable_step && !whole {
            w.push(format!(
                "it declares <DefaultExperiment stepSize=\"{h}\"> and canHandleVariableCommunicationStepSize=\"false\", and the {role}'s period {period_s} s is not a whole multiple of {h} s: it may refuse tiltsim's steps"
            ));
        }
    }
    w
}

/// Whether the FMU can play `role` stepping with period `period_s`: a co-simulation FMU whose
/// fixed internal step, if any, divides the period.
fn check_stepping(
    role: Role,
    settings: &FmuSettings,
    md: &ModelDescription,
    period_s: f64,
) -> Result<(), PlanError> {
    let fmu = || format!("{:?}", settings.fmu.display().to_string());
    if md.cs_identifier.is_none() {
        return Err(PlanError {
            field: "fmu".into(),
            value: fmu(),
            allowed: format!(
                "a co-simulation FMU ({})",
                if md.has_model_exchange {
                    "this one is model exchange only"
                } else {
                    "this one has no <CoSimulation> element"
                }
            ),
        });
    }
    if let Some(h) = md.fixed_step {
        let n = period_s / h;
        if h.is_nan() || h <= 0.0 || (n - n.round()).abs() > 1e-9 * n.max(1.0) || n.round() < 1.0 {
            return Err(PlanError {
                field: "fmu".into(),
                value: fmu(),
                allowed: format!(
                    "an FMU that can step with the {role}'s period {period_s} s (this one steps internally with a fixed {h} s, fixedInternalStepSize, and {period_s} s is not a whole multiple of it)"
                ),
            });
        }
    }
    Ok(())
}

/// Binds the `role`'s fields `list` (its request for causality `input`, its reply for
/// `output`) to the FMU's variables: by the mapping `map` (table `table` of the settings),
/// else by name. Returns the bindings and the fields no variable of the FMU takes (an error
/// for a field mapped explicitly).
fn bind(
    role: Role,
    md: &ModelDescription,
    table: &str,
    list: &[tiltsim_protocol::msg::ScalarInfo],
    map: &BTreeMap<String, String>,
    causality: &str,
) -> Result<(Vec<Binding>, Vec<String>), PlanError> {
    for (k, v) in map {
        if !list.iter().any(|s| &s.name == k) {
            let names: Vec<&str> = list.iter().map(|s| s.name.as_str()).collect();
            return Err(PlanError {
                field: format!("{table}.{k}"),
                value: format!("{v:?}"),
                allowed: format!(
                    "a {} field of the {role} as key: {}",
                    if causality == "input" {
                        "request"
                    } else {
                        "reply"
                    },
                    names.join(", ")
                ),
            });
        }
    }
    let mut found = Vec::new();
    let mut missing = Vec::new();
    for (i, s) in list.iter().enumerate() {
        let (var, explicit) = match map.get(&s.name) {
            Some(v) => (v.as_str(), true),
            None => (s.name.as_str(), false),
        };
        let err = |why: String| PlanError {
            field: format!("{table}.{}", s.name),
            value: format!("{var:?}"),
            allowed: why,
        };
        let Some(v) = md.var(var) else {
            if explicit {
                return Err(err(format!(
                    "a variable of the FMU (it has no `{var}`; {})",
                    names_of(md, causality)
                )));
            }
            missing.push(s.name.clone());
            continue;
        };
        let ok_causality = v.causality == causality;
        if !ok_causality || !fits(s.ty, v) || v.is_array {
            if !explicit {
                missing.push(s.name.clone());
                continue;
            }
            return Err(err(if !ok_causality {
                format!(
                    "an FMU variable of causality `{causality}` (`{var}` is `{}`; {})",
                    v.causality,
                    names_of(md, causality)
                )
            } else if v.is_array {
                format!("a scalar FMU variable (`{var}` is an array)")
            } else {
                format!("{} (`{var}` is a {})", type_word(s.ty), v.type_name)
            }));
        }
        found.push(Binding {
            scalar: i,
            field: s.name.clone(),
            vr: v.vr,
            var: var.to_string(),
            int: int_type(v.kind),
        });
    }
    Ok((found, missing))
}

/// The FMU parameters that `settings` set, each checked against its variable: causality
/// `parameter` (or `structuralParameter`) and a value of its type.
fn parameters(
    settings: &FmuSettings,
    md: &ModelDescription,
) -> Result<Vec<(u32, VarKind, Value, String)>, PlanError> {
    let mut params = Vec::new();
    for (name, value) in &settings.parameters {
        let err = |why: String| PlanError {
            field: format!("parameters.{name}"),
            value: value.to_string(),
            allowed: why,
        };
        let v = md.var(name).ok_or_else(|| {
            err(format!(
                "a parameter of the FMU as key (it has no `{name}`; {})",
                names_of(md, "parameter")
            ))
        })?;
        if !matches!(v.causality.as_str(), "parameter" | "structuralParameter") {
            return Err(err(format!(
                "a parameter of the FMU as key (`{name}` has causality `{}`)",
                v.causality
            )));
        }
        let val = match (v.kind, value) {
            (VarKind::Real, serde_json::Value::Number(n)) => n.as_f64().map(Value::Real),
            (k, serde_json::Value::Number(n)) if int_type(k).is_some() => {
                n.as_i64().map(Value::Int)
            }
            (VarKind::Boolean, serde_json::Value::Bool(b)) => Some(Value::Bool(*b)),
            (VarKind::Str, serde_json::Value::String(s)) => Some(Value::Str(s.clone())),
            _ => None,
        }
        .ok_or_else(|| err(format!("a value of the variable's type, {}", v.type_name)))?;
        params.push((v.vr, v.kind, val, name.clone()));
    }
    Ok(params)
}

/// What an FMU participant process receives: the settings with the FMU's path made absolute,
/// its role, its period and the run's base step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FmuInit {
    /// The role it plays.
    pub role: Role,
    /// Settings, `fmu` absolute.
    pub settings: FmuSettings,
    /// Communication period (s).
    pub period_s: f64,
    /// The run's base step (s): request `k` starts at `k · dt_s`.
    pub dt_s: f64,
}

/// Opens the FMU of `init` and checks it: every problem of the file or the mapping as one
/// message, before anything runs.
pub fn check(init: &FmuInit) -> Result<(ModelDescription, Plan), PlanError> {
    if !init.settings.fmu.exists() {
        return Err(PlanError {
            field: "fmu".into(),
            value: format!("{:?}", init.settings.fmu.display().to_string()),
            allowed: format!(
                "the path of an FMU file (there is none there; tiltsim's own {} is made with `tiltsim export-fmu {} SCENARIO --out FILE.fmu`)",
                init.role, init.role
            ),
        });
    }
    let md = read_description(&init.settings.fmu).map_err(|why| PlanError {
        field: "fmu".into(),
        value: format!("{:?}", init.settings.fmu.display().to_string()),
        allowed: format!("an FMI 2.0 or 3.0 co-simulation FMU ({why})"),
    })?;
    // The library for this platform is looked for without unpacking anything.
    let lib = crate::archive::library_entry(&init.settings.fmu, &md).map_err(|why| PlanError {
        field: "fmu".into(),
        value: format!("{:?}", init.settings.fmu.display().to_string()),
        allowed: format!("an FMU with a library for x86_64-linux ({why})"),
    });
    let p = plan(init.role, &init.settings, &md, init.period_s)?;
    lib?;
    Ok((md, p))
}

/// An FMU stepped as participant `S::ROLE`.
pub struct FmuParticipant<S: Samples> {
    slave: Option<Slave>,
    plan: Plan,
    init: FmuInit,
    initial: S::Out,
    reals_in: (Vec<u32>, Vec<f64>),
    reals_out: (Vec<u32>, Vec<f64>),
    name: String,
    failed: Option<String>,
    _preloaded: Vec<libloading::os::unix::Library>,
    // Declared last: the library is unloaded before its files are removed.
    _unpacked: Unpacked,
    _s: PhantomData<fn() -> S>,
}

impl<S: Samples> FmuParticipant<S> {
    /// Unpacks, loads, instantiates and initialises the FMU of `init`; reads its outputs at t₀.
    pub fn new(init: FmuInit) -> Result<Self, String> {
        let name = file_name(&init.settings.fmu);
        let label = name.clone();
        let err = |e: String| format!("FMU `{label}`: {e}");
        let unpacked = Unpacked::open(&init.settings.fmu).map_err(err)?;
        let preloaded = crate::binding::preload(&init.settings.preload).map_err(err)?;
        let plan = plan(
            S::ROLE,
            &init.settings,
            &unpacked.description,
            init.period_s,
        )
        .map_err(|e| err(e.to_string()))?;
        let mut slave = Slave::instantiate(
            unpacked.description.version,
            &unpacked.library,
            &name,
            &unpacked.description.token,
            &unpacked.resources(),
            0.0,
        )
        .map_err(err)?;
        for (vr, kind, v, pname) in &plan.params {
            let r = match v {
                Value::Real(x) => slave.set_reals(&[*vr], &[*x]),
                Value::Int(x) => slave.set_int(*vr, int_type(*kind).unwrap_or(IntType::I32), *x),
                Value::Bool(b) => slave.set_bool(*vr, *b),
                Value::Str(s) => slave.set_string(*vr, s),
            };
            r.map_err(|e| err(format!("setting parameter `{pname}`: {e}")))?;
        }
        slave.exit_initialization().map_err(err)?;
        let reals = |bs: &[Binding]| {
            let v: Vec<u32> = bs
                .iter()
                .filter(|b| b.int.is_none())
                .map(|b| b.vr)
                .collect();
            let n = v.len();
            (v, vec![0.0; n])
        };
        let mut p = FmuParticipant {
            reals_in: reals(&plan.inputs),
            reals_out: reals(&plan.outputs),
            slave: Some(slave),
            plan,
            init,
            initial: S::Out::default(),
            name,
            failed: None,
            _preloaded: preloaded,
            _unpacked: unpacked,
            _s: PhantomData,
        };
        p.initial = p.read_outputs().map_err(err)?;
        Ok(p)
    }

    fn slave(&mut self) -> &mut Slave {
        self.slave
            .as_mut()
            .expect("the FMU instance lives as long as the participant")
    }

    fn read_outputs(&mut self) -> Result<S::Out, String> {
        let mut out = S::Out::default();
        let (vrs, mut vals) = std::mem::take(&mut self.reals_out);
        let r = self.slave().get_reals(&vrs, &mut vals);
        self.reals_out = (vrs, vals);
        r?;
        let mut j = 0;
        for n in 0..self.plan.outputs.len() {
            let (scalar, vr, int) = {
                let b = &self.plan.outputs[n];
                (b.scalar, b.vr, b.int)
            };
            let v = match int {
                None => {
                    let x = self.reals_out.1[j];
                    j += 1;
                    ScalarValue::F64(x)
                }
                Some(t) => {
                    let x = self.slave().get_int(vr, t)?;
                    ScalarValue::U32(u32::try_from(x).map_err(|_| {
                        let b = &self.plan.outputs[n];
                        format!(
                            "output `{}` = {x} does not fit field `{}` (0 to {})",
                            b.var,
                            b.field,
                            u32::MAX
                        )
                    })?)
                }
            };
            out.set_scalar(scalar, v);
        }
        Ok(out)
    }

    fn step_fmu(&mut self, input: &S::In) -> Result<S::Out, String> {
        let mut j = 0;
        for n in 0..self.plan.inputs.len() {
            let (int, scalar, vr) = {
                let b = &self.plan.inputs[n];
                (b.int, b.scalar, b.vr)
            };
            match (int, input.scalar(scalar)) {
                (None, Some(ScalarValue::F64(x))) => {
                    self.reals_in.1[j] = x;
                    j += 1;
                }
                (Some(t), Some(ScalarValue::U32(x))) => self.slave().set_int(vr, t, x as i64)?,
                _ => {}
            }
        }
        let (vrs, vals) = std::mem::take(&mut self.reals_in);
        let r = self.slave().set_reals(&vrs, &vals);
        self.reals_in = (vrs, vals);
        r?;
        let t = input.header().step as f64 * self.init.dt_s;
        let h = self.init.period_s;
        self.slave().do_step(t, h)?;
        self.read_outputs()
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

impl<S: Samples> Participant for FmuParticipant<S>
where
    S::In: Scalars,
{
    type Input = S::In;
    type Output = S::Out;
    const ROLE: Role = S::ROLE;

    fn initial_output(&mut self) -> S::Out {
        self.initial
    }

    fn step(&mut self, input: &S::In) -> S::Out {
        match self.step_fmu(input) {
            Ok(o) => o,
            Err(e) => {
                // The transport ends the participant with this message; the orchestrator names
                // the participant and the step and ends the run with what was recorded.
                self.failed = Some(format!(
                    "FMU `{}` at t = {} s: {e}",
                    self.name,
                    input.header().step as f64 * self.init.dt_s
                ));
                S::Out::default()
            }
        }
    }

    fn failure(&mut self) -> Option<String> {
        self.failed.take()
    }
}

impl<S: Samples> Drop for FmuParticipant<S> {
    fn drop(&mut self) {
        // The instance is freed before its library's files are removed.
        self.slave.take();
    }
}
