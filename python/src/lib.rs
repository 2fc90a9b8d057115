//! `tiltsim._tiltsim`, the extension module under the `tiltsim` Python package: runs,
//! sweeps, comparisons and the linear design through the library crates, in this process.
//!
//! The simulation runs on a thread of its own while the calling thread waits with the GIL
//! released; every 50 ms it takes the GIL back to look for Ctrl-C (which sets the run's
//! interrupt flag, as SIGINT does for the command line) and to call the progress callback.
//! A run's rows stay where the engine kept them: each column reaches Python as a read-only
//! NumPy view into them (a stride of one row), without a copy. Errors are raised as the
//! classes of `tiltsim.errors`, with the message the command line prints.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use numpy::ndarray::{ArrayView1, ShapeBuilder};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use tiltsim_formats::table::{Row, COLUMNS, OFFSETS, TYPES};
use tiltsim_master::engine::outputs::Outputs;
use tiltsim_master::engine::{RunError, RunOptions};
use tiltsim_scenario::scenario::{Execution, Master, Scenario, Transport};

mod args;
mod route;
mod studies;

use args::arg;

/// What a `transport` argument allows.
const TRANSPORTS: &str = r#""in-process" or "ipc""#;

use studies::{compare, falsify, linearize, parse_grid, sweep};

/// How often the waiting thread looks for Ctrl-C and reports progress.
const POLL: Duration = Duration::from_millis(50);

/// An exception of `tiltsim.errors` by class name, carrying `message`.
fn error(py: Python<'_>, class: &str, message: String) -> PyErr {
    let made = py
        .import("tiltsim.errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.call1((message.clone(),)));
    match made {
        Ok(e) => PyErr::from_value(e),
        Err(e) => e,
    }
}

/// Invalid input: names the origin, the field and what is allowed.
fn invalid(py: Python<'_>, message: impl Into<String>) -> PyErr {
    error(py, "ScenarioError", message.into())
}

/// The scenario a Python call names: `kind` is `file` (a path), `toml` (TOML text) or
/// `json` (a dict, as JSON text); `origin` names it in messages.
fn scenario(py: Python<'_>, kind: &str, value: &str, origin: &str) -> PyResult<Scenario> {
    let parsed = match kind {
        "file" => Scenario::load(Path::new(value)),
        "toml" => Scenario::parse(value, Path::new(origin)),
        "json" => {
            let text = serde_json::from_str::<serde_json::Value>(value)
                .map_err(|e| e.to_string())
                .and_then(|v| toml::Value::try_from(v).map_err(|e| e.to_string()))
                .and_then(|v| toml::to_string(&v).map_err(|e| e.to_string()))
                .map_err(|e| {
                    invalid(
                        py,
                        format!("{origin}: not a scenario table (numbers, strings, booleans, lists and tables only; no None): {e}"),
                    )
                })?;
            Scenario::parse(&text, Path::new(origin))
        }
        other => return Err(invalid(py, format!("scenario kind `{other}`"))),
    };
    let mut s = parsed.map_err(|e| invalid(py, e.to_string()))?;
    if s.name.is_empty() {
        s.name = "scenario".into();
    }
    Ok(s)
}

/// The options a call adds to its scenario, as the command line's flags do.
#[derive(Default)]
struct Overrides {
    settings: Vec<(String, String)>,
    transport: Option<String>,
    master: Option<String>,
    seed: Option<u64>,
    duration: Option<f64>,
    /// `"lock-step"` or `"free"`, as the call gave it.
    execution: Option<String>,
    /// The run replays a free run's timing trace.
    timing_replay: bool,
}

impl Overrides {
    /// The overrides entry point `f` was given: `settings`, then `transport`, `master`,
    /// `seed`, `duration` and `execution` as Python objects, each checked by name.
    fn of_call(
        f: &'static str,
        settings: Vec<(String, String)>,
        [transport, master, seed, duration, execution]: [&Option<Bound<'_, PyAny>>; 5],
        timing_replay: bool,
    ) -> PyResult<Overrides> {
        Ok(Overrides {
            settings,
            transport: arg(f, "transport", transport).text(TRANSPORTS)?,
            master: arg(f, "master", master).text(r#""gauss-seidel" or "jacobi""#)?,
            seed: arg(f, "seed", seed).whole(0, u64::MAX)?,
            duration: arg(f, "duration", duration).number("a duration in s")?,
            execution: arg(f, "execution", execution).text(r#""lock-step" or "free""#)?,
            timing_replay,
        })
    }

    fn apply(&self, py: Python<'_>, mut s: Scenario, origin: &str) -> PyResult<Scenario> {
        if let Some(t) = &self.transport {
            s.run.transport = match t.as_str() {
                "in-process" => Transport::InProcess,
                "ipc" => Transport::Ipc,
                t => {
                    return Err(invalid(
                        py,
                        format!("transport = {t:?}: allowed \"in-process\" or \"ipc\""),
                    ))
                }
            };
        }
        if let Some(m) = &self.master {
            s.run.master = match m.as_str() {
                "gauss-seidel" => Master::GaussSeidel,
                "jacobi" => Master::Jacobi,
                m => {
                    return Err(invalid(
                        py,
                        format!("master = {m:?}: allowed \"gauss-seidel\" or \"jacobi\""),
                    ))
                }
            };
        }
        if let Some(seed) = self.seed {
            s.run.seed = seed;
        }
        if let Some(d) = self.duration {
            if !(1e-5..=3600.0).contains(&d) {
                return Err(invalid(
                    py,
                    format!("duration = {d}: allowed 1e-05 to 3600 s"),
                ));
            }
            s.run.duration_s = Some(d);
        }
        for (k, v) in &self.settings {
            s = s
                .with_setting(k.trim(), v)
                .map_err(|e| invalid(py, format!("{origin}: set {k}={v}: {e}")))?;
        }
        match self.execution.as_deref() {
            None => {}
            Some("lock-step") | Some("lockstep") => s.run.execution = Execution::LockStep,
            Some("free") => s.run.execution = Execution::Free,
            Some(other) => {
                return Err(invalid(
                    py,
                    format!("execution = \"{other}\": allowed \"lock-step\" or \"free\""),
                ))
            }
        }
        if self.timing_replay {
            tiltsim_runner::pipeline::as_timing_replay(&mut s);
        }
        let errors = s.validate();
        if !errors.is_empty() {
            let lines: Vec<String> = errors.iter().map(|e| format!("{origin}: {e}")).collect();
            return Err(invalid(py, lines.join("\n")));
        }
        Ok(s)
    }
}

/// A directory of this process for a study that keeps no files; removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(what: &str) -> std::io::Result<Self> {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "tiltsim-py-{what}-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir)?;
        Ok(Scratch(dir))
    }
}

/// The directory a study writes into: `out` when given, else a [`Scratch`] directory for
/// `what` (held by the caller until the study's files are no longer needed).
fn directory(
    py: Python<'_>,
    out: Option<&Path>,
    what: &str,
) -> PyResult<(PathBuf, Option<Scratch>)> {
    match out {
        Some(o) => Ok((o.to_path_buf(), None)),
        None => {
            let s = Scratch::new(what)
                .map_err(|e| error(py, "ParticipantError", format!("temporary directory: {e}")))?;
            Ok((s.0.clone(), Some(s)))
        }
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `work` on a thread of its own and waits for it with the GIL released. Every
/// [`POLL`] it looks for Ctrl-C (or any signal Python raises for) and calls `progress`
/// with `(done, total)` read from `counter`; a signal or a callback that raises sets
/// `interrupt`, the work ends as interrupted, and the error is handed back with its result.
fn supervise<T: Send + 'static>(
    py: Python<'_>,
    interrupt: &Arc<AtomicBool>,
    counter: (&dyn Fn() -> u64, u64),
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce() -> T + Send + 'static,
) -> (T, Option<PyErr>) {
    let (tx, rx) = mpsc::channel();
    let worker = std::thread::spawn(move || {
        let _ = tx.send(work());
    });
    let mut raised: Option<PyErr> = None;
    let mut told = u64::MAX;
    let mut rx = Some(rx);
    let result = loop {
        let held = rx.take();
        let (got, back) = py.detach(move || {
            let r = held.map(|rx| (rx.recv_timeout(POLL), rx));
            match r {
                Some((got, rx)) => (got, Some(rx)),
                None => (Err(mpsc::RecvTimeoutError::Disconnected), None),
            }
        });
        rx = back;
        match got {
            Ok(r) => break Some(r),
            Err(mpsc::RecvTimeoutError::Disconnected) => break None,
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if raised.is_none() {
            if let Err(e) = py.check_signals() {
                interrupt.store(true, Ordering::Relaxed);
                raised = Some(e);
            }
        }
        if let (Some(cb), None) = (progress, &raised) {
            let done = (counter.0)();
            if done != told {
                told = done;
                if let Err(e) = cb.call1((done, counter.1)) {
                    interrupt.store(true, Ordering::Relaxed);
                    raised = Some(e);
                }
            }
        }
    };
    let joined = py.detach(|| worker.join());
    match (result, joined) {
        (Some(r), _) => {
            if let (Some(cb), None) = (progress, &raised) {
                let done = (counter.0)();
                if done != told {
                    if let Err(e) = cb.call1((done, counter.1)) {
                        raised = Some(e);
                    }
                }
            }
            (r, raised)
        }
        // The worker panicked: a defect, reported as one rather than taking Python down.
        (None, Err(p)) => {
            let why = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            std::panic::resume_unwind(Box::new(format!("tiltsim worker panicked: {why}")))
        }
        (None, Ok(())) => unreachable!("the worker sends its result before it ends"),
    }
}

/// The rows of a run, owned here; NumPy arrays view them in place.
#[pyclass(frozen, module = "tiltsim._tiltsim")]
struct Rows {
    rows: Vec<Row>,
}

/// A read-only view of column `k` of `rows` (every `size_of::<Row>()` bytes from its offset).
///
/// # Safety
/// `owner` must own `rows`, which must not change while any view of them lives.
unsafe fn column_view<'py, T: numpy::Element>(
    owner: &Bound<'py, Rows>,
    rows: &[Row],
    k: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let stride = std::mem::size_of::<Row>() / std::mem::size_of::<T>();
    debug_assert_eq!(std::mem::size_of::<Row>() % std::mem::size_of::<T>(), 0);
    debug_assert_eq!(OFFSETS[k] % std::mem::align_of::<T>(), 0);
    let array = if rows.is_empty() {
        PyArray1::<T>::zeros(owner.py(), 0, false)
    } else {
        let first = (rows.as_ptr() as *const u8).add(OFFSETS[k]) as *const T;
        let view = ArrayView1::from_shape_ptr((rows.len(),).strides((stride,)), first);
        PyArray1::borrow_from_array(&view, owner.clone().into_any())
    };
    array.readwrite().make_nonwriteable();
    Ok(array.into_any())
}

/// Every column of `rows` as a read-only NumPy array viewing them in place, by name.
fn columns<'py>(py: Python<'py>, rows: Vec<Row>) -> PyResult<Bound<'py, PyDict>> {
    let owner = Bound::new(py, Rows { rows })?;
    let out = PyDict::new(py);
    let held = owner.get();
    for (k, name) in COLUMNS.iter().enumerate() {
        // SAFETY: `owner` owns the rows and is frozen: they are never changed or moved.
        let a = unsafe {
            match TYPES[k] {
                "f64" => column_view::<f64>(&owner, &held.rows, k)?,
                "u64" => column_view::<u64>(&owner, &held.rows, k)?,
                "u32" => column_view::<u32>(&owner, &held.rows, k)?,
                "i32" => column_view::<i32>(&owner, &held.rows, k)?,
                "i64" => column_view::<i64>(&owner, &held.rows, k)?,
                t => {
                    return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                        "column {name}: type {t} has no NumPy view"
                    )))
                }
            }
        };
        out.set_item(*name, a)?;
    }
    Ok(out)
}

/// The scenario a call names, with its overrides applied.
#[allow(clippy::too_many_arguments)]
fn scenario_with(
    py: Python<'_>,
    kind: &str,
    value: &str,
    origin: &str,
    settings: Vec<(String, String)>,
    transport: Option<String>,
    master: Option<String>,
    seed: Option<u64>,
    duration: Option<f64>,
) -> PyResult<Scenario> {
    let s = scenario(py, kind, value, origin)?;
    Overrides {
        settings,
        transport,
        master,
        seed,
        duration,
        execution: None,
        timing_replay: false,
    }
    .apply(py, s, origin)
}

/// The executable that serves participant processes (the IPC transport).
fn participant_exe(py: Python<'_>, exe: Option<String>, s: &Scenario) -> PyResult<PathBuf> {
    match exe {
        Some(e) => Ok(PathBuf::from(e)),
        None if s.run.transport == Transport::Ipc => Err(invalid(
            py,
            "transport = \"ipc\": no tiltsim executable found to serve the participants (install the package's `tiltsim` command, or pass exe=PATH)",
        )),
        // Not started with the in-process transport.
        None => Ok(PathBuf::from("tiltsim")),
    }
}

/// The exception of a job that could not be carried out.
fn job_error(py: Python<'_>, e: tiltsim_runner::pipeline::JobError, origin: &str) -> PyErr {
    use tiltsim_runner::pipeline::JobError;
    match e {
        JobError::Run(r) => run_error(py, r, origin),
        JobError::Invalid(m) => invalid(py, m),
        JobError::Trace(t) => invalid(py, t.to_string()),
        JobError::Failed(m) => error(py, "ParticipantError", format!("{origin}: {m}")),
    }
}

/// The message of a run that could not start or end.
fn run_error(py: Python<'_>, e: RunError, origin: &str) -> PyErr {
    match e {
        RunError::Interrupted { .. } => error(py, "Interrupted", format!("{origin}: {e}")),
        e => error(py, "ParticipantError", format!("{origin}: {e}")),
    }
}

/// Runs a scenario; returns `{"summary": JSON text, "columns": {name: array}, "out_dir":
/// str or None}`. With `out` the run writes its files there as `tiltsim run` does (figures
/// when `plots`); without, it keeps its rows in memory and leaves no file.
#[pyfunction]
#[pyo3(signature = (kind, value, origin, settings, out=None, transport=None, master=None,
                    seed=None, duration=None, record=None, plots=None, exe=None,
                    progress=None, execution=None, replay_trace=None))]
#[allow(clippy::too_many_arguments)]
fn run<'py>(
    py: Python<'py>,
    kind: &str,
    value: &str,
    origin: &str,
    settings: Vec<(String, String)>,
    out: Option<Bound<'py, PyAny>>,
    transport: Option<Bound<'py, PyAny>>,
    master: Option<Bound<'py, PyAny>>,
    seed: Option<Bound<'py, PyAny>>,
    duration: Option<Bound<'py, PyAny>>,
    record: Option<Bound<'py, PyAny>>,
    plots: Option<Bound<'py, PyAny>>,
    exe: Option<String>,
    progress: Option<Bound<'py, PyAny>>,
    execution: Option<Bound<'py, PyAny>>,
    replay_trace: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let started = std::time::Instant::now();
    let f = if replay_trace.is_some() {
        "replay_timing"
    } else {
        "run"
    };
    let out = arg(f, "out", &out).path()?;
    let record = arg(f, "record", &record).flag()?;
    let plots = arg(f, "plots", &plots).flag()?;
    let given = [&transport, &master, &seed, &duration, &execution];
    let s = Overrides::of_call(f, settings, given, replay_trace.is_some())?.apply(
        py,
        scenario(py, kind, value, origin)?,
        origin,
    )?;
    let exe = participant_exe(py, exe, &s)?;
    let (dir, scratch) = directory(py, out.as_deref(), "run")?;
    let interrupt = Arc::new(AtomicBool::new(false));
    let ticks = Arc::new(AtomicU64::new(0));
    let ticks_seen = ticks.clone();
    let mut opts = RunOptions::new(dir.clone(), exe);
    opts.interrupt = interrupt.clone();
    opts.plots = plots;
    let steps = s.steps();
    let file = origin.to_string();
    let keep_files = out.is_some();
    let (ran, raised) = supervise(
        py,
        &interrupt,
        (&|| ticks.load(Ordering::Relaxed), steps),
        progress.as_ref(),
        move || {
            let mut job = tiltsim_runner::pipeline::Job::new(&s, file, opts);
            job.replay_trace = replay_trace;
            job.outputs = Outputs {
                record,
                ticks_done: Some(ticks_seen),
                ..Outputs::default()
            };
            carry_out(job, keep_files)
        },
    );
    drop(scratch);
    let library_s = started.elapsed().as_secs_f64();
    let done = ran.map_err(|e| job_error(py, e, origin))?;
    if let Some(e) = raised {
        if !e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
            return Err(e);
        }
    }
    run_result(py, done, out.as_deref(), library_s)
}

/// Carries out `job`; with `keep_files` its files stay in its directory and the arrays are
/// read back from them, otherwise the rows are kept in memory and the directory is a scratch
/// one, removed afterwards.
fn carry_out(
    mut job: tiltsim_runner::pipeline::Job<'_>,
    keep_files: bool,
) -> Result<tiltsim_runner::pipeline::Done, tiltsim_runner::pipeline::JobError> {
    let out_dir = job.opts.out_dir.clone();
    job.claim = keep_files;
    job.outputs.rows_in_memory = !keep_files;
    let done = tiltsim_runner::pipeline::carry_out(job)?;
    if !keep_files {
        return Ok(done);
    }
    // What the run wrote is what the arrays hold.
    let rows = tiltsim_formats::table::read_rows(&out_dir).map_err(|e| {
        tiltsim_runner::pipeline::JobError::Failed(format!("{}: {e}", out_dir.display()))
    })?;
    Ok(tiltsim_runner::pipeline::Done { rows, ..done })
}

/// What `run` returns to Python: the summary's JSON text, the columns, the directory and the
/// library's time; the run's warnings raised as Python warnings.
fn run_result<'py>(
    py: Python<'py>,
    done: tiltsim_runner::pipeline::Done,
    out: Option<&std::path::Path>,
    library_s: f64,
) -> PyResult<Bound<'py, PyDict>> {
    for w in &done.warnings {
        let warnings = py.import("warnings")?;
        warnings.call_method1("warn", (w.as_str(),))?;
    }
    let (summary, rows) = (done.summary, done.rows);
    let result = PyDict::new(py);
    result.set_item(
        "summary",
        serde_json::to_string(&summary).unwrap_or_default(),
    )?;
    result.set_item("columns", columns(py, rows)?)?;
    result.set_item("out_dir", out.map(|o| o.display().to_string()))?;
    result.set_item("library_s", library_s)?;
    Ok(result)
}

/// The columns of a run's time series: `(name, unit, description)` in order.
#[pyfunction]
fn signals() -> Vec<(String, String, String)> {
    tiltsim_formats::columns::timeseries()
        .into_iter()
        .map(|c| (c.name, c.unit, c.description))
        .collect()
}

/// The command line, `tiltsim ARGS...`; returns its exit code. Participant processes of an
/// IPC run are served by the package's `tiltsim` command through it.
#[pyfunction]
fn cli(py: Python<'_>, argv: Vec<String>) -> i32 {
    py.detach(|| orchestrator::cli::main_from(argv))
}

/// The extension module.
#[pymodule]
fn _tiltsim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(falsify, m)?)?;
    m.add_function(wrap_pyfunction!(route::route, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(linearize, m)?)?;
    m.add_function(wrap_pyfunction!(signals, m)?)?;
    m.add_function(wrap_pyfunction!(parse_grid, m)?)?;
    m.add_function(wrap_pyfunction!(cli, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BUILD", tiltsim_studies::sweep::identity::build())?;
    Ok(())
}
