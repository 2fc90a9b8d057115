//! The FMI 2.0 co-simulation interface of the same library (the functions of the standard's
//! `fmi2Functions.h`): the same instances, layout and participant as the FMI 3.0 interface;
//! FMI 2.0's `Integer` carries the unsigned and 64-bit values (within 32 bits).

use std::ffi::{c_char, c_int, c_void, CString};
use std::panic::catch_unwind;

use cosim::msg::ScalarValue;
use tiltsim_fmi::layout::ParamValue;

use crate::{cstr, get_many, instantiate, set_many, with, FmiValue};
use crate::{Status, Vr, ERROR, OK};

/// `fmi2CallbackLogger` (printf-style; called here with the format `"%s"`).
pub type Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char, ...);

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct Callbacks {
    logger: Option<Logger>,
    allocate: *const c_void,
    free: *const c_void,
    step_finished: *const c_void,
    env: *mut c_void,
}

/// Logs `msg` through an FMI 2.0 logger (the message is an argument, never a format).
pub(crate) fn say(f: Logger, env: *mut c_void, name: &str, status: Status, msg: &str) {
    let inst = CString::new(name.replace('\0', " ")).unwrap_or_default();
    let cat = if status >= ERROR {
        c"logStatusError"
    } else {
        c"logEvents"
    };
    let m = CString::new(format!("{name}: {msg}").replace('\0', " ")).unwrap_or_default();
    // SAFETY: the environment's logger, with "%s" and one string argument.
    unsafe {
        f(
            env,
            inst.as_ptr(),
            status,
            cat.as_ptr(),
            c"%s".as_ptr(),
            m.as_ptr(),
        )
    };
}

/// The path of a `file:` URI (`file:///a/b`, `file:/a/b`), percent-decoded.
fn uri_path(uri: &str) -> Option<String> {
    let rest = uri
        .strip_prefix("file://")
        .map(|r| r.strip_prefix("localhost").unwrap_or(r))
        .or_else(|| uri.strip_prefix("file:"))?;
    let b = rest.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// `fmi2GetTypesPlatform`.
#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`.
#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// `fmi2SetDebugLogging`: messages always go to the logger.
#[no_mangle]
pub extern "C" fn fmi2SetDebugLogging(
    _: *mut c_void,
    _: c_int,
    _: usize,
    _: *const *const c_char,
) -> Status {
    OK
}

/// `fmi2Instantiate`: co-simulation only.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const Callbacks,
    _visible: c_int,
    _logging_on: c_int,
) -> *mut c_void {
    let r = catch_unwind(|| {
        // SAFETY: NUL-terminated strings and the callback structure from the environment.
        let name = unsafe { cstr(instance_name) }.unwrap_or("tiltsim");
        // SAFETY: as above.
        let tok = unsafe { cstr(guid) }.unwrap_or("");
        // SAFETY: as above.
        let res = unsafe { cstr(resource_location) };
        // SAFETY: as above; may be null.
        let cb = unsafe { functions.as_ref() };
        let (logger, env) = cb.map_or((None, std::ptr::null_mut()), |c| (c.logger, c.env));
        let report = |m: String| {
            if let Some(f) = logger {
                say(f, env, name, ERROR, &m);
            }
        };
        if fmu_type != 1 {
            report("only co-simulation (fmi2CoSimulation) is offered".into());
            return std::ptr::null_mut();
        }
        let Some(path) = res.and_then(uri_path) else {
            report(format!("resource location {res:?} is not a file: URI"));
            return std::ptr::null_mut();
        };
        match instantiate(name, tok, &path, None, env) {
            Ok(mut i) => {
                i.log2 = logger;
                Box::into_raw(Box::new(i)) as *mut c_void
            }
            Err(e) => {
                report(e);
                std::ptr::null_mut()
            }
        }
    });
    r.unwrap_or(std::ptr::null_mut())
}

/// `fmi2FreeInstance`.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(inst: *mut c_void) {
    // SAFETY: an instance from fmi2Instantiate, freed once.
    unsafe { crate::fmi3FreeInstance(inst) }
}

/// `fmi2SetupExperiment`: tiltsim participants start at 0 s.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    inst: *mut c_void,
    _tol_defined: c_int,
    _tol: f64,
    start: f64,
    _stop_defined: c_int,
    _stop: f64,
) -> Status {
    // SAFETY: see `with`.
    unsafe {
        with(inst, |i| {
            if start != 0.0 {
                return i.fail(&format!(
                    "startTime {start} s: tiltsim participants start at 0 s"
                ));
            }
            OK
        })
    }
}

/// `fmi2EnterInitializationMode`.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(inst: *mut c_void) -> Status {
    // SAFETY: forwarded.
    unsafe { crate::fmi3EnterInitializationMode(inst, false, 0.0, 0.0, false, 0.0) }
}

/// `fmi2ExitInitializationMode`.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(inst: *mut c_void) -> Status {
    // SAFETY: forwarded.
    unsafe { crate::fmi3ExitInitializationMode(inst) }
}

/// `fmi2Terminate`.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(inst: *mut c_void) -> Status {
    // SAFETY: forwarded.
    unsafe { crate::fmi3Terminate(inst) }
}

/// `fmi2Reset`.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(inst: *mut c_void) -> Status {
    // SAFETY: forwarded.
    unsafe { crate::fmi3Reset(inst) }
}

/// `fmi2DoStep`.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    inst: *mut c_void,
    t: f64,
    h: f64,
    _no_set_prior: c_int,
) -> Status {
    // SAFETY: see `with`.
    unsafe {
        with(inst, |i| match i.do_step(t, h) {
            Ok(()) => OK,
            Err(e) => i.fail(&format!("fmi2DoStep at t = {t} s: {e}")),
        })
    }
}

/// FMI 2.0 `Integer`: request and reply integers, and integer parameters within 32 bits.
#[derive(Clone, Copy)]
#[repr(transparent)]
struct Int2(c_int);

impl FmiValue for Int2 {
    const NAME: &'static str = "Integer";
    fn from_scalar(v: ScalarValue) -> Option<Self> {
        match v {
            ScalarValue::U32(x) => c_int::try_from(x).ok().map(Int2),
            ScalarValue::F64(_) => None,
        }
    }
    fn to_scalar(self, like: ScalarValue) -> Option<ScalarValue> {
        match like {
            ScalarValue::U32(_) => u32::try_from(self.0).ok().map(ScalarValue::U32),
            ScalarValue::F64(_) => None,
        }
    }
    fn from_param(v: &ParamValue) -> Option<Self> {
        match v {
            ParamValue::U64(x) => c_int::try_from(*x).ok().map(Int2),
            ParamValue::I64(x) => c_int::try_from(*x).ok().map(Int2),
            _ => None,
        }
    }
    fn to_param(self, like: &ParamValue) -> Option<ParamValue> {
        match like {
            ParamValue::U64(_) => u64::try_from(self.0).ok().map(ParamValue::U64),
            ParamValue::I64(_) => Some(ParamValue::I64(self.0 as i64)),
            _ => None,
        }
    }
}

/// FMI 2.0 `Boolean` (an `int`).
#[derive(Clone, Copy)]
#[repr(transparent)]
struct Bool2(c_int);

impl FmiValue for Bool2 {
    const NAME: &'static str = "Boolean";
    fn from_scalar(_: ScalarValue) -> Option<Self> {
        None
    }
    fn to_scalar(self, _: ScalarValue) -> Option<ScalarValue> {
        None
    }
    fn from_param(v: &ParamValue) -> Option<Self> {
        match v {
            ParamValue::Bool(b) => Some(Bool2(c_int::from(*b))),
            _ => None,
        }
    }
    fn to_param(self, like: &ParamValue) -> Option<ParamValue> {
        matches!(like, ParamValue::Bool(_)).then_some(ParamValue::Bool(self.0 != 0))
    }
}

/// `fmi2GetReal`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *mut f64,
) -> Status {
    // SAFETY: forwarded.
    unsafe { get_many::<f64>("fmi2", inst, vrs, n, v, n) }
}
/// `fmi2SetReal`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *const f64,
) -> Status {
    // SAFETY: forwarded.
    unsafe { set_many::<f64>("fmi2", inst, vrs, n, v, n) }
}
/// `fmi2GetInteger`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *mut c_int,
) -> Status {
    // SAFETY: forwarded; `Int2` is a transparent `int`.
    unsafe { get_many::<Int2>("fmi2", inst, vrs, n, v as *mut Int2, n) }
}
/// `fmi2SetInteger`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *const c_int,
) -> Status {
    // SAFETY: forwarded; `Int2` is a transparent `int`.
    unsafe { set_many::<Int2>("fmi2", inst, vrs, n, v as *const Int2, n) }
}
/// `fmi2GetBoolean`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *mut c_int,
) -> Status {
    // SAFETY: forwarded; `Bool2` is a transparent `int`.
    unsafe { get_many::<Bool2>("fmi2", inst, vrs, n, v as *mut Bool2, n) }
}
/// `fmi2SetBoolean`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *const c_int,
) -> Status {
    // SAFETY: forwarded; `Bool2` is a transparent `int`.
    unsafe { set_many::<Bool2>("fmi2", inst, vrs, n, v as *const Bool2, n) }
}

/// `fmi2GetString`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *mut *const c_char,
) -> Status {
    // SAFETY: forwarded with nValues = n.
    unsafe { crate::fmi3GetString(inst, vrs, n, v, n) }
}

/// `fmi2SetString`.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    inst: *mut c_void,
    vrs: *const Vr,
    n: usize,
    v: *const *const c_char,
) -> Status {
    // SAFETY: forwarded with nValues = n.
    unsafe { crate::fmi3SetString(inst, vrs, n, v, n) }
}

/// Functions of FMI 2.0 this FMU does not offer: they exist and fail.
macro_rules! unsupported2 {
    ($($name:ident),* $(,)?) => {$(
        /// Not offered by tiltsim's FMUs; returns `fmi2Error`.
        #[no_mangle]
        pub unsafe extern "C" fn $name(inst: *mut c_void) -> Status {
            // SAFETY: see `with`.
            unsafe { with(inst, |i| i.fail(concat!(stringify!($name), " is not supported by this FMU"))) }
        }
    )*};
}
unsupported2!(
    fmi2GetFMUstate,
    fmi2SetFMUstate,
    fmi2FreeFMUstate,
    fmi2SerializedFMUstateSize,
    fmi2SerializeFMUstate,
    fmi2DeSerializeFMUstate,
    fmi2GetDirectionalDerivative,
    fmi2SetRealInputDerivatives,
    fmi2GetRealOutputDerivatives,
    fmi2CancelStep,
    fmi2GetStatus,
    fmi2GetRealStatus,
    fmi2GetIntegerStatus,
    fmi2GetBooleanStatus,
    fmi2GetStringStatus,
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_uris_become_paths() {
        assert_eq!(
            uri_path("file:///tmp/a%20b/res").as_deref(),
            Some("/tmp/a b/res")
        );
        assert_eq!(uri_path("file:/tmp/x").as_deref(), Some("/tmp/x"));
        assert_eq!(
            uri_path("file://localhost/tmp/x").as_deref(),
            Some("/tmp/x")
        );
        assert_eq!(uri_path("http://x"), None);
    }
}
