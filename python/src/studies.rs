//! The studies of the extension module: sweeps, comparisons, the linear design and the
//! command line's grids.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use tiltsim_master::engine::RunOptions;
use tiltsim_scenario::scenario::Scenario;
use tiltsim_studies::sweep::{Exec, Plan, Row, SweepError, Swept};

use crate::args::arg;
use crate::{directory, error, invalid, participant_exe, scenario_with, supervise, TRANSPORTS};

/// Runs a sweep; returns its samples' columns (as `samples.csv` has them), the tidy lateral
/// acceleration series (`series.csv`), whether it was interrupted and its directory.
#[pyfunction]
#[pyo3(signature = (kind, value, origin, settings, samples=None, spread=None, seed=None,
                    grid=None, jobs=None, transport=None, out=None, exe=None, progress=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn sweep<'py>(
    py: Python<'py>,
    kind: &str,
    value: &str,
    origin: &str,
    settings: Vec<(String, String)>,
    samples: Option<Bound<'py, PyAny>>,
    spread: Option<Bound<'py, PyAny>>,
    seed: Option<Bound<'py, PyAny>>,
    grid: Option<(String, Vec<f64>)>,
    jobs: Option<Bound<'py, PyAny>>,
    transport: Option<Bound<'py, PyAny>>,
    out: Option<Bound<'py, PyAny>>,
    exe: Option<String>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let samples = arg("sweep", "samples", &samples).count(1, 100_000)?;
    let spread = arg("sweep", "spread", &spread)
        .number("the relative spread of the Monte Carlo factors")?
        .unwrap_or(0.22);
    let seed = arg("sweep", "seed", &seed).whole(0, u64::MAX)?.unwrap_or(1);
    let jobs = arg("sweep", "jobs", &jobs).count(1, 256)?;
    let transport = arg("sweep", "transport", &transport).text(TRANSPORTS)?;
    let out = arg("sweep", "out", &out).path()?;
    // In-process by default, as `tiltsim sweep`.
    let transport = transport.or(Some("in-process".into()));
    let s = scenario_with(
        py, kind, value, origin, settings, transport, None, None, None,
    )?;
    let plan = sweep_plan(py, grid, samples, spread, seed)?;
    tiltsim_studies::sweep::check_plan(&s, &plan)
        .map_err(|e| invalid(py, format!("{origin}: {e}")))?;
    let exe = participant_exe(py, exe, &s)?;
    let (dir, _scratch) = directory(py, out.as_deref(), "sweep")?;
    let lock = tiltsim_rundir::outdir::claim(&dir, tiltsim_rundir::outdir::Kind::Sweep, "sweep")
        .map_err(|e| invalid(py, e.to_string()))?;
    let interrupt = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicUsize::new(0));
    let jobs = sweep_jobs(py, jobs)?;
    let ex = Exec {
        out: dir.clone(),
        jobs,
        keep_runs: false,
        exe,
        interrupt: interrupt.clone(),
        progress: false,
        samples_done: Some(done.clone()),
    };
    let total = plan.len() as u64;
    let write = out.is_some();
    let count = move || done.load(Ordering::Relaxed) as u64;
    let (swept, raised) = supervise(py, &interrupt, (&count, total), progress.as_ref(), {
        let plan = plan.clone();
        move || run_sweep(&s, &plan, &ex, write)
    });
    drop(lock);
    let swept = swept.map_err(|e| error(py, "ParticipantError", e.to_string()))?;
    if let Some(e) = raised {
        if !e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
            return Err(e);
        }
    }
    let result = PyDict::new(py);
    result.set_item("samples", samples_frame(py, &plan, &swept.rows)?)?;
    result.set_item("series", series_frame(py, &swept.rows)?)?;
    result.set_item("interrupted", swept.interrupted)?;
    result.set_item("out_dir", out.map(|o| o.display().to_string()))?;
    Ok(result)
}

/// The plan a sweep call asks for: a grid, or `samples` Monte Carlo samples.
fn sweep_plan(
    py: Python<'_>,
    grid: Option<(String, Vec<f64>)>,
    samples: Option<usize>,
    spread: f64,
    seed: u64,
) -> PyResult<Plan> {
    match (grid, samples) {
        (Some((key, values)), None) => {
            if key.trim().is_empty() || values.is_empty() {
                return Err(invalid(py, "grid: need a key and at least one value"));
            }
            Ok(Plan::Grid { key, values })
        }
        (None, Some(n)) if (1..=100_000).contains(&n) => {
            if !(0.0..1.0).contains(&spread) {
                return Err(invalid(
                    py,
                    format!("spread = {spread}: allowed 0 to 1 (1 excluded)"),
                ));
            }
            Ok(Plan::MonteCarlo {
                samples: n,
                spread,
                seed,
            })
        }
        (None, Some(n)) => Err(invalid(py, format!("samples = {n}: allowed 1 to 100000"))),
        _ => Err(invalid(
            py,
            "give samples=N (Monte Carlo) or grid=(KEY, VALUES), one of them",
        )),
    }
}

/// The parallel runs of a sweep: `jobs`, or one per CPU available.
fn sweep_jobs(py: Python<'_>, jobs: Option<usize>) -> PyResult<usize> {
    let jobs = jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if !(1..=256).contains(&jobs) {
        return Err(invalid(py, format!("jobs = {jobs}: allowed 1 to 256")));
    }
    Ok(jobs)
}

/// Runs the sweep of `s` by `plan`; writes its files to `ex.out` when `write`.
fn run_sweep(s: &Scenario, plan: &Plan, ex: &Exec, write: bool) -> Result<Swept, SweepError> {
    let swept = tiltsim_studies::sweep::run(s, plan, None, ex)?;
    if write {
        let build = tiltsim_studies::sweep::identity::build();
        tiltsim_studies::sweep::write_outputs(
            &ex.out,
            s,
            plan,
            None,
            &swept.rows,
            swept.interrupted,
            build,
        )
        .map_err(|e| SweepError::Files(format!("{}: {e}", ex.out.display())))?;
    }
    Ok(swept)
}

/// The samples' columns, as `samples.csv` has them: sample, parameters, status, metrics
/// and flags.
fn samples_frame<'py>(py: Python<'py>, plan: &Plan, rows: &[Row]) -> PyResult<Bound<'py, PyDict>> {
    let cols = plan.columns();
    let frame = PyDict::new(py);
    frame.set_item(
        tiltsim_studies::sweep::SAMPLE_COLUMN,
        PyArray1::from_iter(py, rows.iter().map(|r| r.sample as i64)),
    )?;
    for (k, c) in cols.iter().enumerate() {
        let v = rows
            .iter()
            .map(|r| r.params.get(k).copied().unwrap_or(f64::NAN));
        frame.set_item(c, PyArray1::from_iter(py, v))?;
    }
    let status: Vec<String> = rows.iter().map(|r| r.status.to_string()).collect();
    frame.set_item("status", PyList::new(py, status)?)?;
    for (m, metric) in tiltsim_assessment::comfort::METRICS.iter().enumerate() {
        let v = rows
            .iter()
            .map(|r| r.metrics.get(m).copied().unwrap_or(f64::NAN));
        frame.set_item(metric.key, PyArray1::from_iter(py, v))?;
    }
    let flags: Vec<String> = rows.iter().map(|r| r.flags.join("; ")).collect();
    frame.set_item(
        tiltsim_studies::sweep::FLAGS_COLUMN,
        PyList::new(py, flags)?,
    )?;
    Ok(frame)
}

/// The tidy lateral acceleration series of the samples, as `series.csv` has it.
fn series_frame<'py>(py: Python<'py>, rows: &[Row]) -> PyResult<Bound<'py, PyDict>> {
    let series = PyDict::new(py);
    let ids = rows
        .iter()
        .flat_map(|r| std::iter::repeat_n(r.sample as i64, r.series.len()));
    let times = rows
        .iter()
        .flat_map(|r| (0..r.series.len()).map(tiltsim_studies::sweep::series_time));
    let values = rows.iter().flat_map(|r| r.series.iter().copied());
    let [c_id, c_time, c_value] = tiltsim_studies::sweep::SERIES_COLUMNS;
    series.set_item(c_id, PyArray1::from_iter(py, ids))?;
    series.set_item(c_time, PyArray1::from_iter(py, times))?;
    series.set_item(c_value, PyArray1::from_iter(py, values))?;
    Ok(series)
}

/// Compares scenarios as `tiltsim compare` does; returns `table.csv`'s text, each run's
/// summary (JSON text) and the directory (the runs stay there only when `out` is given).
#[pyfunction]
#[pyo3(signature = (scenarios, transport=None, out=None, exe=None, progress=None))]
pub(crate) fn compare<'py>(
    py: Python<'py>,
    scenarios: Vec<(String, String, String)>,
    transport: Option<Bound<'py, PyAny>>,
    out: Option<Bound<'py, PyAny>>,
    exe: Option<String>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let transport = arg("compare", "transport", &transport).text(TRANSPORTS)?;
    let out = arg("compare", "out", &out).path()?;
    if scenarios.is_empty() {
        return Err(invalid(py, "compare: give at least one scenario"));
    }
    let mut loaded = Vec::new();
    for (kind, value, origin) in &scenarios {
        let s = scenario_with(
            py,
            kind,
            value,
            origin,
            Vec::new(),
            transport.clone(),
            None,
            None,
            None,
        )?;
        let exe = participant_exe(py, exe.clone(), &s)?;
        loaded.push((PathBuf::from(origin), s, exe));
    }
    let (dir, _scratch) = directory(py, out.as_deref(), "compare")?;
    let mut pairs: Vec<(PathBuf, Scenario)> = loaded
        .iter()
        .map(|(f, s, _)| (f.clone(), s.clone()))
        .collect();
    let notes = tiltsim_runner::compare::distinct(&mut pairs, &dir);
    let exe = loaded[0].2.clone();
    let interrupt = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let total = pairs.len() as u64;
    let (compared, raised) = supervise(
        py,
        &interrupt,
        (&|| done.load(Ordering::Relaxed), total),
        progress.as_ref(),
        {
            let interrupt = interrupt.clone();
            let done = done.clone();
            move || {
                use tiltsim_runner::compare::Comparison;
                let mut cmp = Comparison::start(&dir, &pairs)?;
                let mut base = RunOptions::new(dir.clone(), exe);
                base.interrupt = interrupt;
                base.plots = true;
                let mut summaries = Vec::new();
                for (file, s) in pairs {
                    let sm = cmp.run(&file, s, &base)?;
                    summaries.push(serde_json::to_string(sm).unwrap_or_default());
                    done.fetch_add(1, Ordering::Relaxed);
                }
                let (_, csv) = cmp.finish()?;
                Ok::<_, tiltsim_runner::compare::CompareError>((csv, summaries))
            }
        },
    );
    let (csv, summaries) = compared.map_err(|e| {
        use tiltsim_runner::compare::CompareError as E;
        match e {
            E::Invalid(m) => invalid(py, m),
            E::Failed(m) => error(py, "ParticipantError", m),
            E::Interrupted(m) => error(py, "Interrupted", m),
        }
    })?;
    if let Some(e) = raised {
        return Err(e);
    }
    let result = PyDict::new(py);
    result.set_item("table_csv", csv)?;
    result.set_item("summaries", summaries)?;
    result.set_item("notes", notes)?;
    result.set_item("out_dir", out.map(|o| o.display().to_string()))?;
    Ok(result)
}

/// The design model and the controller's gains (`tiltsim linearize`), as JSON text.
#[pyfunction]
#[pyo3(signature = (kind, value, origin, settings))]
pub(crate) fn linearize(
    py: Python<'_>,
    kind: &str,
    value: &str,
    origin: &str,
    settings: Vec<(String, String)>,
) -> PyResult<String> {
    let s = scenario_with(py, kind, value, origin, settings, None, None, None, None)?;
    let report = tiltsim_report::linearize::report(&s, None)
        .map_err(|e| invalid(py, format!("{origin}: controller design: {e}")))?;
    Ok(serde_json::to_string(&report).unwrap_or_default())
}

/// A grid as the command line's `--grid KEY=START:STOP:STEP` or `KEY=V1,V2,...` gives it:
/// `(key, values)`.
#[pyfunction]
pub(crate) fn parse_grid(py: Python<'_>, spec: &str) -> PyResult<(String, Vec<f64>)> {
    match tiltsim_studies::sweep::parse_grid(spec).map_err(|e| invalid(py, e.to_string()))? {
        Plan::Grid { key, values } => Ok((key, values)),
        Plan::MonteCarlo { .. } => Err(invalid(py, format!("grid `{spec}`"))),
    }
}

/// A falsifying search, as `tiltsim falsify`: the worst trace's text, the worst result
/// (`result.json`'s fields), the progress (`progress.csv`'s columns) and the directory.
#[pyfunction]
#[pyo3(signature = (kind, value, origin, settings, bounds, bounds_origin, objective=None,
                    requirement=None, budget=None, seed=None, jobs=None, out=None, shard=None,
                    restarts=None, margin=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn falsify<'py>(
    py: Python<'py>,
    kind: &str,
    value: &str,
    origin: &str,
    settings: Vec<(String, String)>,
    bounds: &str,
    bounds_origin: &str,
    objective: Option<Bound<'py, PyAny>>,
    requirement: Option<Bound<'py, PyAny>>,
    budget: Option<Bound<'py, PyAny>>,
    seed: Option<Bound<'py, PyAny>>,
    jobs: Option<Bound<'py, PyAny>>,
    out: Option<Bound<'py, PyAny>>,
    shard: Option<Bound<'py, PyAny>>,
    restarts: Option<Bound<'py, PyAny>>,
    margin: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let f = "falsify";
    let objective = arg(f, "objective", &objective)
        .text("a comfort metric of summary.json (a str: p_ct, p_ct_seated, lat_acc_peak, ...)")?;
    let requirement = arg(f, "requirement", &requirement).texts(
        "requirements, a str or a list of str (\"p_ct < 26\", \"valid\", \"always |lat_acc| < 1.2\")",
    )?;
    let shard = arg(f, "shard", &shard).text("a shard, a str \"I/N\"")?;
    let restarts = arg(f, "restarts", &restarts).count(1, 100_000)?;
    let margin = arg(f, "margin", &margin).numbers("the largest scale and the bisection steps")?;
    let budget = arg(f, "budget", &budget).whole(1, 100_000)?;
    let seed = arg(f, "seed", &seed).whole(0, u64::MAX)?.unwrap_or(1);
    let jobs = arg(f, "jobs", &jobs).count(1, 256)?;
    let out = arg(f, "out", &out).path()?;
    use tiltsim_studies::falsify::{self as fz, FalsifyError, Objective};
    let bad = |e: FalsifyError| match e {
        FalsifyError::Invalid(m) => invalid(py, m),
        e => error(py, "ParticipantError", e.to_string()),
    };
    let objective = match (objective, requirement) {
        (Some(_), Some(_)) => {
            return Err(invalid(py, "give objective or requirement, not both"));
        }
        (Some(o), None) => Objective::maximise(&o),
        (None, Some(r)) => Objective::requirements(&r),
        (None, None) => Objective::maximise("p_ct"),
    }
    .map_err(bad)?;
    let mut s = scenario_with(py, kind, value, origin, settings, None, None, None, None)?;
    fz::prepare(&mut s, origin).map_err(bad)?;
    let b = fz::Bounds::parse(bounds, bounds_origin).map_err(bad)?;
    b.ticks(&s, bounds_origin).map_err(bad)?;
    let budget = match budget {
        Some(n) => n as usize,
        None => fz::search::default_budget(&s, &b, bounds_origin)
            .map_err(bad)?
            .min(100_000),
    };
    let (shard, margin) = falsify_plan(py, &objective, budget, shard, restarts, margin)?;
    let spec = fz::Spec {
        bounds: b,
        bounds_from: bounds_origin.to_string(),
        objective,
        budget,
        seed,
        margin,
    };
    let (dir, _scratch) = directory(py, out.as_deref(), "falsify")?;
    let lock = tiltsim_rundir::outdir::claim(&dir, tiltsim_rundir::outdir::Kind::Sweep, "falsify")
        .map_err(|e| invalid(py, e.to_string()))?;
    let interrupt = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicUsize::new(0));
    let ex = fz::Exec {
        out: dir.clone(),
        jobs: sweep_jobs(py, jobs)?,
        exe: PathBuf::new(),
        interrupt: interrupt.clone(),
        done: Some(done.clone()),
    };
    let count = move || done.load(Ordering::Relaxed) as u64;
    let total = 2 * budget as u64;
    let (found, raised) = supervise(py, &interrupt, (&count, total), None, move || {
        match restarts {
            Some(n) if n > 1 => fz::shards::restarts(&s, &spec, n, &ex)
                .map(|(evals, o)| (evals.into_iter().map(|(_, e)| e).collect(), o)),
            _ => fz::falsify_part(&s, &spec, shard, &ex).map(|(f, o)| (f.evals, o)),
        }
        .map_err(|e| e.to_string())
    });
    drop(lock);
    if let Some(e) = raised {
        return Err(e);
    }
    let (evals, o) = found.map_err(|e| error(py, "ParticipantError", e))?;
    let result = falsify_result(py, &dir, &o)?;
    result.set_item("progress", progress_frame(py, &evals)?)?;
    result.set_item("out_dir", out.map(|o| o.display().to_string()))?;
    Ok(result)
}

/// How a search is carried out: the shard it is (`"I/N"`), and the timing margin's plan
/// (`(largest scale, bisection steps)`), checked against the objective and the budget.
fn falsify_plan(
    py: Python<'_>,
    objective: &tiltsim_studies::falsify::Objective,
    budget: usize,
    shard: Option<String>,
    restarts: Option<usize>,
    margin: Option<Vec<f64>>,
) -> PyResult<(
    Option<tiltsim_studies::sweep::Shard>,
    Option<tiltsim_studies::falsify::margin::MarginPlan>,
)> {
    let margin = match margin.as_deref() {
        None => None,
        Some(&[k, n]) if n >= 0.0 && n.fract() == 0.0 => Some((k, n as usize)),
        Some(_) => return Err(invalid(
            py,
            "falsify: margin: allowed (largest scale, bisection steps), the steps a whole number",
        )),
    };
    let shard = shard
        .map(|sh| tiltsim_studies::sweep::Shard::parse(&sh))
        .transpose()
        .map_err(|e| invalid(py, format!("shard: {e}")))?;
    if let Some(n) = restarts.filter(|n| *n == 0 || *n > budget) {
        return Err(invalid(
            py,
            format!("restarts = {n}: allowed 1 to the budget ({budget})"),
        ));
    }
    if let Some((k, steps)) = margin {
        if !(1.0..=100.0).contains(&k) || steps > 20 {
            return Err(invalid(
                py,
                format!("margin = ({k}, {steps}): allowed a largest scale from 1 to 100 and 0 to 20 bisection steps"),
            ));
        }
        if !objective.is_requirement() || shard.is_some() || restarts.is_some() {
            return Err(invalid(
                py,
                "margin: allowed with a requirement, and without shard or restarts",
            ));
        }
    }
    Ok((
        shard,
        margin.map(
            |(max_scale, steps)| tiltsim_studies::falsify::margin::MarginPlan { max_scale, steps },
        ),
    ))
}

/// The worst trace's text and the result's fields, for Python.
fn falsify_result<'py>(
    py: Python<'py>,
    dir: &std::path::Path,
    o: &tiltsim_studies::falsify::Outcome,
) -> PyResult<Bound<'py, PyDict>> {
    let trace = std::fs::read_to_string(dir.join("worst").join("timing.csv"))
        .map_err(|e| error(py, "ParticipantError", format!("worst/timing.csv: {e}")))?;
    let result = PyDict::new(py);
    result.set_item("trace", trace)?;
    let worst = PyDict::new(py);
    let json = serde_json::to_value(o).unwrap_or_default();
    if let Some(m) = json.as_object() {
        for (k, v) in m {
            match v {
                serde_json::Value::Number(n) => worst.set_item(k, n.as_f64())?,
                serde_json::Value::Bool(b) => worst.set_item(k, *b)?,
                v => worst.set_item(k, v.as_str().map_or(v.to_string(), str::to_string))?,
            }
        }
    }
    result.set_item("worst", worst)?;
    Ok(result)
}

/// A search's evaluations as `progress.csv` has them.
fn progress_frame<'py>(
    py: Python<'py>,
    evals: &[tiltsim_studies::falsify::search::Eval],
) -> PyResult<Bound<'py, PyDict>> {
    use tiltsim_studies::falsify as fz;
    let progress = PyDict::new(py);
    let col = |g: fn(&fz::search::Eval) -> f64| PyArray1::from_iter(py, evals.iter().map(g));
    let method: Vec<&str> = evals.iter().map(|e| e.method.name()).collect();
    progress.set_item("method", PyList::new(py, method)?)?;
    progress.set_item(
        "evaluation",
        PyArray1::from_iter(py, evals.iter().map(|e| e.evaluation as i64)),
    )?;
    let phase: Vec<&str> = evals.iter().map(|e| e.phase.name()).collect();
    progress.set_item("phase", PyList::new(py, phase)?)?;
    progress.set_item("metric", col(|e| e.metric))?;
    progress.set_item("objective", col(|e| e.objective))?;
    progress.set_item("margin", col(|e| e.margin))?;
    let violated: Vec<bool> = evals.iter().map(|e| e.violated).collect();
    progress.set_item("violated", PyList::new(py, violated)?)?;
    progress.set_item("best_so_far", col(|e| e.best_so_far))?;
    let valid: Vec<bool> = evals.iter().map(|e| e.valid).collect();
    progress.set_item("valid", PyList::new(py, valid)?)?;
    let flags: Vec<&str> = evals.iter().map(|e| e.flags.as_str()).collect();
    progress.set_item("flags", PyList::new(py, flags)?)?;
    Ok(progress)
}
