//! `tiltsim bench SCENARIO --concurrent N,...`: many IPC runs on one machine at once.
//!
//! For each count of runs and each count of CPU hogs, the hogs start (threads of this process
//! that only spin, stopped afterwards), then that many `tiltsim run SCENARIO --transport ipc`
//! at once; each run's process wall time (start to exit) and its lock-step loop's
//! (`summary.json` → `wall_time_s`) are taken, with the placement each run chose
//! (`timing.placement`) and the load average before and after. The runs write into a scratch
//! directory that is removed afterwards.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use super::common::write_json;
use super::error::{CliError, CliResult};

/// One row: `runs` runs beside `hogs` hogs.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Runs started at once.
    pub runs: usize,
    /// CPU hogs beside them.
    pub hogs: usize,
    /// Runs that exited with status 0 and wrote a summary.
    pub completed: usize,
    /// Each run's process wall time, start to exit (s), in start order.
    pub wall_s: Vec<f64>,
    /// Median of `wall_s` (s).
    pub wall_median_s: f64,
    /// From the first start to the last exit (s).
    pub total_s: f64,
    /// Each completed run's lock-step loop (`summary.json` → `wall_time_s`).
    pub loop_s: Vec<f64>,
    /// Median of `loop_s` (s); `None` when no run completed.
    pub loop_median_s: Option<f64>,
    /// How many runs chose each placement and wait (`reason/wait`).
    pub placements: std::collections::BTreeMap<String, usize>,
    /// 1-minute load average before the row and after it.
    pub load_before: Option<f64>,
    /// See `load_before`.
    pub load_after: Option<f64>,
}

/// Spinning threads until dropped.
struct Hogs {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Hogs {
    fn start(n: usize) -> Result<Hogs, CliError> {
        let mut hogs = Hogs {
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
        };
        for _ in 0..n {
            let stop = hogs.stop.clone();
            let t = std::thread::Builder::new()
                .name("hog".into())
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        core::hint::spin_loop();
                    }
                })
                .map_err(|e| CliError::Failed(format!("bench: cannot start a hog: {e}")))?;
            hogs.threads.push(t);
        }
        Ok(hogs)
    }
}

impl Drop for Hogs {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// The median (the lower of the middle two, as `tiltsim bench`'s), `None` when empty.
fn median(v: &[f64]) -> Option<f64> {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[(v.len() - 1) / 2])
}

/// The loop's wall time and the placement from a run's summary.
fn summary_of(out: &Path) -> Option<(f64, String)> {
    let text = std::fs::read_to_string(out.join("summary.json")).ok()?;
    let s: serde_json::Value = serde_json::from_str(&text).ok()?;
    let p = &s["timing"]["placement"];
    let placement = format!(
        "{}/{}",
        p["reason"].as_str().unwrap_or("none"),
        p["wait"].as_str().unwrap_or("?")
    );
    Some((s["wall_time_s"].as_f64()?, placement))
}

/// A run started by the bench: its process, when it started, and its directory.
type Started = (std::process::Child, Instant, std::path::PathBuf);

/// How a run ended: its exit (or why it has none), and its wall time (s).
type Ended = (std::io::Result<std::process::ExitStatus>, f64);

/// Starts `runs` IPC runs of `scenario` for `duration` s, each in `dir/r<k>`; if one cannot
/// start, those started are killed.
fn start_runs(
    exe: &Path,
    scenario: &Path,
    duration: f64,
    runs: usize,
    dir: &Path,
) -> Result<Vec<Started>, CliError> {
    let mut children = Vec::new();
    for k in 0..runs {
        let out = dir.join(format!("r{k}"));
        let child = std::process::Command::new(exe)
            .arg("run")
            .arg(scenario)
            .args(["--transport", "ipc", "--duration", &duration.to_string()])
            .arg("--out")
            .arg(&out)
            .arg("-q")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn();
        match child {
            Ok(c) => children.push((c, Instant::now(), out)),
            Err(e) => {
                for (mut c, _, _) in children {
                    let _ = c.kill();
                    let _ = c.wait();
                }
                return Err(CliError::Failed(format!("bench: cannot start a run: {e}")));
            }
        }
    }
    Ok(children)
}

/// Each run's end, taken when it happens (polled every 10 ms), whatever the order; a run
/// still going after `limit` is killed and ends with an error.
fn wait_for_all(children: &mut [Started], limit: std::time::Duration) -> Vec<Option<Ended>> {
    let mut ends: Vec<Option<Ended>> = children.iter().map(|_| None).collect();
    while ends.iter().any(Option::is_none) {
        for (i, (c, started, _)) in children.iter_mut().enumerate() {
            if ends[i].is_some() {
                continue;
            }
            match c.try_wait() {
                Ok(None) if started.elapsed() > limit => {
                    let _ = c.kill();
                    let _ = c.wait();
                    let late = std::io::Error::other("killed: did not end in time");
                    ends[i] = Some((Err(late), started.elapsed().as_secs_f64()));
                }
                Ok(None) => {}
                Ok(Some(st)) => ends[i] = Some((Ok(st), started.elapsed().as_secs_f64())),
                Err(e) => ends[i] = Some((Err(e), started.elapsed().as_secs_f64())),
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    ends
}

/// One row: `runs` runs of `scenario` for `duration` s beside `hogs` hogs, in `dir`.
fn row(
    exe: &Path,
    scenario: &Path,
    duration: f64,
    runs: usize,
    hogs: usize,
    dir: &Path,
) -> Result<Row, CliError> {
    let load_before = tiltsim_master::engine::machine::load_average();
    let _hogs = Hogs::start(hogs)?;
    // A run ends by itself (its own deadlines name a participant that stalls); one that has
    // not after this long is killed and counted as not completed.
    let limit = std::time::Duration::from_secs_f64(120.0 + 50.0 * duration * runs as f64);
    let t0 = Instant::now();
    let mut children = start_runs(exe, scenario, duration, runs, dir)?;
    let ends = wait_for_all(&mut children, limit);
    let mut wall_s = Vec::new();
    let mut loop_s = Vec::new();
    let mut placements = std::collections::BTreeMap::new();
    let mut completed = 0;
    for ((_, _, out), end) in children.iter().zip(ends) {
        let Some((status, wall)) = end else { continue };
        wall_s.push(wall);
        let summary = summary_of(out);
        let name = summary
            .as_ref()
            .map_or("no summary".to_string(), |(_, p)| p.clone());
        *placements.entry(name).or_insert(0) += 1;
        if let (Ok(st), Some((l, _))) = (status, summary) {
            if st.success() {
                completed += 1;
                loop_s.push(l);
            }
        }
    }
    let total_s = t0.elapsed().as_secs_f64();
    Ok(Row {
        runs,
        hogs,
        completed,
        wall_median_s: median(&wall_s).unwrap_or(0.0),
        wall_s,
        total_s,
        loop_median_s: median(&loop_s),
        loop_s,
        placements,
        load_before,
        load_after: tiltsim_master::engine::machine::load_average(),
    })
}

/// The rows as a Markdown table.
fn table(scenario: &str, duration: f64, rows: &[Row]) -> String {
    use std::fmt::Write as _;
    let mut s = format!(
        "tiltsim bench --concurrent: {scenario}, {duration} s simulated per run, over IPC\n\n\
         | runs | hogs | completed | wall per run, median (s) | total (s) | loop per run, median (s) | placements | load before / after |\n\
         |---|---|---|---|---|---|---|---|\n"
    );
    let load = |x: Option<f64>| x.map_or("?".into(), |x| format!("{x:.1}"));
    for r in rows {
        let placements: Vec<String> = r
            .placements
            .iter()
            .map(|(k, n)| format!("{n}× {k}"))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.2} | {} | {} | {} / {} |",
            r.runs,
            r.hogs,
            r.completed,
            r.wall_median_s,
            r.total_s,
            r.loop_median_s.map_or("-".into(), |x| format!("{x:.3}")),
            placements.join(", "),
            load(r.load_before),
            load(r.load_after)
        );
    }
    s
}

/// Runs `--concurrent`: every count of runs beside every count of hogs.
pub fn concurrent(
    scenario: &Path,
    name: &str,
    duration: f64,
    counts: &[usize],
    hogs: &[usize],
    exe: &Path,
    out: &Path,
) -> CliResult {
    let scratch: PathBuf = tiltsim_studies::bench::scratch_dir(out);
    // Ctrl-C reaches the runs too (they end as interrupted); the rows measured so far are
    // reported and no further row starts.
    let interrupt = tiltsim_rundir::signals::install();
    let mut rows = Vec::new();
    'rows: for &h in hogs {
        for &n in counts {
            if interrupt.load(Ordering::Relaxed) {
                break 'rows;
            }
            eprintln!("  {n} run(s) at once beside {h} hog(s) ...");
            let dir = scratch.join(format!("runs-{n}-hogs-{h}"));
            let r = row(exe, scenario, duration, n, h, &dir);
            let _ = std::fs::remove_dir_all(&dir);
            match r {
                Ok(r) => rows.push(r),
                Err(e) => {
                    let _ = std::fs::remove_dir_all(&scratch);
                    return Err(e);
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&scratch);
    println!("{}", table(name, duration, &rows));
    if let Some(dir) = out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    let machine = tiltsim_studies::bench::Machine::this();
    write_json(
        out,
        &serde_json::json!({
            "concurrent": rows,
            "scenario": name,
            "duration_s": duration,
            "machine": machine,
            "interrupted": interrupt.load(Ordering::Relaxed),
        }),
    )?;
    println!("wrote {}", out.display());
    if interrupt.load(Ordering::Relaxed) {
        return Err(CliError::Interrupted(format!(
            "interrupted by {}: {} of {} rows measured",
            tiltsim_rundir::signals::describe(),
            rows.len(),
            counts.len() * hogs.len()
        )));
    }
    Ok(())
}
