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
    /// Whether the runs ran under SCHED_FIFO (`--realtime`).
    pub realtime: bool,
    /// The loop of the same run in one process beside the same hogs, run after them (s).
    pub in_process_loop_s: Option<f64>,
    /// `loop_median_s` over `in_process_loop_s`: what the processes cost beside this load.
    pub loop_over_in_process: Option<f64>,
}

/// Spinning threads until dropped.
pub(super) struct Hogs {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Hogs {
    pub(super) fn start(n: usize) -> Result<Hogs, CliError> {
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

/// Starts `runs` IPC runs, each in `dir/r<k>`; if one cannot start, those started are
/// killed.
fn start_runs(how: Runs<'_>, runs: usize, dir: &Path) -> Result<Vec<Started>, CliError> {
    let mut children = Vec::new();
    for k in 0..runs {
        let out = dir.join(format!("r{k}"));
        match how.command("ipc", &out).spawn() {
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

/// How the bench starts each run.
#[derive(Clone, Copy)]
pub struct Runs<'a> {
    /// The `tiltsim` program.
    pub exe: &'a Path,
    /// The scenario file.
    pub scenario: &'a Path,
    /// Simulated seconds per run.
    pub duration: f64,
    /// Under SCHED_FIFO (`tiltsim run --realtime`).
    pub realtime: bool,
}

impl Runs<'_> {
    /// The command of one run writing to `out`, over `transport`.
    fn command(&self, transport: &str, out: &Path) -> std::process::Command {
        let mut c = std::process::Command::new(self.exe);
        c.arg("run")
            .arg(self.scenario)
            .args([
                "--transport",
                transport,
                "--duration",
                &self.duration.to_string(),
            ])
            .arg("--out")
            .arg(out)
            .args(["-q", "--no-plots"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null());
        if self.realtime && transport == "ipc" {
            c.arg("--realtime");
        }
        c
    }
}

/// One row: `runs` runs beside `hogs` hogs, in `dir`, then (unless `interrupt`ed) one in
/// process beside the same hogs for reference.
fn row(
    how: Runs<'_>,
    runs: usize,
    hogs: usize,
    dir: &Path,
    interrupt: &AtomicBool,
) -> Result<Row, CliError> {
    let load_before = tiltsim_master::engine::machine::load_average();
    let _hogs = Hogs::start(hogs)?;
    // A run ends by itself (its own deadlines name a participant that stalls); one that has
    // not after this long is killed and counted as not completed.
    let limit = std::time::Duration::from_secs_f64(120.0 + 50.0 * how.duration * runs as f64);
    let t0 = Instant::now();
    let mut children = start_runs(how, runs, dir)?;
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
    let alone = dir.join("in-process");
    let in_process_loop_s = (!interrupt.load(Ordering::Relaxed))
        .then(|| how.command("in-process", &alone).status().ok())
        .flatten()
        .filter(|st| st.success())
        .and_then(|_| summary_of(&alone))
        .map(|(l, _)| l);
    let loop_median_s = median(&loop_s);
    Ok(Row {
        runs,
        hogs,
        completed,
        wall_median_s: median(&wall_s).unwrap_or(0.0),
        wall_s,
        total_s,
        loop_median_s,
        loop_s,
        placements,
        load_before,
        load_after: tiltsim_master::engine::machine::load_average(),
        realtime: how.realtime,
        in_process_loop_s,
        loop_over_in_process: loop_median_s
            .zip(in_process_loop_s)
            .filter(|(_, a)| *a > 0.0)
            .map(|(l, a)| l / a),
    })
}

/// The rows as a Markdown table.
fn table(scenario: &str, duration: f64, rows: &[Row]) -> String {
    use std::fmt::Write as _;
    let mut s = format!(
        "tiltsim bench --concurrent: {scenario}, {duration} s simulated per run, over IPC\n\n\
         | runs | hogs | realtime | completed | wall per run, median (s) | total (s) | loop per run, median (s) | loop in process (s) | loop over in process | placements | load before / after |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n"
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
            "| {} | {} | {} | {} | {:.2} | {:.2} | {} | {} | {} | {} | {} / {} |",
            r.runs,
            r.hogs,
            if r.realtime { "yes" } else { "no" },
            r.completed,
            r.wall_median_s,
            r.total_s,
            r.loop_median_s.map_or("-".into(), |x| format!("{x:.3}")),
            r.in_process_loop_s
                .map_or("-".into(), |x| format!("{x:.3}")),
            r.loop_over_in_process
                .map_or("-".into(), |x| format!("{x:.2}")),
            placements.join(", "),
            load(r.load_before),
            load(r.load_after)
        );
    }
    s
}

/// Runs `--concurrent`: every count of runs beside every count of hogs.
pub fn concurrent(
    how: Runs<'_>,
    name: &str,
    counts: &[usize],
    hogs: &[usize],
    out: &Path,
) -> CliResult {
    let duration = how.duration;
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
            let r = row(how, n, h, &dir, &interrupt);
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
