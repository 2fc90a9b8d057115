//! Running the samples: a shard's samples in parallel, each in its own directory, resumable.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use tiltsim_assessment::comfort::{values, METRICS};
use tiltsim_master::engine::{RunOptions, Status};
use tiltsim_scenario::scenario::Scenario;

use super::{identity, resume, sample, Plan, Row, SampleStatus, SweepError, SERIES_DT};

/// Which samples an invocation runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard (0-based).
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// Parses `i/n` with `0 <= i < n`.
    pub fn parse(s: &str) -> Result<Shard, SweepError> {
        let bad = || {
            SweepError::Argument(format!(
                "--shard `{s}`: expected I/N with 0 <= I < N, e.g. 0/4"
            ))
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<usize>().map_err(|_| bad())?,
            n.trim().parse::<usize>().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
    /// The shard a batch scheduler's array task is, from its environment (`var` reads a
    /// variable): Slurm (`SLURM_ARRAY_TASK_ID` less `SLURM_ARRAY_TASK_MIN`, of
    /// `SLURM_ARRAY_TASK_COUNT`), AWS Batch (`AWS_BATCH_JOB_ARRAY_INDEX` of
    /// `AWS_BATCH_JOB_ARRAY_SIZE`), or a Kubernetes indexed job (`JOB_COMPLETION_INDEX`, of
    /// `shards`, which the job does not publish).
    pub fn auto(
        shards: Option<usize>,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<Shard, SweepError> {
        let num = |name: &str| -> Result<Option<usize>, SweepError> {
            var(name)
                .map(|v| {
                    v.trim().parse::<usize>().map_err(|_| {
                        SweepError::Argument(format!(
                            "--shard auto: {name}={v:?} is not a whole number"
                        ))
                    })
                })
                .transpose()
        };
        let check = |index: usize, count: usize, from: &str| {
            if count == 0 || index >= count {
                Err(SweepError::Argument(format!(
                    "--shard auto: {from} gives index {index} of {count}; need 0 <= index < count"
                )))
            } else {
                Ok(Shard { index, count })
            }
        };
        if let (Some(id), Some(count)) =
            (num("SLURM_ARRAY_TASK_ID")?, num("SLURM_ARRAY_TASK_COUNT")?)
        {
            return Shard::slurm(id, count, |n| num(n));
        }
        if let (Some(index), Some(count)) = (
            num("AWS_BATCH_JOB_ARRAY_INDEX")?,
            num("AWS_BATCH_JOB_ARRAY_SIZE")?,
        ) {
            return check(index, count, "AWS Batch");
        }
        if let Some(index) = num("JOB_COMPLETION_INDEX")? {
            let count = shards.ok_or_else(|| {
                SweepError::Argument(
                    "--shard auto: a Kubernetes indexed job (JOB_COMPLETION_INDEX) needs --shards N, its completions".into(),
                )
            })?;
            return check(index, count, "Kubernetes (JOB_COMPLETION_INDEX, --shards)");
        }
        Err(SweepError::Argument(
            "--shard auto: no array-task index found; set by Slurm (SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT), AWS Batch (AWS_BATCH_JOB_ARRAY_INDEX and AWS_BATCH_JOB_ARRAY_SIZE) or a Kubernetes indexed job (JOB_COMPLETION_INDEX, with --shards N); or give --shard I/N".into(),
        ))
    }

    /// The shard of a Slurm array task: task `id` of `count`, its index counted from
    /// `SLURM_ARRAY_TASK_MIN` in steps of `SLURM_ARRAY_TASK_STEP` (`--array=0-6:2` gives tasks
    /// 0, 2, 4, 6 the shards 0/4 .. 3/4). Refused, with how to resubmit: a task run as an array
    /// of one with an index other than 0 (`sbatch --array=2`, a resubmitted task of a larger
    /// array, whose shard Slurm no longer tells), and indices that are not an evenly spaced
    /// range (`--array=1,2,5`).
    pub(super) fn slurm(
        id: usize,
        count: usize,
        num: impl Fn(&str) -> Result<Option<usize>, SweepError>,
    ) -> Result<Shard, SweepError> {
        let bad = |m: String| Err(SweepError::Argument(format!("--shard auto: {m}")));
        let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
        let max = num("SLURM_ARRAY_TASK_MAX")?;
        let step = num("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1);
        if count == 1 && id != 0 {
            return bad(format!(
                "Slurm runs task {id} as an array of one task (SLURM_ARRAY_TASK_COUNT=1), as `sbatch --array={id}` does when one task of a larger array is submitted again: its shard cannot be told from Slurm. Submit it with its shard given, `--shard I/N` in place of `--shard auto` (I its place in the original array, N that array's task count: task {id} of `--array=0-7` is `--shard {id}/8`)"
            ));
        }
        if step == 0 || count == 0 {
            return bad(format!(
                "Slurm gives SLURM_ARRAY_TASK_STEP={step}, SLURM_ARRAY_TASK_COUNT={count}"
            ));
        }
        let spaced = max.is_none_or(|max| {
            (count - 1)
                .checked_mul(step)
                .and_then(|d| d.checked_add(min))
                == Some(max)
        });
        let offset = id.checked_sub(min);
        match offset {
            Some(o) if spaced && o % step == 0 => {}
            _ => {
                return bad(format!(
                    "Slurm's array indices are not an evenly spaced range holding this task (SLURM_ARRAY_TASK_ID={id}, _MIN={min}, _MAX={}, _STEP={step}, _COUNT={count}), so its shard cannot be told: give each task `--shard I/N`, I from 0 to N-1",
                    max.map_or("unset".to_string(), |m| m.to_string())
                ))
            }
        }
        let index = offset.unwrap_or(0) / step;
        if index >= count {
            return bad(format!(
                "Slurm gives index {index} of {count}; need 0 <= index < count"
            ));
        }
        Ok(Shard { index, count })
    }

    /// Samples of this shard out of `n`.
    pub fn samples(self, n: usize) -> Vec<usize> {
        (self.index..n).step_by(self.count).collect()
    }
}

/// How to execute a sweep.
pub struct Exec {
    /// Output directory.
    pub out: PathBuf,
    /// Parallel runs.
    pub jobs: usize,
    /// Keep each sample's run directory (`runs/sample-NNNN`).
    pub keep_runs: bool,
    /// Executable serving participants.
    pub exe: PathBuf,
    /// Set by Ctrl-C.
    pub interrupt: Arc<AtomicBool>,
    /// Show a progress bar (on a terminal).
    pub progress: bool,
    /// Samples finished so far, counted up as each ends, for a caller that watches the sweep
    /// from another thread.
    pub samples_done: Option<Arc<AtomicUsize>>,
}

pub(super) fn run_one(base: &Scenario, plan: &Plan, j: usize, ex: &Exec) -> Row {
    let failed = |params: Vec<f64>, why: String, series| Row {
        sample: j,
        params,
        status: SampleStatus::Failed(why),
        metrics: vec![f64::NAN; METRICS.len()],
        flags: Vec::new(),
        series,
    };
    let (s, params) = match sample(base, plan, j) {
        Ok(x) => x,
        Err(e) => return failed(Vec::new(), e.to_string(), Vec::new()),
    };
    let dir = ex.out.join("runs").join(format!("sample-{j:04}"));
    let mut opts = RunOptions::new(dir.clone(), ex.exe.clone());
    opts.interrupt = ex.interrupt.clone();
    opts.plots = ex.keep_runs;
    // Nor does it report wall-clock timing: no clock reads per exchange (`RunOptions::timing`).
    opts.timing = ex.keep_runs;
    let name = format!("{} (sample {j})", base.name);
    let mut job = tiltsim_runner::pipeline::Job::new(&s, name, opts);
    // The sweep holds its directory; each sample's is its own.
    job.claim = false;
    // A sample whose directory is removed afterwards keeps its rows in memory: no
    // timeseries.csv to write and read back (the values are the same, f64 round-trips).
    job.outputs.rows_in_memory = !ex.keep_runs;
    let (summary, rows) = match tiltsim_runner::pipeline::carry_out(job) {
        Ok(done) if !ex.keep_runs => (Ok(done.summary), done.rows),
        Ok(done) => (
            Ok(done.summary),
            tiltsim_formats::table::read_rows(&dir).unwrap_or_default(),
        ),
        Err(e) => (Err(e), Vec::new()),
    };
    let every = (SERIES_DT / s.run.dt_s).round().max(1.0) as usize;
    // Row k holds t_k: keep t = 0, 10 ms, 20 ms, ...
    let series: Vec<f64> = rows.iter().step_by(every).map(|r| r.lat_acc).collect();
    if !ex.keep_runs {
        let _ = std::fs::remove_dir_all(&dir);
    }
    match summary {
        Ok(sum) if sum.status == Status::Completed => Row {
            sample: j,
            params,
            status: SampleStatus::Completed,
            metrics: values(&sum.comfort).to_vec(),
            flags: sum.flags.raised().iter().map(|f| f.to_string()).collect(),
            series,
        },
        Ok(sum) => failed(params, sum.error.unwrap_or_default(), series),
        Err(e) => failed(params, e.to_string(), series),
    }
}

/// The samples a sweep finished.
#[derive(Debug, Clone)]
pub struct Swept {
    /// Rows of the finished samples, in sample order.
    pub rows: Vec<Row>,
    /// Whether the sweep was interrupted: `rows` then holds only the samples that had ended
    /// before the interrupt (the ones in flight are dropped, being cut short).
    pub interrupted: bool,
}

/// Runs the samples of `shard` (all when `None`) in parallel and returns the rows of those
/// that finished, in sample order. Samples kept in `ex.out/done` by an earlier invocation of
/// the same sweep (same scenario, plan, shard and build) are checked and reused, damaged ones
/// run again; a directory kept for another shard is refused before anything runs. Starting
/// afresh, the results of an earlier sweep in `ex.out` are removed first.
pub fn run(
    base: &Scenario,
    plan: &Plan,
    shard: Option<Shard>,
    ex: &Exec,
) -> Result<Swept, SweepError> {
    let mine = shard
        .unwrap_or(Shard { index: 0, count: 1 })
        .samples(plan.len());
    // Samples finished by an earlier, interrupted invocation with the same arguments.
    let (done, resumed) = resume::Done::open(&ex.out, base, plan, shard, identity::build())?;
    if !resumed {
        clear_results(&ex.out).map_err(|e| SweepError::Files(e.to_string()))?;
    }
    let kept = kept_rows(&done, &mine, plan, &ex.out);
    let todo: Vec<usize> = mine
        .into_iter()
        .filter(|j| !kept.iter().any(|r| r.sample == *j))
        .collect();
    // Parallel samples over IPC place themselves like concurrent runs: each pins to CPUs no
    // other run claims, or, when there are none left, lets the kernel balance it
    // (`cosim::ipc::placement`).
    let rows = run_parallel(base, plan, &todo, ex, &done);
    let _ = std::fs::remove_dir(ex.out.join("runs"));
    let mut all: Vec<Row> = rows.into_iter().flatten().chain(kept).collect();
    all.sort_by_key(|r| r.sample);
    Ok(Swept {
        rows: all,
        interrupted: ex.interrupt.load(Ordering::Relaxed),
    })
}

/// The rows of the samples of `mine` that an earlier invocation kept in `out/done` and that
/// check out; a damaged one is said and run again.
fn kept_rows(done: &resume::Done, mine: &[usize], plan: &Plan, out: &Path) -> Vec<Row> {
    let mut kept: Vec<Row> = Vec::new();
    for j in mine {
        match done.get(*j, plan) {
            Ok(Some(r)) => kept.push(r),
            Ok(None) => {}
            // Said even under -q: a result is recomputed.
            Err(why) => eprintln!("warning: {why}; sample {j} is run again"),
        }
    }
    if !kept.is_empty() {
        eprintln!(
            "resuming: {} of {} samples already finished in {}",
            kept.len(),
            mine.len(),
            out.join("done").display()
        );
    }
    kept
}

/// Runs samples `todo` on `ex.jobs` threads, each kept in `done` as it ends; returns their
/// rows in `todo`'s order, `None` for those not run or cut short by an interrupt.
fn run_parallel(
    base: &Scenario,
    plan: &Plan,
    todo: &[usize],
    ex: &Exec,
    done: &resume::Done,
) -> Vec<Option<Row>> {
    let bar = progress_bar(ex.progress, todo.len());
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<Option<Row>>> = Mutex::new(vec![None; todo.len()]);
    std::thread::scope(|sc| {
        for _ in 0..ex.jobs.clamp(1, todo.len().max(1)) {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= todo.len() || ex.interrupt.load(Ordering::Relaxed) {
                    break;
                }
                let row = run_one(base, plan, todo[i], ex);
                if ex.interrupt.load(Ordering::Relaxed) {
                    // This sample may have been cut short by the interrupt: not kept.
                    break;
                }
                if !row.status.completed() {
                    bar.set_message(format!("(sample {} failed)", row.sample));
                }
                if let Err(e) = done.put(&row) {
                    tracing::warn!("sample {} not kept for resuming: {e}", row.sample);
                }
                if let Ok(mut r) = rows.lock() {
                    r[i] = Some(row);
                }
                bar.inc(1);
                if let Some(n) = &ex.samples_done {
                    n.fetch_add(1, Ordering::Relaxed);
                }
            });
        }
    });
    bar.finish_and_clear();
    rows.into_inner().unwrap_or_default()
}

/// The sweep's progress bar over `n` samples (hidden unless `shown`).
fn progress_bar(shown: bool, n: usize) -> indicatif::ProgressBar {
    let bar = if shown {
        indicatif::ProgressBar::new(n as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} samples, eta {eta} {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar
}

/// Removes an earlier sweep's results from `out`: its tables, figures and kept sample runs
/// (`runs/sample-NNNN`, each cleared as a run), never files the program does not write.
pub(super) fn clear_results(out: &Path) -> Result<(), tiltsim_rundir::outdir::OutDirError> {
    tiltsim_rundir::outdir::clear_sweep_results(out)?;
    let runs = out.join("runs");
    if let Ok(entries) = std::fs::read_dir(&runs) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with("sample-") && e.path().is_dir() {
                tiltsim_rundir::outdir::clear_run(&e.path())?;
                tiltsim_rundir::outdir::remove_if_empty(&e.path());
            }
        }
        tiltsim_rundir::outdir::remove_if_empty(&runs);
    }
    Ok(())
}

/// Clears `out` for a merged sweep: an earlier sweep's results and kept samples.
pub fn clear_for_merge(out: &Path) -> Result<(), tiltsim_rundir::outdir::OutDirError> {
    clear_results(out)?;
    resume::clear(out);
    Ok(())
}

/// Checks that `row`'s parameters are those the plan gives sample `row.sample` (bit for bit;
/// none for a sample that could not be set up).
pub(crate) fn check_params(base: &Scenario, plan: &Plan, row: &Row) -> Result<(), String> {
    let want = sample(base, plan, row.sample)
        .map(|(_, p)| p)
        .unwrap_or_default();
    let cols = plan.columns();
    if want.is_empty() {
        return if row.params.iter().all(|p| p.is_nan()) {
            Ok(())
        } else {
            Err(format!(
                "sample {} has parameters where the plan gives none",
                row.sample
            ))
        };
    }
    if row.params.len() != want.len() {
        return Err(format!(
            "sample {}: {} parameters, the plan gives {}",
            row.sample,
            row.params.len(),
            want.len()
        ));
    }
    for ((got, w), col) in row.params.iter().zip(&want).zip(&cols) {
        if got.to_bits() != w.to_bits() {
            return Err(format!(
                "the parameters of sample {} are not the plan's ({col} = {got}, the plan gives {w})",
                row.sample
            ));
        }
    }
    Ok(())
}
