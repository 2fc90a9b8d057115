//! A small binding of the FMI C API (the function signatures of the standard's
//! `fmi2Functions.h` and `fmi3Functions.h`, co-simulation part) over `libloading`: one
//! instance of an FMI 2.0 or FMI 3.0 co-simulation FMU behind one [`Slave`] interface.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;
use std::sync::Mutex;

use crate::description::FmiVersion;

/// A value of a variable as tiltsim sets or gets it.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Real / Float64.
    Real(f64),
    /// Any integer type.
    Int(i64),
    /// Boolean.
    Bool(bool),
    /// String.
    Str(String),
}

/// Integer variable types (the C types differ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IntType {
    /// 32-bit signed (FMI 2 `Integer`, FMI 3 `Int32` and enumerations in FMI 2).
    I32,
    /// FMI 3 `UInt32`.
    U32,
    /// FMI 3 `Int64`.
    I64,
    /// FMI 3 `UInt64`.
    U64,
}

/// Messages an FMU logged, kept for error reports.
#[derive(Default)]
struct Log {
    name: String,
    last: Mutex<Vec<String>>,
}

impl Log {
    fn push(&self, status: c_int, category: &str, message: &str) {
        let line = format!("{} [{category}] {message}", status_name(status));
        if status >= 1 {
            eprintln!("FMU {}: {line}", self.name);
        }
        if let Ok(mut l) = self.last.lock() {
            if l.len() >= 8 {
                l.remove(0);
            }
            l.push(line);
        }
    }
    fn recent(&self) -> String {
        self.last
            .lock()
            .map(|l| {
                if l.is_empty() {
                    String::new()
                } else {
                    format!(" (it logged: {})", l.join("; "))
                }
            })
            .unwrap_or_default()
    }
}

fn status_name(s: c_int) -> &'static str {
    match s {
        0 => "OK",
        1 => "Warning",
        2 => "Discard",
        3 => "Error",
        4 => "Fatal",
        5 => "Pending",
        _ => "unknown status",
    }
}

unsafe fn text(p: *const c_char) -> String {
    if p.is_null() {
        String::new()
    } else {
        // SAFETY: the FMU passes NUL-terminated strings.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// FMI 2 logger. The standard declares it variadic (printf-style); the message is reported as
/// given, without substituting arguments (Rust cannot define C-variadic functions). On x86_64
/// a variadic call passes the fixed arguments exactly as a plain call does.
unsafe extern "C" fn log2(
    env: *mut c_void,
    _instance: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    if env.is_null() {
        return;
    }
    // SAFETY: env is the `Log` this binding registered; it outlives the instance.
    let log = unsafe { &*(env as *const Log) };
    log.push(status, &unsafe { text(category) }, &unsafe {
        text(message)
    });
}

/// FMI 3 logger.
unsafe extern "C" fn log3(
    env: *mut c_void,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    if env.is_null() {
        return;
    }
    // SAFETY: as for `log2`.
    let log = unsafe { &*(env as *const Log) };
    log.push(status, &unsafe { text(category) }, &unsafe {
        text(message)
    });
}

unsafe extern "C" fn alloc2(n: usize, size: usize) -> *mut c_void {
    // SAFETY: calloc with the FMU's sizes, as FMI 2 asks of the environment.
    unsafe { libc::calloc(n, size) }
}
unsafe extern "C" fn free2(p: *mut c_void) {
    // SAFETY: memory from `alloc2`.
    unsafe { libc::free(p) }
}

#[repr(C)]
struct Callbacks2 {
    logger: unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char),
    allocate: unsafe extern "C" fn(usize, usize) -> *mut c_void,
    free: unsafe extern "C" fn(*mut c_void),
    step_finished: *const c_void,
    env: *mut c_void,
}

/// Opens `libs` with `RTLD_NOW | RTLD_GLOBAL`, so their symbols resolve those an FMU's library
/// leaves to its host.
pub fn preload(libs: &[String]) -> Result<Vec<libloading::os::unix::Library>, String> {
    use libloading::os::unix::{Library, RTLD_GLOBAL, RTLD_NOW};
    libs.iter()
        .map(|l| {
            // SAFETY: loading a shared library the scenario names runs its initialisers.
            unsafe { Library::open(Some(l), RTLD_NOW | RTLD_GLOBAL) }.map_err(|e| {
                let why =
                    std::error::Error::source(&e).map_or_else(|| e.to_string(), |s| s.to_string());
                format!("cannot preload `{l}`: {why}")
            })
        })
        .collect()
}

type Inst = *mut c_void;
type Vr = u32;

/// One instance of a co-simulation FMU, stepped by the caller.
pub struct Slave {
    lib: libloading::Library,
    inst: Inst,
    version: FmiVersion,
    log: Box<Log>,
    _callbacks: Option<Box<Callbacks2>>,
    /// Strings passed to the FMU stay alive as long as it may read them.
    strings: Vec<CString>,
    hot: Hot,
}

/// The functions called every step, looked up once.
#[derive(Clone, Copy)]
struct Hot {
    set_reals: *const c_void,
    get_reals: *const c_void,
    do_step: *const c_void,
}

// SAFETY: an FMU instance is used from one thread at a time; `Slave` is moved, never shared.
unsafe impl Send for Slave {}

macro_rules! sym {
    ($lib:expr, $ty:ty, $name:expr) => {{
        // SAFETY: the symbol's type is the standard's signature of that function.
        let s: libloading::Symbol<$ty> = unsafe { $lib.get($name.as_bytes()) }
            .map_err(|_| format!("the library does not export `{}`", $name))?;
        *s
    }};
}

fn check(status: c_int, what: &str, log: &Log) -> Result<(), String> {
    match status {
        0 | 1 => Ok(()),
        s => Err(format!(
            "{what} returned {}{}",
            status_name(s),
            log.recent()
        )),
    }
}

/// `fmi2Instantiate` as a co-simulation slave with the resources at `resources`: the
/// instance, the callbacks it keeps (`env` the log), and the resource URI it was given.
fn instantiate2(
    lib: &libloading::Library,
    cname: &CString,
    ctoken: &CString,
    resources: &Path,
    env: *mut c_void,
) -> Result<(Inst, Box<Callbacks2>, CString), String> {
    type F = unsafe extern "C" fn(
        *const c_char,
        c_int,
        *const c_char,
        *const c_char,
        *const Callbacks2,
        c_int,
        c_int,
    ) -> Inst;
    let f = sym!(lib, F, "fmi2Instantiate");
    let uri = CString::new(format!("file://{}", resources.display()))
        .map_err(|_| "path with NUL".to_string())?;
    let cb = Box::new(Callbacks2 {
        logger: log2,
        allocate: alloc2,
        free: free2,
        step_finished: std::ptr::null(),
        env,
    });
    // SAFETY: arguments as fmi2Instantiate asks (fmi2CoSimulation = 1).
    let inst = unsafe { f(cname.as_ptr(), 1, ctoken.as_ptr(), uri.as_ptr(), &*cb, 0, 0) };
    Ok((inst, cb, uri))
}

/// `fmi3InstantiateCoSimulation` with the resources at `resources` (`env` the log): the
/// instance and the resource path it was given.
fn instantiate3(
    lib: &libloading::Library,
    cname: &CString,
    ctoken: &CString,
    resources: &Path,
    env: *mut c_void,
) -> Result<(Inst, CString), String> {
    type F = unsafe extern "C" fn(
        *const c_char,
        *const c_char,
        *const c_char,
        bool,
        bool,
        bool,
        bool,
        *const Vr,
        usize,
        *mut c_void,
        unsafe extern "C" fn(*mut c_void, c_int, *const c_char, *const c_char),
        *const c_void,
    ) -> Inst;
    let f = sym!(lib, F, "fmi3InstantiateCoSimulation");
    let path = CString::new(format!("{}/", resources.display()))
        .map_err(|_| "path with NUL".to_string())?;
    // SAFETY: arguments as fmi3InstantiateCoSimulation asks; no event mode, no early
    // return, no intermediate update.
    let inst = unsafe {
        f(
            cname.as_ptr(),
            ctoken.as_ptr(),
            path.as_ptr(),
            false,
            false,
            false,
            false,
            std::ptr::null(),
            0,
            env,
            log3,
            std::ptr::null(),
        )
    };
    Ok((inst, path))
}

impl Hot {
    /// The addresses of the functions each step calls, from `lib` of `version`.
    fn of(lib: &libloading::Library, version: FmiVersion) -> Result<Hot, String> {
        let names = match version {
            FmiVersion::V2 => ["fmi2SetReal", "fmi2GetReal", "fmi2DoStep"],
            FmiVersion::V3 => ["fmi3SetFloat64", "fmi3GetFloat64", "fmi3DoStep"],
        };
        let mut ptrs = [std::ptr::null::<c_void>(); 3];
        for (p, n) in ptrs.iter_mut().zip(names) {
            // SAFETY: only the address is taken; it is called with the standard's signature.
            let f: libloading::Symbol<*const c_void> = unsafe { lib.get(n.as_bytes()) }
                .map_err(|_| format!("the library does not export `{n}`"))?;
            *p = *f;
        }
        Ok(Hot {
            set_reals: ptrs[0],
            get_reals: ptrs[1],
            do_step: ptrs[2],
        })
    }
}

impl Slave {
    /// Loads `library`, instantiates it as a co-simulation slave called `name` and takes it
    /// into initialisation mode at `start_s`.
    pub fn instantiate(
        version: FmiVersion,
        library: &Path,
        name: &str,
        token: &str,
        resources: &Path,
        start_s: f64,
    ) -> Result<Slave, String> {
        // SAFETY: loading the FMU's library runs its initialisers; that is what an FMU is for.
        let lib = unsafe { libloading::Library::new(library) }.map_err(|e| {
            let why =
                std::error::Error::source(&e).map_or_else(|| e.to_string(), |s| s.to_string());
            format!("cannot load its library {}: {why}", library.display())
        })?;
        let log = Box::new(Log {
            name: name.to_string(),
            ..Default::default()
        });
        let cname = CString::new(name).map_err(|_| "name with NUL".to_string())?;
        let ctoken = CString::new(token).map_err(|_| "token with NUL".to_string())?;
        let env = &*log as *const Log as *mut c_void;
        let (inst, callbacks, path) = match version {
            FmiVersion::V2 => {
                let (inst, cb, uri) = instantiate2(&lib, &cname, &ctoken, resources, env)?;
                (inst, Some(cb), uri)
            }
            FmiVersion::V3 => {
                let (inst, path) = instantiate3(&lib, &cname, &ctoken, resources, env)?;
                (inst, None, path)
            }
        };
        let strings = vec![path, cname, ctoken];
        if inst.is_null() {
            return Err(format!("instantiation failed{}", log.recent()));
        }
        let hot = Hot::of(&lib, version)?;
        let mut s = Slave {
            lib,
            inst,
            version,
            log,
            _callbacks: callbacks,
            strings,
            hot,
        };
        s.enter_initialization(start_s)?;
        Ok(s)
    }

    fn enter_initialization(&mut self, t0: f64) -> Result<(), String> {
        match self.version {
            FmiVersion::V2 => {
                type Setup = unsafe extern "C" fn(Inst, c_int, f64, f64, c_int, f64) -> c_int;
                type Enter = unsafe extern "C" fn(Inst) -> c_int;
                let setup = sym!(self.lib, Setup, "fmi2SetupExperiment");
                let enter = sym!(self.lib, Enter, "fmi2EnterInitializationMode");
                // SAFETY: a live instance.
                check(
                    unsafe { setup(self.inst, 0, 0.0, t0, 0, 0.0) },
                    "fmi2SetupExperiment",
                    &self.log,
                )?;
                // SAFETY: a live instance.
                check(
                    unsafe { enter(self.inst) },
                    "fmi2EnterInitializationMode",
                    &self.log,
                )
            }
            FmiVersion::V3 => {
                type Enter = unsafe extern "C" fn(Inst, bool, f64, f64, bool, f64) -> c_int;
                let enter = sym!(self.lib, Enter, "fmi3EnterInitializationMode");
                // SAFETY: a live instance.
                check(
                    unsafe { enter(self.inst, false, 0.0, t0, false, 0.0) },
                    "fmi3EnterInitializationMode",
                    &self.log,
                )
            }
        }
    }

    /// Leaves initialisation mode: the outputs at the start time can then be read.
    pub fn exit_initialization(&mut self) -> Result<(), String> {
        type Exit = unsafe extern "C" fn(Inst) -> c_int;
        let name = match self.version {
            FmiVersion::V2 => "fmi2ExitInitializationMode",
            FmiVersion::V3 => "fmi3ExitInitializationMode",
        };
        let f = sym!(self.lib, Exit, name);
        // SAFETY: a live instance.
        check(unsafe { f(self.inst) }, name, &self.log)
    }

    /// Sets reals.
    pub fn set_reals(&mut self, vrs: &[Vr], values: &[f64]) -> Result<(), String> {
        if vrs.is_empty() {
            return Ok(());
        }
        match self.version {
            FmiVersion::V2 => {
                type F = unsafe extern "C" fn(Inst, *const Vr, usize, *const f64) -> c_int;
                // SAFETY: the address of fmi2SetReal, of this type.
                let f: F = unsafe { std::mem::transmute(self.hot.set_reals) };
                // SAFETY: slices of equal length.
                check(
                    unsafe { f(self.inst, vrs.as_ptr(), vrs.len(), values.as_ptr()) },
                    "fmi2SetReal",
                    &self.log,
                )
            }
            FmiVersion::V3 => {
                type F = unsafe extern "C" fn(Inst, *const Vr, usize, *const f64, usize) -> c_int;
                // SAFETY: the address of fmi3SetFloat64, of this type.
                let f: F = unsafe { std::mem::transmute(self.hot.set_reals) };
                // SAFETY: slices of equal length.
                check(
                    unsafe {
                        f(
                            self.inst,
                            vrs.as_ptr(),
                            vrs.len(),
                            values.as_ptr(),
                            values.len(),
                        )
                    },
                    "fmi3SetFloat64",
                    &self.log,
                )
            }
        }
    }

    /// Gets reals.
    pub fn get_reals(&mut self, vrs: &[Vr], values: &mut [f64]) -> Result<(), String> {
        if vrs.is_empty() {
            return Ok(());
        }
        match self.version {
            FmiVersion::V2 => {
                type F = unsafe extern "C" fn(Inst, *const Vr, usize, *mut f64) -> c_int;
                // SAFETY: the address of fmi2GetReal, of this type.
                let f: F = unsafe { std::mem::transmute(self.hot.get_reals) };
                // SAFETY: slices of equal length.
                check(
                    unsafe { f(self.inst, vrs.as_ptr(), vrs.len(), values.as_mut_ptr()) },
                    "fmi2GetReal",
                    &self.log,
                )
            }
            FmiVersion::V3 => {
                type F = unsafe extern "C" fn(Inst, *const Vr, usize, *mut f64, usize) -> c_int;
                // SAFETY: the address of fmi3GetFloat64, of this type.
                let f: F = unsafe { std::mem::transmute(self.hot.get_reals) };
                // SAFETY: slices of equal length.
                check(
                    unsafe {
                        f(
                            self.inst,
                            vrs.as_ptr(),
                            vrs.len(),
                            values.as_mut_ptr(),
                            values.len(),
                        )
                    },
                    "fmi3GetFloat64",
                    &self.log,
                )
            }
        }
    }

    /// Sets one integer of type `t`.
    pub fn set_int(&mut self, vr: Vr, t: IntType, v: i64) -> Result<(), String> {
        macro_rules! one {
            ($name:expr, $ct:ty, $v2:expr) => {{
                let x: $ct = $v2;
                match self.version {
                    FmiVersion::V2 => {
                        type F = unsafe extern "C" fn(Inst, *const Vr, usize, *const $ct) -> c_int;
                        let f = sym!(self.lib, F, $name);
                        // SAFETY: one value reference, one value.
                        check(unsafe { f(self.inst, &vr, 1, &x) }, $name, &self.log)
                    }
                    FmiVersion::V3 => {
                        type F = unsafe extern "C" fn(
                            Inst,
                            *const Vr,
                            usize,
                            *const $ct,
                            usize,
                        ) -> c_int;
                        let f = sym!(self.lib, F, $name);
                        // SAFETY: one value reference, one value.
                        check(unsafe { f(self.inst, &vr, 1, &x, 1) }, $name, &self.log)
                    }
                }
            }};
        }
        let range = |ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(format!("value {v} out of range"))
            }
        };
        match (self.version, t) {
            (FmiVersion::V2, _) => {
                range(i32::try_from(v).is_ok())?;
                one!("fmi2SetInteger", c_int, v as c_int)
            }
            (FmiVersion::V3, IntType::I32) => {
                range(i32::try_from(v).is_ok())?;
                one!("fmi3SetInt32", i32, v as i32)
            }
            (FmiVersion::V3, IntType::U32) => {
                range(u32::try_from(v).is_ok())?;
                one!("fmi3SetUInt32", u32, v as u32)
            }
            (FmiVersion::V3, IntType::I64) => one!("fmi3SetInt64", i64, v),
            (FmiVersion::V3, IntType::U64) => {
                range(v >= 0)?;
                one!("fmi3SetUInt64", u64, v as u64)
            }
        }
    }

    /// Gets one integer of type `t`.
    pub fn get_int(&mut self, vr: Vr, t: IntType) -> Result<i64, String> {
        macro_rules! one {
            ($name:expr, $ct:ty) => {{
                let mut x: $ct = Default::default();
                match self.version {
                    FmiVersion::V2 => {
                        type F = unsafe extern "C" fn(Inst, *const Vr, usize, *mut $ct) -> c_int;
                        let f = sym!(self.lib, F, $name);
                        // SAFETY: one value reference, one value.
                        check(unsafe { f(self.inst, &vr, 1, &mut x) }, $name, &self.log)?;
                    }
                    FmiVersion::V3 => {
                        type F =
                            unsafe extern "C" fn(Inst, *const Vr, usize, *mut $ct, usize) -> c_int;
                        let f = sym!(self.lib, F, $name);
                        // SAFETY: one value reference, one value.
                        check(unsafe { f(self.inst, &vr, 1, &mut x, 1) }, $name, &self.log)?;
                    }
                }
                x as i64
            }};
        }
        Ok(match (self.version, t) {
            (FmiVersion::V2, _) => one!("fmi2GetInteger", c_int),
            (FmiVersion::V3, IntType::I32) => one!("fmi3GetInt32", i32),
            (FmiVersion::V3, IntType::U32) => one!("fmi3GetUInt32", u32),
            (FmiVersion::V3, IntType::I64) => one!("fmi3GetInt64", i64),
            (FmiVersion::V3, IntType::U64) => one!("fmi3GetUInt64", u64),
        })
    }

    /// Sets one boolean.
    pub fn set_bool(&mut self, vr: Vr, v: bool) -> Result<(), String> {
        match self.version {
            FmiVersion::V2 => {
                type F = unsafe extern "C" fn(Inst, *const Vr, usize, *const c_int) -> c_int;
                let f = sym!(self.lib, F, "fmi2SetBoolean");
                let x = v as c_int;
                // SAFETY: one value reference, one value.
                check(
                    unsafe { f(self.inst, &vr, 1, &x) },
                    "fmi2SetBoolean",
                    &self.log,
                )
            }
            FmiVersion::V3 => {
                type F = unsafe extern "C" fn(Inst, *const Vr, usize, *const bool, usize) -> c_int;
                let f = sym!(self.lib, F, "fmi3SetBoolean");
                // SAFETY: one value reference, one value.
                check(
                    unsafe { f(self.inst, &vr, 1, &v, 1) },
                    "fmi3SetBoolean",
                    &self.log,
                )
            }
        }
    }

    /// Sets one string.
    pub fn set_string(&mut self, vr: Vr, v: &str) -> Result<(), String> {
        let c = CString::new(v).map_err(|_| "string with NUL".to_string())?;
        let p = c.as_ptr();
        self.strings.push(c);
        match self.version {
            FmiVersion::V2 => {
                type F =
                    unsafe extern "C" fn(Inst, *const Vr, usize, *const *const c_char) -> c_int;
                let f = sym!(self.lib, F, "fmi2SetString");
                // SAFETY: one value reference, one value.
                check(
                    unsafe { f(self.inst, &vr, 1, &p) },
                    "fmi2SetString",
                    &self.log,
                )
            }
            FmiVersion::V3 => {
                type F = unsafe extern "C" fn(
                    Inst,
                    *const Vr,
                    usize,
                    *const *const c_char,
                    usize,
                ) -> c_int;
                let f = sym!(self.lib, F, "fmi3SetString");
                // SAFETY: one value reference, one value.
                check(
                    unsafe { f(self.inst, &vr, 1, &p, 1) },
                    "fmi3SetString",
                    &self.log,
                )
            }
        }
    }

    /// One communication step from `t` to `t + h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), String> {
        match self.version {
            FmiVersion::V2 => {
                type F = unsafe extern "C" fn(Inst, f64, f64, c_int) -> c_int;
                // SAFETY: the address of fmi2DoStep, of this type.
                let f: F = unsafe { std::mem::transmute(self.hot.do_step) };
                // SAFETY: a live instance.
                check(unsafe { f(self.inst, t, h, 1) }, "fmi2DoStep", &self.log)
            }
            FmiVersion::V3 => {
                type F = unsafe extern "C" fn(
                    Inst,
                    f64,
                    f64,
                    bool,
                    *mut bool,
                    *mut bool,
                    *mut bool,
                    *mut f64,
                ) -> c_int;
                // SAFETY: the address of fmi3DoStep, of this type.
                let f: F = unsafe { std::mem::transmute(self.hot.do_step) };
                let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                // SAFETY: a live instance and valid out-pointers.
                let s = unsafe {
                    f(
                        self.inst,
                        t,
                        h,
                        true,
                        &mut event,
                        &mut terminate,
                        &mut early,
                        &mut last,
                    )
                };
                check(s, "fmi3DoStep", &self.log)?;
                if terminate {
                    return Err(format!(
                        "fmi3DoStep asked to terminate the simulation{}",
                        self.log.recent()
                    ));
                }
                if early {
                    return Err(format!("fmi3DoStep returned early at t = {last} s although early return was not allowed"));
                }
                Ok(())
            }
        }
    }
}

impl Drop for Slave {
    fn drop(&mut self) {
        type F = unsafe extern "C" fn(Inst) -> c_int;
        type Free = unsafe extern "C" fn(Inst);
        let (term, free) = match self.version {
            FmiVersion::V2 => ("fmi2Terminate", "fmi2FreeInstance"),
            FmiVersion::V3 => ("fmi3Terminate", "fmi3FreeInstance"),
        };
        // SAFETY: the standard's signatures; the instance is live until freed here.
        unsafe {
            if let Ok(f) = self.lib.get::<F>(term.as_bytes()) {
                f(self.inst);
            }
            if let Ok(f) = self.lib.get::<Free>(free.as_bytes()) {
                f(self.inst);
            }
        }
    }
}
