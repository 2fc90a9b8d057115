//! What a run will write, estimated before it starts, against the space the output directory
//! has: a run whose files cannot fit is refused with the estimate, one that would take a large
//! share of the disk is warned about. Memory is not estimated: the engine and the analysis
//! hold a constant amount whatever the run's length (`record`, `cosim::stats::Timings`).

use std::path::Path;

use tiltsim_scenario::scenario::Scenario;

/// Bytes per row of `timeseries.csv` with the ideal actuator: its drive columns stay 0, the
/// other 25 hold up to 17 significant digits once the run is under way (measured 373 B on
/// paper-passive's whole run, 300-330 B on controlled ones); 10 % above the largest measured.
pub const ROW_BYTES_IDEAL: u64 = 410;
/// Bytes per row with a modelled drive (`bldc`, the switched one, or `bldc-averaged`): its
/// torque, speed, current, power and voltage columns are full-width too (measured 599-608 B
/// on paper-lqg, paper-mpc, paper-pi and pi-drive); 10 % above the largest measured. The
/// largest possible row is 35 × 24 + 34 = 874 B.
pub const ROW_BYTES_DRIVE: u64 = 670;
/// Bytes per tick of `trace.csv` (`--trace`: two or three exchanges of about 90 B each;
/// measured 168-264 B on the paper's scenarios, in-process and over IPC).
pub const TRACE_BYTES_PER_TICK: u64 = 300;
/// Bytes per tick of `run.mcap` (`--record`: every participant's inputs and outputs and every
/// link, in zstd chunks; measured 386 B on paper-passive, 429-574 B on the controlled,
/// irregular-track and jittered scenarios); 10 % above the largest measured.
pub const RECORD_BYTES_PER_TICK: u64 = 640;
/// Bytes per tick of a free run's `timing.csv`: a line of about 60-75 B for the plant's and
/// the actuator's step of each tick and one per controller period (about 150 B a tick at a
/// 1 ms tick); a third above that.
pub const TIMING_BYTES_PER_TICK: u64 = 200;
/// Bytes per tick of the whole car's accelerations along the body, kept in the run's
/// directory until the analysis (three f64 a row).
pub const CAR_BYTES_PER_TICK: u64 = 24;
/// What every run writes whatever its length: figures (about 1 MB), summary, perf, events,
/// scenario.
pub const FIXED_BYTES: u64 = 2 << 20;

/// Bytes per row of `timeseries.csv` for the actuator model of `s`.
pub fn row_bytes(s: &Scenario) -> u64 {
    match s.actuator.model {
        actuator_proc::ActuatorModel::Ideal => ROW_BYTES_IDEAL,
        actuator_proc::ActuatorModel::Bldc | actuator_proc::ActuatorModel::BldcAveraged => {
            ROW_BYTES_DRIVE
        }
    }
}
/// Above this share of the free space a run is warned about.
const WARN_SHARE: f64 = 0.25;

/// The optional outputs a run writes (`tiltsim run --trace`, `--record`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Extras {
    /// `--trace`: `trace.csv`.
    pub trace: bool,
    /// `--record`: `run.mcap`.
    pub record: bool,
}

/// The estimated size of a run's outputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Rows of `timeseries.csv`.
    pub rows: u64,
    /// Bytes of every output (the time series, and the trace if asked for).
    pub bytes: u64,
}

/// What a run of `s` writes, with the optional outputs of `extras`.
pub fn estimate(s: &Scenario, extras: Extras) -> Estimate {
    let rows = s.steps();
    let per_row = row_bytes(s)
        + if extras.trace {
            TRACE_BYTES_PER_TICK
        } else {
            0
        }
        + if extras.record {
            RECORD_BYTES_PER_TICK
        } else {
            0
        }
        + if s.run.execution == tiltsim_scenario::scenario::Execution::Free {
            TIMING_BYTES_PER_TICK
        } else {
            0
        }
        + if !s.vehicle.model.is_half() {
            CAR_BYTES_PER_TICK
        } else {
            0
        };
    Estimate {
        rows,
        bytes: rows.saturating_mul(per_row).saturating_add(FIXED_BYTES),
    }
}

/// Free bytes for an unprivileged writer on the file system that holds `dir` (or its nearest
/// existing ancestor, since the directory may not exist yet).
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let abs = std::path::absolute(dir).ok()?;
    let existing = abs.ancestors().find(|p| p.exists())?;
    let c = std::ffi::CString::new(existing.as_os_str().as_encoded_bytes()).ok()?;
    // SAFETY: statvfs writes into the zeroed struct we own; the path is NUL-terminated.
    unsafe {
        let mut st: libc::statvfs = std::mem::zeroed();
        if libc::statvfs(c.as_ptr(), &mut st) != 0 {
            return None;
        }
        Some((st.f_bavail as u64).saturating_mul(st.f_frsize as u64))
    }
}

/// A size in the largest unit that keeps it above 1.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match b {
        _ if b >= 1e12 => format!("{:.1} TB", b / 1e12),
        _ if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        _ if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        _ => format!("{:.0} kB", b / 1e3),
    }
}

/// What the check found.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Fits comfortably (or the free space is unknown).
    Fits,
    /// Fits, but takes a large share of the free space: the message says how much.
    Warn(String),
    /// Does not fit: the message gives the estimate and the free space.
    Refuse(String),
}

/// Checks a run of `s` into `dir` against the free space there.
pub fn check(s: &Scenario, dir: &Path, extras: Extras) -> Verdict {
    let e = estimate(s, extras);
    let Some(free) = free_bytes(dir) else {
        return Verdict::Fits;
    };
    let with = match (extras.trace, extras.record) {
        (false, false) => "",
        (true, false) => ", with the trace",
        (false, true) => ", with the recording",
        (true, true) => ", with the trace and the recording",
    };
    let what = format!(
        "{} steps (run.duration_s / run.dt_s) write about {} ({} B per row of timeseries.csv for actuator.model{with})",
        e.rows,
        human(e.bytes),
        row_bytes(s),
    );
    if e.bytes > free {
        Verdict::Refuse(format!(
            "{what}, more than the {} free on the disk of {}; shorten the run, raise run.dt_s or choose --out on a larger disk",
            human(free),
            dir.display()
        ))
    } else if e.bytes as f64 > WARN_SHARE * free as f64 {
        Verdict::Warn(format!(
            "{what}, {:.0} % of the {} free on the disk of {}",
            100.0 * e.bytes as f64 / free as f64,
            human(free),
            dir.display()
        ))
    } else {
        Verdict::Fits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_hour_at_ten_microseconds_is_refused_on_any_ordinary_disk_and_a_paper_run_fits() {
        let mut s = Scenario::default();
        let none = Extras::default();
        let paper = estimate(&s, none);
        assert_eq!(paper.rows, s.steps());
        assert!(matches!(
            check(&s, &std::env::temp_dir(), none),
            Verdict::Fits
        ));
        s.run.dt_s = 1e-5;
        s.run.duration_s = Some(3600.0);
        // 3.6e8 rows of 670 B (the default actuator is the switched drive): 241 GB.
        let e = estimate(&s, none);
        assert_eq!(e.rows, 360_000_000);
        assert_eq!(e.bytes, 360_000_000 * 670 + (2 << 20));
        let free = free_bytes(&std::env::temp_dir()).unwrap();
        match check(&s, &std::env::temp_dir(), none) {
            Verdict::Refuse(m) if free < e.bytes => {
                assert!(m.contains("241.2 GB") && m.contains("run.dt_s"), "{m}")
            }
            Verdict::Warn(m) if free >= e.bytes => assert!(m.contains("241.2 GB"), "{m}"),
            Verdict::Fits if free / 4 >= e.bytes => {}
            v => panic!("{v:?} with {free} B free"),
        }
    }
}
