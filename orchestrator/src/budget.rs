//! What a run will write, estimated before it starts, against the space the output directory
//! has: a run whose files cannot fit is refused with the estimate, one that would take a large
//! share of the disk is warned about. Memory is not estimated: the engine and the analysis
//! hold a constant amount whatever the run's length (`record`, `cosim::stats::Timings`).

use std::path::Path;

use crate::scenario::Scenario;

/// Bytes per row of `timeseries.csv` used for the estimate: 35 columns, most of them of 17
/// significant digits once the run is under way (measured 380-405 B on paper-passive from 20 s
/// to 600 s, 300-330 B on the controlled scenarios); the largest possible row is
/// 35 × 24 + 34 = 874 B.
pub const ROW_BYTES: u64 = 420;
/// Bytes per tick of `trace.csv` (two or three exchanges of about 90 B each).
pub const TRACE_BYTES_PER_TICK: u64 = 270;
/// Above this share of the free space a run is warned about.
const WARN_SHARE: f64 = 0.25;

/// The estimated size of a run's outputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Rows of `timeseries.csv`.
    pub rows: u64,
    /// Bytes of every output (the time series, and the trace if asked for).
    pub bytes: u64,
}

/// What a run of `s` writes (`trace`: with `--trace`).
pub fn estimate(s: &Scenario, trace: bool) -> Estimate {
    let rows = s.steps();
    let per_row = ROW_BYTES + if trace { TRACE_BYTES_PER_TICK } else { 0 };
    Estimate {
        rows,
        bytes: rows.saturating_mul(per_row).saturating_add(64 * 1024),
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
pub fn check(s: &Scenario, dir: &Path, trace: bool) -> Verdict {
    let e = estimate(s, trace);
    let Some(free) = free_bytes(dir) else {
        return Verdict::Fits;
    };
    let what = format!(
        "{} steps (run.duration_s / run.dt_s) write about {} ({} B per row{})",
        e.rows,
        human(e.bytes),
        ROW_BYTES,
        if trace { ", with the trace" } else { "" }
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
        let paper = estimate(&s, false);
        assert_eq!(paper.rows, s.steps());
        assert!(matches!(
            check(&s, &std::env::temp_dir(), false),
            Verdict::Fits
        ));
        s.run.dt_s = 1e-5;
        s.run.duration_s = Some(3600.0);
        // 3.6e8 rows of 420 B: 151 GB.
        let e = estimate(&s, false);
        assert_eq!(e.rows, 360_000_000);
        assert_eq!(e.bytes, 360_000_000 * 420 + 65536);
        let free = free_bytes(&std::env::temp_dir()).unwrap();
        match check(&s, &std::env::temp_dir(), false) {
            Verdict::Refuse(m) if free < e.bytes => {
                assert!(m.contains("151.2 GB") && m.contains("run.dt_s"), "{m}")
            }
            Verdict::Warn(m) if free >= e.bytes => assert!(m.contains("151.2 GB"), "{m}"),
            Verdict::Fits if free / 4 >= e.bytes => {}
            v => panic!("{v:?} with {free} B free"),
        }
    }
}
