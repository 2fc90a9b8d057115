//! The shared library inside tiltsim's FMUs: the FMI 3.0 co-simulation interface (the
//! functions of the standard's `fmi3Functions.h`) over the participants the processes run.
//!
//! An instance reads `resources/tiltsim.json` (role, base step, settings), lays out its
//! variables with [`tiltsim_fmi::Layout`] exactly as the exporter did, takes parameter values
//! until initialisation ends, then builds its participant with [`model::build`]. Time is counted
//! in whole base ticks ([`grid`]): a `fmi3DoStep` of any whole multiple of the tick (or, when
//! exported with `--steps period`, of the participant's period) steps the participant on the
//! ticks of its period within it, as the lock-step master does, and its outputs hold between.
//! [`fmi2`] is the FMI 2.0 interface of the same instances; `values` reads and writes the
//! variables' values through the layout.
//! Model exchange and scheduled
//! execution are not offered: their functions exist (the standard asks every FMU to export
//! them) and return `fmi3Error`.

//!
//! # Safety
//!
//! The exported functions are called by an FMI importer under the standard's contract: an
//! instance pointer from `fmi3InstantiateCoSimulation` not yet freed, arrays of the lengths
//! given, NUL-terminated strings. That contract is their safety section, stated once here.

#![allow(clippy::missing_safety_doc)]

pub mod fmi2;
pub mod grid;
pub mod model;
#[cfg(test)]
mod tests;
mod values;

use std::ffi::{c_char, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use cosim::msg::{ScalarType, ScalarValue};
use serde_json::Value;
use tiltsim_fmi::layout::{period_ticks, token, FmuConfig, Layout, ParamValue, Slot, Stepping};

use model::Model;
pub(crate) use values::{get_one, set_one, FmiValue};

pub(crate) type Status = i32;
pub(crate) const OK: Status = 0;
pub(crate) const ERROR: Status = 3;
const FATAL: Status = 4;
pub(crate) type Vr = u32;
type LogFn = unsafe extern "C" fn(*mut c_void, Status, *const c_char, *const c_char);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum State {
    Instantiated,
    Initialization,
    Step,
    Terminated,
    Failed,
}

/// One FMU instance.
pub struct Instance {
    pub(crate) name: String,
    pub(crate) layout: Layout,
    pub(crate) base: Value,
    pub(crate) params: Vec<ParamValue>,
    pub(crate) inputs: Vec<ScalarValue>,
    /// A parameter was set after the model was built.
    pub(crate) params_changed: bool,
    /// The period of the built model in base ticks: it computes on the multiples of it.
    pub(crate) period: u64,
    pub(crate) model: Option<Box<dyn Model>>,
    pub(crate) state: State,
    /// The base tick the instance has reached.
    pub(crate) tick: u64,
    pub(crate) dt_s: f64,
    /// Which communication steps it takes.
    pub(crate) stepping: Stepping,
    pub(crate) log: Option<LogFn>,
    /// The FMI 2.0 logger, for instances made by `fmi2Instantiate`.
    pub(crate) log2: Option<fmi2::Logger>,
    pub(crate) env: *mut c_void,
    pub(crate) strings: Vec<CString>,
}

impl Instance {
    fn say(&self, status: Status, msg: &str) {
        if let Some(f) = self.log2 {
            fmi2::say(f, self.env, &self.name, status, msg);
        }
        if let Some(f) = self.log {
            let cat = CString::new(if status >= ERROR {
                "logStatusError"
            } else {
                "logEvents"
            })
            .unwrap_or_default();
            let m = CString::new(format!("{}: {msg}", self.name).replace('\0', " "))
                .unwrap_or_default();
            // SAFETY: the callback the environment gave at instantiation.
            unsafe { f(self.env, status, cat.as_ptr(), m.as_ptr()) };
        }
    }

    pub(crate) fn fail(&mut self, msg: &str) -> Status {
        self.say(ERROR, msg);
        ERROR
    }

    fn settings(&self) -> Value {
        self.layout.settings_with(&self.base, &self.params)
    }

    /// The model for the current parameters, built (again) if one was set since.
    pub(crate) fn model(&mut self) -> Result<&mut Box<dyn Model>, String> {
        if self.model.is_none() || self.params_changed {
            let settings = self.settings();
            let role = self.layout.role;
            self.period = period_ticks(role, &settings, self.dt_s).ok_or_else(|| {
                format!(
                    "the {role}'s period ({}) is not a whole multiple of the base tick {} s",
                    match role {
                        cosim::Role::Controller => "controller.period_s",
                        _ => "dt_s",
                    },
                    self.dt_s
                )
            })?;
            self.model = Some(model::build(role, &settings)?);
            self.params_changed = false;
        }
        Ok(self.model.as_mut().expect("built above"))
    }

    fn output(&mut self, i: usize) -> Result<ScalarValue, String> {
        if self.state == State::Instantiated {
            return Err("outputs can be read from initialisation mode on".into());
        }
        self.model()?
            .output(i)
            .ok_or_else(|| format!("no output {i}"))
    }

    /// The time of the tick reached (s).
    pub(crate) fn time(&self) -> f64 {
        cosim::time::tick_time(self.tick, self.dt_s)
    }

    /// A communication step from `t` of `h` s: whole base ticks ([`grid::span`]; a step that
    /// ends within the tolerance of the tick reached takes no tick). The participant computes
    /// on the ticks of its period within the step, each time with the inputs as set, and its
    /// outputs hold between.
    pub(crate) fn do_step(&mut self, t: f64, h: f64) -> Result<(), String> {
        if self.state != State::Step {
            return Err(format!("fmi3DoStep called in {:?} mode", self.state));
        }
        self.model()?;
        let span = grid::span(t, h, self.tick, self.dt_s, self.period, self.stepping)?;
        let mut due = span.due(self.period).peekable();
        if due.peek().is_some() {
            let m = self.model.as_mut().expect("built above");
            for (i, v) in self.inputs.iter().enumerate() {
                m.set_input(i, *v);
            }
            for k in due {
                m.step(k)?;
            }
        }
        self.tick = span.to;
        Ok(())
    }
}

pub(crate) unsafe fn cstr<'a>(p: *const c_char) -> Option<&'a str> {
    if p.is_null() {
        None
    } else {
        // SAFETY: the caller passes a NUL-terminated string.
        unsafe { CStr::from_ptr(p) }.to_str().ok()
    }
}

pub(crate) fn instantiate(
    name: &str,
    token_given: &str,
    resources: &str,
    log: Option<LogFn>,
    env: *mut c_void,
) -> Result<Instance, String> {
    let file = std::path::Path::new(resources).join("tiltsim.json");
    let bytes = std::fs::read(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    let want = token(&bytes);
    if token_given != want {
        return Err(format!(
            "instantiationToken `{token_given}` is not this FMU's ({want})"
        ));
    }
    let cfg: FmuConfig =
        serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", file.display()))?;
    let layout = Layout::new(cfg.role, &cfg.settings).map_err(|e| e.to_string())?;
    let inputs = layout
        .inputs
        .iter()
        .map(|s| match s.ty {
            ScalarType::F64 => ScalarValue::F64(0.0),
            ScalarType::U32 => ScalarValue::U32(0),
        })
        .collect();
    Ok(Instance {
        name: name.to_string(),
        params: layout.params.iter().map(|p| p.value.clone()).collect(),
        inputs,
        layout,
        base: cfg.settings,
        params_changed: false,
        period: 1,
        model: None,
        state: State::Instantiated,
        tick: 0,
        dt_s: cfg.dt_s,
        stepping: cfg.stepping,
        log,
        log2: None,
        env,
        strings: Vec::new(),
    })
}

/// Runs `f` on the instance, turning a panic into `fmi3Fatal` (a panic must not cross the C
/// boundary) and a failed instance into `fmi3Error`.
pub(crate) unsafe fn with(inst: *mut c_void, f: impl FnOnce(&mut Instance) -> Status) -> Status {
    if inst.is_null() {
        return ERROR;
    }
    // SAFETY: the pointer came from fmi3InstantiateCoSimulation and is not freed yet.
    let i = unsafe { &mut *(inst as *mut Instance) };
    match catch_unwind(AssertUnwindSafe(|| f(i))) {
        Ok(s) => s,
        Err(e) => {
            let why = e
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| e.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into());
            i.state = State::Failed;
            i.say(FATAL, &format!("internal error: {why}"));
            FATAL
        }
    }
}

/// `fmi3GetVersion`.
#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

/// `fmi3SetDebugLogging`: messages always go to the callback.
#[no_mangle]
pub extern "C" fn fmi3SetDebugLogging(
    _: *mut c_void,
    _: bool,
    _: usize,
    _: *const *const c_char,
) -> Status {
    OK
}

/// `fmi3InstantiateCoSimulation`. Event mode and early return are not offered.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instance_name: *const c_char,
    instantiation_token: *const c_char,
    resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    event_mode_used: bool,
    _early_return_allowed: bool,
    _required: *const Vr,
    _n_required: usize,
    env: *mut c_void,
    log: Option<LogFn>,
    _intermediate: *const c_void,
) -> *mut c_void {
    let r = catch_unwind(|| {
        // SAFETY: NUL-terminated strings from the environment.
        let name = unsafe { cstr(instance_name) }.unwrap_or("tiltsim");
        // SAFETY: as above.
        let tok = unsafe { cstr(instantiation_token) }.unwrap_or("");
        // SAFETY: as above.
        let res = unsafe { cstr(resource_path) };
        let report = |m: String| {
            if let Some(f) = log {
                let c = CString::new(format!("{name}: {m}").replace('\0', " ")).unwrap_or_default();
                // SAFETY: the environment's callback.
                unsafe { f(env, ERROR, c"logStatusError".as_ptr(), c.as_ptr()) };
            }
        };
        if event_mode_used {
            report("event mode is not supported (hasEventMode = false)".into());
            return std::ptr::null_mut();
        }
        let Some(res) = res else {
            report("no resourcePath: the FMU's resources/tiltsim.json is needed".into());
            return std::ptr::null_mut();
        };
        match instantiate(name, tok, res, log, env) {
            Ok(i) => Box::into_raw(Box::new(i)) as *mut c_void,
            Err(e) => {
                report(e);
                std::ptr::null_mut()
            }
        }
    });
    r.unwrap_or(std::ptr::null_mut())
}

/// `fmi3FreeInstance`.
#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(inst: *mut c_void) {
    if !inst.is_null() {
        // SAFETY: from Box::into_raw in fmi3InstantiateCoSimulation, freed once.
        drop(unsafe { Box::from_raw(inst as *mut Instance) });
    }
}

/// `fmi3EnterInitializationMode`.
#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    inst: *mut c_void,
    _tol_defined: bool,
    _tol: f64,
    start: f64,
    _stop_defined: bool,
    _stop: f64,
) -> Status {
    // SAFETY: see `with`.
    unsafe {
        with(inst, |i| {
            if i.state != State::Instantiated {
                return i.fail("fmi3EnterInitializationMode called twice");
            }
            if start != 0.0 {
                return i.fail(&format!(
                    "startTime {start} s: tiltsim participants start at 0 s"
                ));
            }
            i.state = State::Initialization;
            OK
        })
    }
}

/// `fmi3ExitInitializationMode`: the participant is built from the parameters as set.
#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(inst: *mut c_void) -> Status {
    // SAFETY: see `with`.
    unsafe {
        with(inst, |i| {
            if i.state != State::Initialization {
                return i.fail("fmi3ExitInitializationMode outside initialisation mode");
            }
            if let Err(e) = i.model() {
                i.state = State::Failed;
                return i.fail(&e);
            }
            i.state = State::Step;
            OK
        })
    }
}

/// `fmi3Terminate`.
#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(inst: *mut c_void) -> Status {
    // SAFETY: see `with`.
    unsafe {
        with(inst, |i| {
            i.state = State::Terminated;
            OK
        })
    }
}

/// `fmi3Reset`: back to the instantiated state with the FMU's own parameter values.
#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(inst: *mut c_void) -> Status {
    // SAFETY: see `with`.
    unsafe {
        with(inst, |i| {
            i.params = i.layout.params.iter().map(|p| p.value.clone()).collect();
            i.inputs.iter_mut().for_each(|v| {
                *v = match v {
                    ScalarValue::F64(_) => ScalarValue::F64(0.0),
                    ScalarValue::U32(_) => ScalarValue::U32(0),
                }
            });
            i.model = None;
            i.params_changed = false;
            i.tick = 0;
            i.state = State::Instantiated;
            OK
        })
    }
}

/// `fmi3DoStep`: whole base ticks ([`Instance::do_step`]).
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn fmi3DoStep(
    inst: *mut c_void,
    t: f64,
    h: f64,
    _no_set_prior: bool,
    event_handling_needed: *mut bool,
    terminate: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> Status {
    // SAFETY: see `with`; the out-pointers are the caller's.
    unsafe {
        with(inst, |i| {
            let r = i.do_step(t, h);
            for p in [event_handling_needed, terminate, early_return] {
                if !p.is_null() {
                    *p = false;
                }
            }
            if !last_successful_time.is_null() {
                *last_successful_time = i.time();
            }
            match r {
                Ok(()) => OK,
                Err(e) => i.fail(&format!("fmi3DoStep at t = {t} s: {e}")),
            }
        })
    }
}

/// Which variables a setter may change in the instance's state.
pub(crate) fn settable(i: &Instance, slot: Slot) -> Result<(), String> {
    match (slot, i.state) {
        (Slot::Input(_), State::Instantiated | State::Initialization | State::Step) => Ok(()),
        (Slot::Param(_), State::Instantiated | State::Initialization) => Ok(()),
        (Slot::Param(_), _) => Err("parameters are fixed after initialisation".into()),
        (Slot::Time | Slot::Output(_), _) => Err("only inputs and parameters can be set".into()),
        _ => Err(format!("not in {:?} mode", i.state)),
    }
}

/// `fmi3Get<T>` / `fmi2Get<T>` (`api` names the caller in messages; FMI 2.0 passes
/// `nv = n`).
pub(crate) unsafe fn get_many<T: FmiValue>(
    api: &str,
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    values: *mut T,
    nv: usize,
) -> Status {
    // SAFETY: see `with`; the arrays are the caller's, of the lengths given.
    unsafe {
        with(inst, |i| {
            if n != nv || (n > 0 && (vrs.is_null() || values.is_null())) {
                return i.fail(&format!(
                    "{api}Get{}: {n} value references, {nv} values",
                    T::NAME
                ));
            }
            for j in 0..n {
                match get_one::<T>(i, *vrs.add(j)) {
                    Ok(v) => *values.add(j) = v,
                    Err(e) => return i.fail(&format!("{api}Get{}: {e}", T::NAME)),
                }
            }
            OK
        })
    }
}

/// `fmi3Set<T>` / `fmi2Set<T>`, as [`get_many`].
pub(crate) unsafe fn set_many<T: FmiValue>(
    api: &str,
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    values: *const T,
    nv: usize,
) -> Status {
    // SAFETY: see `get_many`.
    unsafe {
        with(inst, |i| {
            if n != nv || (n > 0 && (vrs.is_null() || values.is_null())) {
                return i.fail(&format!(
                    "{api}Set{}: {n} value references, {nv} values",
                    T::NAME
                ));
            }
            for j in 0..n {
                if let Err(e) = set_one::<T>(i, *vrs.add(j), *values.add(j)) {
                    return i.fail(&format!("{api}Set{}: {e}", T::NAME));
                }
            }
            OK
        })
    }
}

macro_rules! typed {
    ($get:ident, $set:ident, $t:ty) => {
        /// The standard's getter of this type.
        #[no_mangle]
        pub unsafe extern "C" fn $get(
            inst: *mut c_void,
            vrs: *const Vr,
            n: usize,
            v: *mut $t,
            nv: usize,
        ) -> Status {
            // SAFETY: forwarded as received.
            unsafe { get_many::<$t>("fmi3", inst, vrs, n, v, nv) }
        }
        /// The standard's setter of this type.
        #[no_mangle]
        pub unsafe extern "C" fn $set(
            inst: *mut c_void,
            vrs: *const Vr,
            n: usize,
            v: *const $t,
            nv: usize,
        ) -> Status {
            // SAFETY: forwarded as received.
            unsafe { set_many::<$t>("fmi3", inst, vrs, n, v, nv) }
        }
    };
}
typed!(fmi3GetFloat64, fmi3SetFloat64, f64);
typed!(fmi3GetUInt32, fmi3SetUInt32, u32);
typed!(fmi3GetUInt64, fmi3SetUInt64, u64);
typed!(fmi3GetInt64, fmi3SetInt64, i64);
typed!(fmi3GetBoolean, fmi3SetBoolean, bool);

/// `fmi3GetString`: the parameters that are choices (`controller.mode`).
#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    values: *mut *const c_char,
    nv: usize,
) -> Status {
    // SAFETY: see `get_many`.
    unsafe {
        with(inst, |i| {
            if n != nv || (n > 0 && (vrs.is_null() || values.is_null())) {
                return i.fail("fmi3GetString: value references and values differ in number");
            }
            i.strings.clear();
            for j in 0..n {
                let vr = *vrs.add(j);
                match i.layout.slot(vr) {
                    Some(Slot::Param(k)) => match &i.params[k] {
                        ParamValue::Str(s) => {
                            let c = CString::new(s.as_str()).unwrap_or_default();
                            *values.add(j) = c.as_ptr();
                            i.strings.push(c);
                        }
                        _ => {
                            return i.fail(&format!(
                                "fmi3GetString: value reference {vr} is not a String"
                            ))
                        }
                    },
                    _ => {
                        return i.fail(&format!(
                            "fmi3GetString: value reference {vr} is not a String"
                        ))
                    }
                }
            }
            OK
        })
    }
}

/// `fmi3SetString`.
#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    values: *const *const c_char,
    nv: usize,
) -> Status {
    // SAFETY: see `get_many`.
    unsafe {
        with(inst, |i| {
            if n != nv || (n > 0 && (vrs.is_null() || values.is_null())) {
                return i.fail("fmi3SetString: value references and values differ in number");
            }
            for j in 0..n {
                let vr = *vrs.add(j);
                let Some(s) = cstr(*values.add(j)) else {
                    return i.fail("fmi3SetString: a value is not UTF-8 text");
                };
                let r = match i.layout.slot(vr) {
                    Some(slot @ Slot::Param(k)) if matches!(i.params[k], ParamValue::Str(_)) => {
                        settable(i, slot).map(|()| {
                            i.params[k] = ParamValue::Str(s.to_string());
                            i.params_changed = true;
                        })
                    }
                    _ => Err(format!("value reference {vr} is not a String")),
                };
                if let Err(e) = r {
                    return i.fail(&format!("fmi3SetString: {e}"));
                }
            }
            OK
        })
    }
}

/// Functions of interfaces and types this FMU does not offer: they exist, say so and fail.
macro_rules! unsupported {
    ($($name:ident),* $(,)?) => {$(
        /// Not offered by tiltsim's FMUs; returns `fmi3Error`.
        #[no_mangle]
        pub unsafe extern "C" fn $name(inst: *mut c_void) -> Status {
            // SAFETY: see `with`.
            unsafe { with(inst, |i| i.fail(concat!(stringify!($name), " is not supported by this FMU"))) }
        }
    )*};
}
unsupported!(
    fmi3EnterEventMode,
    fmi3GetFloat32,
    fmi3SetFloat32,
    fmi3GetInt8,
    fmi3SetInt8,
    fmi3GetUInt8,
    fmi3SetUInt8,
    fmi3GetInt16,
    fmi3SetInt16,
    fmi3GetUInt16,
    fmi3SetUInt16,
    fmi3GetInt32,
    fmi3SetInt32,
    fmi3GetBinary,
    fmi3SetBinary,
    fmi3GetClock,
    fmi3SetClock,
    fmi3GetNumberOfVariableDependencies,
    fmi3GetVariableDependencies,
    fmi3GetFMUState,
    fmi3SetFMUState,
    fmi3FreeFMUState,
    fmi3SerializedFMUStateSize,
    fmi3SerializeFMUState,
    fmi3DeserializeFMUState,
    fmi3GetDirectionalDerivative,
    fmi3GetAdjointDerivative,
    fmi3EnterConfigurationMode,
    fmi3ExitConfigurationMode,
    fmi3GetIntervalDecimal,
    fmi3GetIntervalFraction,
    fmi3GetShiftDecimal,
    fmi3GetShiftFraction,
    fmi3SetIntervalDecimal,
    fmi3SetIntervalFraction,
    fmi3SetShiftDecimal,
    fmi3SetShiftFraction,
    fmi3EvaluateDiscreteStates,
    fmi3UpdateDiscreteStates,
    fmi3EnterContinuousTimeMode,
    fmi3CompletedIntegratorStep,
    fmi3SetTime,
    fmi3SetContinuousStates,
    fmi3GetContinuousStateDerivatives,
    fmi3GetEventIndicators,
    fmi3GetContinuousStates,
    fmi3GetNominalsOfContinuousStates,
    fmi3GetNumberOfEventIndicators,
    fmi3GetNumberOfContinuousStates,
    fmi3EnterStepMode,
    fmi3GetOutputDerivatives,
    fmi3ActivateModelPartition,
);

/// `fmi3InstantiateModelExchange`: not offered.
#[no_mangle]
pub extern "C" fn fmi3InstantiateModelExchange() -> *mut c_void {
    std::ptr::null_mut()
}

/// `fmi3InstantiateScheduledExecution`: not offered.
#[no_mangle]
pub extern "C" fn fmi3InstantiateScheduledExecution() -> *mut c_void {
    std::ptr::null_mut()
}
