//! The route study of the extension module: a line's per-transition table and its variants'
//! summary, as `tiltsim route` computes them.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use tiltsim_studies::route::run::{process_cpu_s, RouteExec};
use tiltsim_studies::route::study::{transition_columns, Column};
use tiltsim_studies::route::{Grid, Limits, Running};

use crate::args::arg;
use crate::{directory, error, invalid, participant_exe, scenario_with, supervise};

/// Runs `scenarios` (each `(kind, value, origin)`) over the route file `route`; returns
/// `transitions` (the columns of `transitions.csv`), `variants` (one dict per variant, as
/// `route.json` has them), the journey times and the output directory (when written).
#[pyfunction]
#[pyo3(signature = (route, scenarios, rho=None, cd_tilting=None, cd_conventional=None,
                    accel=None, brake=None, running=None, jobs=None, transport=None, out=None,
                    exe=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn route<'py>(
    py: Python<'py>,
    route: Bound<'py, PyAny>,
    scenarios: Vec<(String, String, String)>,
    rho: Option<Bound<'py, PyAny>>,
    cd_tilting: Option<Bound<'py, PyAny>>,
    cd_conventional: Option<Bound<'py, PyAny>>,
    accel: Option<Bound<'py, PyAny>>,
    brake: Option<Bound<'py, PyAny>>,
    running: Option<Bound<'py, PyAny>>,
    jobs: Option<Bound<'py, PyAny>>,
    transport: Option<Bound<'py, PyAny>>,
    out: Option<Bound<'py, PyAny>>,
    exe: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let f = "route";
    let route = arg(f, "route_file", &Some(route))
        .path()?
        .unwrap_or_default();
    let jobs = arg(f, "jobs", &jobs).count(1, 256)?;
    let transport = arg(f, "transport", &transport).text(crate::TRANSPORTS)?;
    let out = arg(f, "out", &out).path()?;
    // Every argument is checked before the route file is read.
    let (grid, limits) = grid_and_limits(
        py,
        [&rho, &cd_tilting],
        [&cd_conventional, &accel, &brake],
        &running,
    )?;
    let line = tiltsim_studies::route::load(&route).map_err(|e| invalid(py, e.to_string()))?;
    let loaded = load(py, &scenarios, transport)?;
    let exe = match loaded.first() {
        Some(s) => participant_exe(py, exe, s)?,
        None => PathBuf::from("tiltsim"),
    };
    let variants = tiltsim_studies::route::variants(&loaded, &limits, &grid);
    let (dir, _scratch) = directory(py, out.as_deref(), "route")?;
    let interrupt = Arc::new(AtomicBool::new(false));
    let jobs = jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let ex = RouteExec {
        out: dir.clone(),
        jobs,
        keep_runs: false,
        exe,
        interrupt: interrupt.clone(),
    };
    let write = out.is_some();
    let (done, raised) = supervise(py, &interrupt, (&|| 0u64, 0), None, move || {
        let (t0, c0) = (std::time::Instant::now(), process_cpu_s());
        let results = tiltsim_studies::route::study(&line, &variants, &ex)?;
        let cost = tiltsim_studies::route::outputs::Cost {
            wall_s: t0.elapsed().as_secs_f64(),
            cpu_s: process_cpu_s() - c0,
            jobs: ex.jobs,
        };
        let written = if write {
            tiltsim_studies::route::outputs::write(&ex.out, &line, &limits, &results, cost)
                .map(|_| ())
                .map_err(|e| format!("{}: {e}", ex.out.display()))
        } else {
            Ok(())
        };
        Some((
            results,
            tiltsim_studies::route::outputs::Journey::of(&line, &limits),
            written,
        ))
    });
    if let Some(e) = raised {
        return Err(e);
    }
    let Some((results, journey, written)) = done else {
        return Err(error(
            py,
            "Interrupted",
            "interrupted: nothing written".into(),
        ));
    };
    written.map_err(|e| error(py, "ParticipantError", e))?;
    let table = transitions(py, &results)?;
    let json = |v: &dyn erased::Ser| -> PyResult<Bound<'py, PyAny>> {
        let text = v.json().map_err(|e| error(py, "TiltsimError", e))?;
        py.import("json")?.call_method1("loads", (text,))
    };
    let result = PyDict::new(py);
    result.set_item("transitions", table)?;
    result.set_item("variants", json(&results)?)?;
    result.set_item("journey", json(&journey)?)?;
    result.set_item("out_dir", out.map(|o| o.display().to_string()))?;
    Ok(result)
}

/// The variants' grid and the profiles' limits the call asks for, checked.
/// The route's scenarios, in-process by default as `tiltsim route`.
fn load(
    py: Python<'_>,
    scenarios: &[(String, String, String)],
    transport: Option<String>,
) -> PyResult<Vec<tiltsim_scenario::scenario::Scenario>> {
    let transport = transport.or(Some("in-process".into()));
    let mut loaded = Vec::new();
    for (kind, value, origin) in scenarios {
        loaded.push(scenario_with(
            py,
            kind,
            value,
            origin,
            Vec::new(),
            transport.clone(),
            None,
            None,
            None,
        )?);
    }
    Ok(loaded)
}

/// The transitions' columns as `{name: array or list}`.
fn transitions<'py>(
    py: Python<'py>,
    results: &[tiltsim_studies::route::study::VariantResult],
) -> PyResult<Bound<'py, PyDict>> {
    let table = PyDict::new(py);
    for (name, col) in transition_columns(results) {
        match col {
            Column::Num(v) => table.set_item(name, PyArray1::from_vec(py, v))?,
            Column::Text(v) => table.set_item(name, PyList::new(py, v)?)?,
        }
    }
    Ok(table)
}

/// The grid of variants and the speed limits from `rho` and `cd_tilting` (lists),
/// `cd_conventional`, `accel` and `brake` (numbers) and `running`, each named in its error.
fn grid_and_limits<'py>(
    py: Python<'py>,
    [rho, cd_tilting]: [&Option<Bound<'py, PyAny>>; 2],
    [cd_conventional, accel, brake]: [&Option<Bound<'py, PyAny>>; 3],
    running: &Option<Bound<'py, PyAny>>,
) -> PyResult<(Grid, Limits)> {
    let f = "route";
    let rho = arg(f, "rho", rho).numbers("compensation factors rho")?;
    let cd_tilting = arg(f, "cd_tilting", cd_tilting).numbers("cant deficiencies in mm")?;
    let cd = |name, v, what, default| -> PyResult<f64> {
        Ok(arg(f, name, v).number(what)?.unwrap_or(default))
    };
    let cd_conventional = cd(
        "cd_conventional",
        cd_conventional,
        "a cant deficiency in mm",
        150.0,
    )?;
    let accel = cd("accel", accel, "an acceleration in m/s2", 0.5)?;
    let brake = cd("brake", brake, "a deceleration in m/s2", 0.6)?;
    let running = arg(f, "running", running).text(r#""conventional" or "tilting""#)?;
    let grid = Grid {
        rho: rho.unwrap_or_default(),
        cd_tilting_mm: cd_tilting.unwrap_or_default(),
        running: match running.as_deref() {
            None | Some("auto") => None,
            Some("conventional") => Some(Running::Conventional),
            Some("tilting") => Some(Running::Tilting),
            Some(o) => {
                return Err(invalid(
                    py,
                    format!("running = {o:?}: allowed \"auto\", \"conventional\", \"tilting\""),
                ))
            }
        },
    };
    grid.check().map_err(|e| invalid(py, e))?;
    for (what, v, hi) in [
        ("cd_conventional", cd_conventional, 400.0),
        ("accel", accel, 5.0),
        ("brake", brake, 5.0),
    ] {
        if !(v.is_finite() && v > 0.0 && v <= hi) {
            return Err(invalid(
                py,
                format!("{what} = {v}: allowed above 0 and up to {hi}"),
            ));
        }
    }
    let limits = Limits {
        cant_deficiency_conventional_mm: cd_conventional,
        cant_deficiency_tilting_mm: grid.cd_tilting_mm.first().copied().unwrap_or(275.0),
        accel_m_s2: accel,
        brake_m_s2: brake,
    };
    Ok((grid, limits))
}

/// Serialising the results to JSON text behind one object-safe trait.
mod erased {
    pub trait Ser {
        fn json(&self) -> Result<String, String>;
    }
    impl<T: serde::Serialize> Ser for T {
        fn json(&self) -> Result<String, String> {
            serde_json::to_string(self).map_err(|e| e.to_string())
        }
    }
}
