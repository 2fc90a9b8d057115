//! `tiltsim export-mcap RUN_DIR`: the `run.mcap` of a finished run, made from its files
//! (`timeseries.csv`, `events.csv`, `summary.json`, `scenario.toml`, and `trace.csv` and
//! `perf.json` when present), with the same channels and messages as `tiltsim run --record`
//! writes live (`tests/cli/record.rs` compares the two). What the files do not hold is rebuilt
//! exactly: the participants' outputs at t₀ (each model built from `scenario.toml`), and
//! what each link's sender sent, which is the sender's held output in the row the master
//! algorithm reads it from. Publish times come from `trace.csv` (ns from the loop's start)
//! when the run was traced, otherwise they equal the log times.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use cosim::msg::{FromActuator, FromController, FromPlant, ToController};
use cosim::participant::Participant;
use cosim::Role;
use tiltsim_formats::table::Row;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::{Master, Scenario};

use crate::engine::mcap::{EventMessage, McapRecorder, TickData};
use crate::engine::summary::deterministic;
use crate::engine::Inits;

/// Why a run could not be exported.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {what}")]
pub struct ExportError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong.
    pub what: String,
}

fn err(path: &Path, what: impl std::fmt::Display) -> ExportError {
    ExportError {
        path: path.to_path_buf(),
        what: what.to_string(),
    }
}

/// The outputs a row holds.
fn outputs(r: &Row) -> (FromPlant, FromActuator, FromController) {
    let p = FromPlant {
        t: r.time,
        s: r.s,
        curvature: r.curvature,
        cant: r.cant,
        x: [
            r.y_v, r.theta_v, r.y_b, r.theta_b, r.dy_v, r.dtheta_v, r.dy_b, r.dtheta_b, r.theta_r,
        ],
        psi: r.psi,
        lat_acc: r.lat_acc,
        theta_v_meas: r.theta_v_meas,
        ..Default::default()
    };
    let a = FromActuator {
        delta_a: r.delta_a,
        delta_a_ref: r.delta_a_ref,
        motor_torque: r.motor_torque,
        motor_speed: r.motor_speed,
        motor_current: r.motor_current,
        dc_power: r.dc_power,
        phase_current_peak: r.phase_current_peak,
        v_dc: r.v_dc,
        chopper_power: r.chopper_power,
        limits: r.actuator_limits,
        ..Default::default()
    };
    let c = FromController {
        delta_a_cmd: r.delta_a_cmd,
        theta_ref: r.theta_ref,
        theta_v_hat: r.theta_v_hat,
        solver_status: r.solver_status,
        ..Default::default()
    };
    (p, a, c)
}

/// Wall-clock (request sent, reply received) ns per (step, role).
type WallTimes = HashMap<(u64, Role), (u64, u64)>;

/// The line of a record, for messages (the header is line 1).
fn line_of(rec: &csv::StringRecord, index: usize) -> u64 {
    rec.position().map_or(index as u64 + 2, |p| p.line())
}

/// The wall-clock times of `trace.csv` (empty when the run was not traced). A damaged row is
/// an error naming the file and its line.
fn trace(dir: &Path) -> Result<WallTimes, ExportError> {
    let path = dir.join("trace.csv");
    let mut out = HashMap::new();
    if !path.exists() {
        return Ok(out);
    }
    let mut rd = tiltsim_formats::table::whole_lines(&path).map_err(|e| err(&path, e))?;
    for (i, rec) in rd.records().enumerate() {
        let rec = rec.map_err(|e| err(&path, e))?;
        let num = |i: usize| rec.get(i).and_then(|v| v.parse::<u64>().ok());
        let (Some(step), Some(role), Some(sent), Some(got)) =
            (num(0), rec.get(2).and_then(Role::parse), num(3), num(8))
        else {
            return Err(err(
                &path,
                format!(
                    "line {}: not a row of tiltsim's trace (step,t,participant,… with whole-number times)",
                    line_of(&rec, i)
                ),
            ));
        };
        // The last exchange of a (step, role) is the step's (tick 0 also has the Init one).
        out.insert((step, role), (sent, got));
    }
    Ok(out)
}

/// The events of `events.csv`; a damaged row is an error naming the file and its line.
fn events(dir: &Path) -> Result<Vec<EventMessage>, ExportError> {
    let path = dir.join("events.csv");
    let mut rd = tiltsim_formats::table::whole_lines(&path).map_err(|e| err(&path, e))?;
    let mut out = Vec::new();
    for (i, rec) in rd.records().enumerate() {
        let rec = rec.map_err(|e| err(&path, e))?;
        let line = line_of(&rec, i);
        if rec.len() != 6 {
            return Err(err(
                &path,
                format!(
                    "line {line}: {} fields, not the 6 of time,step,source,event,value,detail",
                    rec.len()
                ),
            ));
        }
        let f = |i: usize| rec.get(i).unwrap_or("").to_string();
        let bad = |what: &str| err(&path, format!("line {line}: {what}"));
        let kind: tiltsim_formats::events::EventKind = serde_json::from_value(f(3).into())
            .map_err(|_| bad(&format!("`{}` is not an event kind tiltsim writes", f(3))))?;
        out.push(EventMessage {
            t: f(0)
                .parse()
                .map_err(|_| bad("a time that is not a number"))?,
            step: f(1)
                .parse()
                .map_err(|_| bad("a step that is not a whole number"))?,
            source: f(2),
            kind: f(3),
            // An event without a value leaves the field empty.
            value: if f(4).is_empty() {
                f64::NAN
            } else {
                f(4).parse()
                    .map_err(|_| bad("a value that is not a number"))?
            },
            detail: f(5),
            level: crate::engine::mcap::level(kind),
        });
    }
    Ok(out)
}

/// The most a run's JSON file (`summary.json`, `perf.json`) may hold when read back.
const MAX_JSON_BYTES: u64 = 16 << 20;

/// Reads a run's JSON file, at most [`MAX_JSON_BYTES`] of it.
fn read_json(path: &Path) -> Result<serde_json::Value, ExportError> {
    use std::io::Read as _;
    let f = std::fs::File::open(path).map_err(|e| err(path, e))?;
    let mut text = String::new();
    f.take(MAX_JSON_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(|e| err(path, e))?;
    if text.len() as u64 > MAX_JSON_BYTES {
        return Err(err(
            path,
            format!("larger than {} MiB: not a run's file", MAX_JSON_BYTES >> 20),
        ));
    }
    serde_json::from_str(&text).map_err(|e| err(path, e))
}

/// Writes `dir/run.mcap` from the run's files; returns its path.
pub fn export(dir: &Path) -> Result<PathBuf, ExportError> {
    let sc = dir.join("scenario.toml");
    let s = Scenario::load(&sc).map_err(|e| err(&sc, e))?;
    let sp = dir.join("summary.json");
    let summary = read_json(&sp)?;
    let pp = dir.join("perf.json");
    let perf = if pp.exists() {
        read_json(&pp)?
    } else {
        serde_json::Value::Null
    };
    let events = events(dir)?;
    let wall = trace(dir)?;
    let mut held = initial_outputs(&s).map_err(|e| err(&sc, e))?;
    let path = dir.join("run.mcap");
    let mut rec = McapRecorder::create(&path, s.run.dt_s).map_err(|e| err(&path, e))?;
    rec.queue_events(events);
    rec.at_start(&held.0, &held.1).map_err(|e| err(&path, e))?;
    let period = s.controller_period_ticks();
    let gauss_seidel = s.run.master == Master::GaussSeidel;
    let mut failed: Option<std::io::Error> = None;
    let rows = tiltsim_formats::table::each_row(dir, |r| {
        // Row 0 holds the outputs at the start time, which no tick wrote; row k + 1 is tick k.
        let Some(k) = r.step.checked_sub(1) else {
            return true;
        };
        let (p, a, c) = outputs(r);
        let rx = [
            r.rx_actuator_command,
            r.rx_bar_angle,
            r.rx_measurement,
            r.rx_bar_twist,
        ];
        let tx = sent(&held, (&a, &c), gauss_seidel);
        let to_c = ToController {
            t: held.0.t,
            s: held.0.s,
            theta_v_meas: r.rx_measurement,
            ..Default::default()
        };
        let when = |role: Role| wall.get(&(k, role)).copied();
        let written = rec.write_tick(&TickData {
            k,
            due: k % period == 0,
            to_controller: &to_c,
            p: &p,
            a: &a,
            c: &c,
            rx: &rx,
            tx: &tx,
            wall: Role::ALL.map(when),
        });
        held = (p, a, c);
        match written {
            Ok(()) => true,
            Err(e) => {
                failed = Some(e);
                false
            }
        }
    })
    .map_err(|e| {
        // The reader's message names the file already.
        let p = dir.join("timeseries.csv");
        let m = e.to_string();
        let what = m.strip_prefix(&format!("{}: ", p.display())).unwrap_or(&m);
        err(&p, what)
    })?;
    if let Some(e) = failed {
        return Err(err(&path, e));
    }
    let dt_ns = (s.run.dt_s * 1e9).round() as u64;
    rec.close(
        &deterministic(summary),
        &perf,
        rows.saturating_sub(1) * dt_ns,
    )
    .map_err(|e| err(&path, e))
}

/// The outputs at t₀, as each participant gives them before its first step.
fn initial_outputs(s: &Scenario) -> Result<(FromPlant, FromActuator, FromController), String> {
    let inits = Inits::from(s);
    let p0 = plant_proc::Plant::new(&inits.plant).initial_output();
    let a0 = actuator_proc::Actuator::new(&inits.actuator).initial_output();
    let c0 = controller_proc::Controller::new(&inits.controller)?.initial_output();
    Ok((p0, a0, c0))
}

/// What each link sent in a tick (indexed by [`LinkId`]), from the outputs `held` of the
/// tick before and this tick's actuator and controller outputs `now`: Gauss-Seidel sends the
/// command and the bar angle of this tick, Jacobi the last.
fn sent(
    held: &(FromPlant, FromActuator, FromController),
    (a, c): (&FromActuator, &FromController),
    gauss_seidel: bool,
) -> [f64; 4] {
    let (hp, ha, hc) = held;
    let mut tx = [0.0; 4];
    tx[LinkId::Measurement as usize] = hp.theta_v_meas;
    tx[LinkId::BarTwist as usize] = hp.psi;
    tx[LinkId::ActuatorCommand as usize] = if gauss_seidel {
        c.delta_a_cmd
    } else {
        hc.delta_a_cmd
    };
    tx[LinkId::BarAngle as usize] = if gauss_seidel { a.delta_a } else { ha.delta_a };
    tx
}
