//! `tiltsim sweep`: many runs of one scenario with something varied, and what the comfort
//! metrics do across them.
//!
//! Two plans:
//! * **Monte Carlo** (Fig. 21 of the paper): every mass, inertia and suspension parameter of
//!   the true vehicle is scaled by its own factor drawn uniformly from `1 ± spread` (default
//!   ±22 %), while the controller keeps the nominal design (`design_vehicle`). Sample `j`
//!   draws from ChaCha8 seeded with the sweep seed on stream `j`, so a sample's parameters do
//!   not depend on which other samples run, where or in which order. The track irregularity
//!   and sensor noise keep the scenario's `run.seed`: samples differ only in the vehicle.
//! * **Grid**: one numeric scenario key (dotted path, e.g. `vehicle.m_v` or
//!   `links.actuator_command.delay_ticks`) set to each listed value in turn.
//!
//! Results: `samples.csv` (one row per sample: parameters, status, every comfort metric),
//! `series.csv` (each sample's lateral acceleration every 10 ms), `table.md`/`table.csv`
//! (Monte Carlo: median, 5th and 95th percentile of each metric; grid: the metrics per
//! value), `plots/` and `sweep.json` (the plan). A shard (`--shard i/n`) runs samples
//! `j ≡ i (mod n)` and writes the same files for its samples; `tiltsim sweep-merge` joins
//! shards into files byte-identical to the unsharded sweep's, because every file is written
//! by one function from the rows alone, and numbers are written in Rust's shortest
//! round-trip form, so reading a shard back loses nothing.

pub mod identity;
mod resume;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::comfort::{metric, values, METRICS};
use crate::compare::fmt;
use crate::engine::{RunOptions, Status};
use crate::plot::{Chart, Line, PALETTE};
use crate::scenario::Scenario;

/// The vehicle parameters a Monte Carlo sweep perturbs: masses, inertias and suspension.
pub const PERTURBED: [&str; 15] = [
    "m_v", "i_vr", "m_b", "i_br", "k_az", "k_sz", "k_rz", "c_rz", "k_sy", "c_sy", "k_vr", "k_pz",
    "c_pz", "k_py", "c_py",
];

/// Interval of the stored lateral-acceleration series (s).
pub const SERIES_DT: f64 = 0.01;

/// What a sweep varies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "method")]
pub enum Plan {
    /// Uniform factors `1 ± spread` on [`PERTURBED`].
    MonteCarlo {
        /// Number of samples.
        samples: usize,
        /// Relative half-width of the uniform distribution.
        spread: f64,
        /// Seed of the draws.
        seed: u64,
    },
    /// One key set to each value.
    Grid {
        /// Dotted scenario key.
        key: String,
        /// Values, one sample each.
        values: Vec<f64>,
    },
}

impl Plan {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Plan::MonteCarlo { samples, .. } => *samples,
            Plan::Grid { values, .. } => values.len(),
        }
    }
    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Names of the parameter columns.
    pub fn columns(&self) -> Vec<String> {
        match self {
            Plan::MonteCarlo { .. } => PERTURBED.iter().map(|p| format!("factor_{p}")).collect(),
            Plan::Grid { key, .. } => vec![key.clone()],
        }
    }
}

/// Why a sweep could not be set up or its files read back.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A `--grid`, `--shard` or sweep key as given: the message names it and what is allowed.
    #[error("{0}")]
    Argument(String),
    /// A sweep's files: the message names the file (and line) and what is wrong.
    #[error("{0}")]
    Files(String),
    /// Shards that do not make one sweep together.
    #[error("{0}")]
    Merge(String),
}

/// Parses a grid `KEY=SPEC` where SPEC is `start:stop:step` (inclusive) or `v1,v2,...`.
pub fn parse_grid(arg: &str) -> Result<Plan, SweepError> {
    grid_plan(arg).map_err(SweepError::Argument)
}

fn grid_plan(arg: &str) -> Result<Plan, String> {
    let (key, spec) = arg
        .split_once('=')
        .ok_or_else(|| format!("--grid `{arg}`: expected KEY=START:STOP:STEP or KEY=V1,V2,..."))?;
    let num = |x: &str| {
        let x = x.trim();
        // A value is held as f64: a whole number written in digits must be one that f64
        // holds exactly, or it would arrive as its neighbour (2^53 + 1 as 2^53).
        if let Ok(n) = x.parse::<i128>() {
            if n.unsigned_abs() > 1u128 << 53 {
                return Err(format!(
                    "--grid `{arg}`: `{x}` is a whole number beyond 2^53 = 9007199254740992, which a grid value cannot hold exactly; set it with `tiltsim run --set KEY={x}` (or `--seed`)"
                ));
            }
        }
        x.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("--grid `{arg}`: `{x}` is not a finite number"))
    };
    let values = if spec.contains(':') {
        let p: Vec<&str> = spec.split(':').collect();
        if p.len() != 3 {
            return Err(format!("--grid `{arg}`: a range is START:STOP:STEP"));
        }
        let (a, b, st) = (num(p[0])?, num(p[1])?, num(p[2])?);
        if st <= 0.0 || b < a || (b - a) / st > 10_000.0 {
            return Err(format!(
                "--grid `{arg}`: need STOP >= START and 0 < STEP, at most 10000 values"
            ));
        }
        let n = ((b - a) / st + 1e-9).floor() as usize;
        // Computed from the index, so values do not drift by accumulated rounding.
        (0..=n).map(|i| a + i as f64 * st).collect()
    } else {
        spec.split(',').map(num).collect::<Result<Vec<_>, _>>()?
    };
    if key.trim().is_empty() || values.is_empty() {
        return Err(format!("--grid `{arg}`: need a key and at least one value"));
    }
    Ok(Plan::Grid {
        key: key.trim().to_string(),
        values,
    })
}

/// Sets the dotted `key` of a scenario to `v` (an integer where the key holds one), and
/// re-validates. Errors name the key.
pub fn with_key(base: &Scenario, key: &str, v: f64) -> Result<Scenario, SweepError> {
    set_key(base, key, v).map_err(SweepError::Argument)
}

fn set_key(base: &Scenario, key: &str, v: f64) -> Result<Scenario, String> {
    let mut doc = toml::Value::try_from(base).map_err(|e| e.to_string())?;
    fn set(node: &mut toml::Value, parts: &[&str], key: &str, v: f64) -> Result<(), String> {
        let table = node
            .as_table_mut()
            .ok_or_else(|| format!("sweep key `{key}`: `{}` is not inside a table", parts[0]))?;
        if let [last] = parts {
            let integer = matches!(table.get(*last), Some(toml::Value::Integer(_)));
            let value = if integer {
                if v.fract() != 0.0 {
                    return Err(format!("sweep key `{key}` takes whole numbers, not {v}"));
                }
                toml::Value::Integer(v as i64)
            } else {
                toml::Value::Float(v)
            };
            table.insert(last.to_string(), value);
            Ok(())
        } else {
            let child = table
                .entry(parts[0].to_string())
                .or_insert_with(|| toml::Value::Table(Default::default()));
            set(child, &parts[1..], key, v)
        }
    }
    let parts: Vec<&str> = key.split('.').collect();
    set(&mut doc, &parts, key, v)?;
    // Typed straight from the document (no text, so no line of an internal document in the
    // message): the error names the key as the user gave it.
    let mut s = serde_path_to_error::deserialize::<_, Scenario>(doc).map_err(|e| {
        format!(
            "key `{key}`: {} (at `{}`); keys are the scenario's settings as dotted paths, e.g. `vehicle.m_v`, `controller.rho`",
            e.inner().to_string().trim_end(),
            e.path()
        )
    })?;
    let errors = s.validate();
    if !errors.is_empty() {
        let lines: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
        return Err(format!("key `{key}` = {v}: {}", lines.join("; ")));
    }
    s.name = base.name.clone();
    Ok(s)
}

/// The scenario of sample `j` and its parameter values (factors or the grid value).
pub fn sample(base: &Scenario, plan: &Plan, j: usize) -> Result<(Scenario, Vec<f64>), SweepError> {
    match plan {
        Plan::MonteCarlo { spread, seed, .. } => {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(*seed);
            rng.set_stream(j as u64);
            let factors: Vec<f64> = PERTURBED
                .iter()
                .map(|_| 1.0 + spread * (2.0 * rng.random::<f64>() - 1.0))
                .collect();
            let mut s = base.clone();
            s.design_vehicle = Some(base.controller_vehicle().clone());
            let v = &mut s.vehicle;
            let fields: [&mut f64; 15] = [
                &mut v.m_v,
                &mut v.i_vr,
                &mut v.m_b,
                &mut v.i_br,
                &mut v.k_az,
                &mut v.k_sz,
                &mut v.k_rz,
                &mut v.c_rz,
                &mut v.k_sy,
                &mut v.c_sy,
                &mut v.k_vr,
                &mut v.k_pz,
                &mut v.c_pz,
                &mut v.k_py,
                &mut v.c_py,
            ];
            for (f, k) in fields.into_iter().zip(&factors) {
                *f *= k;
            }
            Ok((s, factors))
        }
        Plan::Grid { key, values } => Ok((with_key(base, key, values[j])?, vec![values[j]])),
    }
}

/// The settings sample `j` changes, as dotted keys and values: every leaf of its scenario
/// that differs from `base` (for a Monte Carlo sample the 15 scaled parameters and the
/// nominal design vehicle). `tiltsim run SCENARIO --set KEY=VALUE ...` with them runs exactly
/// that sample.
pub fn overrides(
    base: &Scenario,
    plan: &Plan,
    j: usize,
) -> Result<Vec<(String, toml::Value)>, SweepError> {
    let (s, _) = sample(base, plan, j)?;
    let to_value =
        |s: &Scenario| toml::Value::try_from(s).map_err(|e| SweepError::Argument(e.to_string()));
    let (a, b) = (to_value(base)?, to_value(&s)?);
    fn diff(
        path: &str,
        a: Option<&toml::Value>,
        b: &toml::Value,
        out: &mut Vec<(String, toml::Value)>,
    ) {
        match b {
            toml::Value::Table(t) => {
                for (k, v) in t {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    diff(&p, a.and_then(|a| a.get(k)), v, out);
                }
            }
            _ if a != Some(b) => out.push((path.to_string(), b.clone())),
            _ => {}
        }
    }
    let mut out = Vec::new();
    diff("", Some(&a), &b, &mut out);
    Ok(out)
}

/// How one sample ended (written `completed` or `failed: cause`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SampleStatus {
    /// The run completed.
    Completed,
    /// The run failed, or the sample could not be set up.
    Failed(String),
}

impl SampleStatus {
    /// Whether the run completed.
    pub fn completed(&self) -> bool {
        *self == SampleStatus::Completed
    }

    /// Parses the text of `samples.csv`.
    pub fn parse(s: &str) -> Option<Self> {
        if s == "completed" {
            Some(SampleStatus::Completed)
        } else {
            s.strip_prefix("failed: ")
                .map(|why| SampleStatus::Failed(why.to_string()))
        }
    }
}

impl std::fmt::Display for SampleStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SampleStatus::Completed => f.write_str("completed"),
            SampleStatus::Failed(why) => write!(f, "failed: {why}"),
        }
    }
}

/// One sample's result.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Sample index.
    pub sample: usize,
    /// Parameter values ([`Plan::columns`]).
    pub params: Vec<f64>,
    /// How it ended.
    pub status: SampleStatus,
    /// Metrics in [`METRICS`] order (NaN when the run failed).
    pub metrics: Vec<f64>,
    /// The validity flags the run raised (`crate::validity::Flags::raised`).
    pub flags: Vec<String>,
    /// Lateral acceleration every [`SERIES_DT`] (m/s²), as far as recorded.
    pub series: Vec<f64>,
}

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
    fn slurm(
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
}

fn run_one(base: &Scenario, plan: &Plan, j: usize, ex: &Exec) -> Row {
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
    // A sample whose directory is removed afterwards keeps its rows in memory: no
    // timeseries.csv to write and read back (the values are the same, f64 round-trips).
    opts.keep_rows = !ex.keep_runs;
    // Nor does it report wall-clock timing: no clock reads per exchange (`RunOptions::timing`).
    opts.timing = ex.keep_runs;
    let name = format!("{} (sample {j})", base.name);
    let (summary, rows) = if opts.keep_rows {
        match crate::analysis::run_keeping_rows(&s, &name, &opts) {
            Ok((sum, rows)) => (Ok(sum), rows),
            Err(e) => (Err(e), Vec::new()),
        }
    } else {
        let summary = crate::analysis::run(&s, &name, &opts);
        (summary, crate::record::read_rows(&dir).unwrap_or_default())
    };
    let every = (SERIES_DT / s.run.dt_s).round().max(1.0) as usize;
    // Row k holds t_{k+1}; keep t = 10 ms, 20 ms, ...
    let series: Vec<f64> = rows
        .iter()
        .skip(every - 1)
        .step_by(every)
        .map(|r| r.lat_acc)
        .collect();
    if ex.keep_runs {
        if let Ok(sum) = &summary {
            let _ = crate::files::write_atomic(
                &dir.join("summary.json"),
                serde_json::to_string_pretty(sum).unwrap_or_default() + "\n",
            );
        }
    } else {
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
    let mut kept: Vec<Row> = Vec::new();
    for j in &mine {
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
            ex.out.join("done").display()
        );
    }
    let todo: Vec<usize> = mine
        .into_iter()
        .filter(|j| !kept.iter().any(|r| r.sample == *j))
        .collect();
    let mut base = base.clone();
    // Parallel process runs must not all pin themselves to the same two CPUs.
    base.run.pin_cpus = false;
    let bar = if ex.progress {
        indicatif::ProgressBar::new(todo.len() as u64)
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
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<Option<Row>>> = Mutex::new(vec![None; todo.len()]);
    std::thread::scope(|sc| {
        for _ in 0..ex.jobs.clamp(1, todo.len().max(1)) {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= todo.len() || ex.interrupt.load(Ordering::Relaxed) {
                    break;
                }
                let row = run_one(&base, plan, todo[i], ex);
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
            });
        }
    });
    bar.finish_and_clear();
    let _ = std::fs::remove_dir(ex.out.join("runs"));
    let mut all: Vec<Row> = rows
        .into_inner()
        .unwrap_or_default()
        .into_iter()
        .flatten()
        .chain(kept)
        .collect();
    all.sort_by_key(|r| r.sample);
    Ok(Swept {
        rows: all,
        interrupted: ex.interrupt.load(Ordering::Relaxed),
    })
}

/// Removes an earlier sweep's results from `out`: its tables, figures and kept sample runs
/// (`runs/sample-NNNN`, each cleared as a run), never files the program does not write.
fn clear_results(out: &Path) -> Result<(), crate::outdir::OutDirError> {
    crate::outdir::clear_sweep_results(out)?;
    let runs = out.join("runs");
    if let Ok(entries) = std::fs::read_dir(&runs) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with("sample-") && e.path().is_dir() {
                crate::outdir::clear_run(&e.path())?;
                crate::outdir::remove_if_empty(&e.path());
            }
        }
        crate::outdir::remove_if_empty(&runs);
    }
    Ok(())
}

/// Clears `out` for a merged sweep: an earlier sweep's results and kept samples.
pub fn clear_for_merge(out: &Path) -> Result<(), crate::outdir::OutDirError> {
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

/// What `sweep.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepFile {
    /// Scenario name.
    pub scenario: String,
    /// The plan.
    pub plan: Plan,
    /// `i/n` for a shard's output, absent for a whole (or merged) sweep.
    pub shard: Option<String>,
    /// Samples in this output.
    pub samples: Vec<usize>,
    /// The sweep was interrupted: `samples` are those that had finished (present only then).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub interrupted: bool,
    /// The build of tiltsim that computed the samples ([`identity::build`]).
    pub build: String,
    /// The fingerprint of base scenario, plan and build ([`identity::fingerprint`]), the same
    /// for every shard of one sweep.
    pub fingerprint: String,
    /// SHA-256 of each result file as written, checked by `sweep-merge` before it reads one.
    pub sha256: std::collections::BTreeMap<String, String>,
}

/// Checks rows before they are written: each sample of the plan and the shard at most once,
/// every metric there, and (unless interrupted) every sample of the shard present.
fn check_rows(
    plan: &Plan,
    shard: Option<Shard>,
    rows: &[Row],
    interrupted: bool,
) -> std::io::Result<()> {
    let bad = |m: String| Err(std::io::Error::other(m));
    let mine = shard
        .unwrap_or(Shard { index: 0, count: 1 })
        .samples(plan.len());
    for (k, r) in rows.iter().enumerate() {
        if mine.binary_search(&r.sample).is_err() {
            return bad(format!("sample {} is not in this sweep's plan", r.sample));
        }
        if k > 0 && rows[k - 1].sample >= r.sample {
            return bad(format!("sample {} twice or out of order", r.sample));
        }
        if r.metrics.len() != METRICS.len() {
            return bad(format!("sample {}: {} metrics", r.sample, r.metrics.len()));
        }
    }
    if !interrupted && rows.len() != mine.len() {
        return bad(format!("{} of {} samples finished", rows.len(), mine.len()));
    }
    Ok(())
}

/// Linear-interpolation percentile (type 7) of sorted values.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = (sorted.len() - 1) as f64 * p;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// A CSV file in memory, written by the `csv` crate.
fn csv_text(records: impl IntoIterator<Item = Vec<String>>) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in records {
        // Writing into memory cannot fail.
        let _ = w.write_record(&r);
    }
    w.into_inner()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

fn numbers(v: &[f64]) -> impl Iterator<Item = String> + '_ {
    v.iter().map(|x| x.to_string())
}

/// `samples.csv`: each sample's parameters, status and metrics.
fn samples_csv(plan: &Plan, rows: &[Row]) -> String {
    let cols = plan.columns();
    let head = std::iter::once("sample".to_string())
        .chain(cols.iter().map(|c| c.to_string()))
        .chain(std::iter::once("status".to_string()))
        .chain(METRICS.iter().map(|m| m.key.to_string()))
        .chain(std::iter::once("flags".to_string()))
        .collect();
    let body = rows.iter().map(|r| {
        let params = (0..cols.len()).map(|k| r.params.get(k).copied().unwrap_or(f64::NAN));
        std::iter::once(r.sample.to_string())
            .chain(params.map(|v| v.to_string()))
            .chain(std::iter::once(r.status.to_string()))
            .chain(numbers(&r.metrics))
            .chain(std::iter::once(r.flags.join("; ")))
            .collect()
    });
    csv_text(std::iter::once(head).chain(body))
}

/// `series.csv`: each sample's lateral acceleration every [`SERIES_DT`].
fn series_csv(rows: &[Row]) -> String {
    let longest = rows.iter().map(|r| r.series.len()).max().unwrap_or(0);
    let head = std::iter::once("sample".to_string())
        .chain((0..longest).map(|i| ((i + 1) as f64 * SERIES_DT).to_string()))
        .collect();
    let body = rows.iter().map(|r| {
        std::iter::once(r.sample.to_string())
            .chain(numbers(&r.series))
            .collect()
    });
    // Series of failed samples are shorter: the csv crate needs flexible records.
    let mut w = csv::WriterBuilder::new()
        .flexible(true)
        .from_writer(Vec::new());
    for r in std::iter::once(head).chain(body) {
        let _ = w.write_record::<&Vec<String>, &String>(&r);
    }
    w.into_inner()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

/// `table.md` and `table.csv` of a Monte Carlo sweep: each metric's distribution.
fn monte_carlo_tables(base: &Scenario, spread: f64, seed: u64, rows: &[Row]) -> (String, String) {
    let ok: Vec<&Row> = rows.iter().filter(|r| r.status.completed()).collect();
    let mut md = format!(
        "# Robustness sweep of `{}`\n\nMonte Carlo over the true vehicle: {} masses, \
         inertias and suspension parameters each scaled by U(1 − {s}, 1 + {s}) (seed \
         {seed}); the controller keeps the nominal design. {} of {} samples completed.\n\n\
         | metric | median | p5 | p95 | min | max |\n|---|---|---|---|---|---|\n",
        base.name,
        PERTURBED.len(),
        ok.len(),
        rows.len(),
        s = spread
    );
    let mut records = vec![["metric", "n", "median", "p5", "p95", "min", "max"]
        .map(String::from)
        .to_vec()];
    for (m, metric) in METRICS.iter().enumerate() {
        let mut v: Vec<f64> = ok
            .iter()
            .filter_map(|r| r.metrics.get(m).copied())
            .collect();
        v.sort_by(|a, b| a.total_cmp(b));
        let q = [0.5, 0.05, 0.95, 0.0, 1.0].map(|p| percentile(&v, p));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} |",
            metric.label,
            fmt(q[0]),
            fmt(q[1]),
            fmt(q[2]),
            fmt(q[3]),
            fmt(q[4])
        );
        let mut rec = vec![metric.key.to_string(), v.len().to_string()];
        rec.extend(numbers(&q));
        records.push(rec);
    }
    let flagged = rows.iter().filter(|r| !r.flags.is_empty()).count();
    if flagged > 0 {
        let mut kinds: Vec<&str> = rows
            .iter()
            .flat_map(|r| r.flags.iter().map(String::as_str))
            .collect();
        kinds.sort_unstable();
        kinds.dedup();
        let counts: Vec<String> = kinds
            .iter()
            .map(|k| {
                let n = rows
                    .iter()
                    .filter(|r| r.flags.iter().any(|f| f == k))
                    .count();
                format!("{k} {n}")
            })
            .collect();
        let _ = writeln!(
            md,
            "\n{flagged} of {} samples raised a validity flag ({}; samples.csv names them).\n",
            rows.len(),
            counts.join(", ")
        );
    }
    (md, csv_text(records))
}

/// `table.md` and `table.csv` of a grid sweep: the metrics at each value.
fn grid_tables(base: &Scenario, key: &str, rows: &[Row]) -> (String, String) {
    let mut md = format!(
        "# Sweep of `{}` over `{key}`\n\n| {key} | status | lat. acc. peak (%g) | \
         P_CT standing (%) | P_CT seated (%) | P_CT EN 12299 standing (%) | roll speed \
         peak (rad/s) | jerk peak (%g/s) |\n|---|---|---|---|---|---|---|---|\n",
        base.name
    );
    let shown = [
        "lat_acc_peak_pct_g",
        "p_ct_standing",
        "p_ct_seated",
        "p_ct_en12299_standing",
        "roll_speed_peak_rad_s",
        "jerk_peak_pct_g_s",
    ];
    let head = [key.to_string(), "status".to_string()]
        .into_iter()
        .chain(METRICS.iter().map(|m| m.key.to_string()))
        .collect();
    let mut records = vec![head];
    for r in rows {
        let value = r.params.first().copied().unwrap_or(f64::NAN);
        let _ = write!(md, "| {value} | {} |", r.status);
        for k in shown {
            let v = r.metrics.get(metric(k)).copied().unwrap_or(f64::NAN);
            let _ = write!(md, " {} |", fmt(v));
        }
        md.push('\n');
        let mut rec = vec![value.to_string(), r.status.to_string()];
        rec.extend(numbers(&r.metrics));
        records.push(rec);
    }
    (md, csv_text(records))
}

/// Writes every output file of a sweep (or shard) from its rows, computed by `build`. The rows
/// are checked first and every file is made in memory before any is written, so an earlier
/// complete table is never replaced by a truncated one; `sweep.json`, which holds the others'
/// checksums, is written last.
pub fn write_outputs(
    out: &Path,
    base: &Scenario,
    plan: &Plan,
    shard: Option<Shard>,
    rows: &[Row],
    interrupted: bool,
    build: &str,
) -> std::io::Result<Vec<PathBuf>> {
    check_rows(plan, shard, rows, interrupted)?;
    let scenario = toml::to_string(base).unwrap_or_default();
    let (md, tcsv) = match plan {
        Plan::MonteCarlo { spread, seed, .. } => monte_carlo_tables(base, *spread, *seed, rows),
        Plan::Grid { key, .. } => grid_tables(base, key, rows),
    };
    let texts = [
        ("scenario.toml", scenario.clone()),
        ("samples.csv", samples_csv(plan, rows)),
        ("series.csv", series_csv(rows)),
        ("table.md", md),
        ("table.csv", tcsv),
    ];
    let meta = SweepFile {
        scenario: base.name.clone(),
        plan: plan.clone(),
        shard: shard.map(|s| format!("{}/{}", s.index, s.count)),
        samples: rows.iter().map(|r| r.sample).collect(),
        interrupted,
        build: build.to_string(),
        fingerprint: identity::fingerprint(&scenario, plan, build),
        sha256: texts
            .iter()
            .map(|(n, t)| (n.to_string(), identity::sha256(t.as_bytes())))
            .collect(),
    };
    std::fs::create_dir_all(out)?;
    let mut files = Vec::new();
    let mut put = |name: &str, text: &str| -> std::io::Result<()> {
        let p = out.join(name);
        crate::files::write_atomic(&p, text)?;
        files.push(p);
        Ok(())
    };
    for (name, text) in &texts {
        put(name, text)?;
    }
    put(
        "sweep.json",
        &(serde_json::to_string_pretty(&meta).unwrap_or_default() + "\n"),
    )?;
    files.extend(write_plots(out, base, plan, rows)?);
    Ok(files)
}

fn line<'a>(label: &'a str, y: Vec<f64>, colour: &'static str, dashed: bool) -> Line<'a> {
    Line {
        label,
        y,
        colour,
        dashed,
    }
}

fn column(ok: &[&Row], key: &str) -> Vec<f64> {
    let m = metric(key);
    ok.iter()
        .map(|r| r.metrics.get(m).copied().unwrap_or(f64::NAN))
        .collect()
}

/// The lateral-acceleration envelope (5th, 50th, 95th percentile at each time) and the
/// empirical distribution of P_CT.
fn monte_carlo_plots(
    dir: &Path,
    ok: &[&Row],
    t: &[f64],
    bands: Vec<(f64, f64, bool)>,
) -> std::io::Result<Vec<PathBuf>> {
    let mut env = [Vec::new(), Vec::new(), Vec::new()];
    for i in 0..t.len() {
        let mut v: Vec<f64> = ok.iter().map(|r| r.series[i]).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        for (k, p) in [0.05, 0.5, 0.95].iter().enumerate() {
            env[k].push(percentile(&v, *p));
        }
    }
    let [p5, p50, p95] = env;
    let chart = Chart {
        title: "Lateral acceleration across the perturbed vehicles (Fig. 21)",
        x_label: "time (s)",
        y_label: "lateral acceleration (m/s²)",
        lines: vec![
            line("95th percentile", p95, "#d62728", true),
            line("median", p50, "#1f77b4", false),
            line("5th percentile", p5, "#2ca02c", true),
        ],
        bands,
        note: crate::plot::SECTION_NOTE,
    };
    let mut files =
        crate::plot::write_chart(dir, "sweep_lateral_acceleration", &chart, t)?.to_vec();
    let mut p = column(ok, "p_ct_standing");
    p.sort_by(|a, b| a.total_cmp(b));
    let frac: Vec<f64> = (1..=p.len()).map(|i| i as f64 / p.len() as f64).collect();
    let chart = Chart {
        title: "Distribution of P_CT (standing, whole-run peaks) over the samples",
        x_label: "P_CT standing (%)",
        y_label: "fraction of samples ≤ P_CT",
        lines: vec![line("empirical CDF", frac, "#1f77b4", false)],
        bands: Vec::new(),
        note: "",
    };
    files.extend(crate::plot::write_chart(dir, "sweep_p_ct", &chart, &p)?);
    Ok(files)
}

/// The lateral acceleration for each swept value, and comfort against the value.
fn grid_plots(
    dir: &Path,
    key: &str,
    ok: &[&Row],
    t: &[f64],
    bands: Vec<(f64, f64, bool)>,
) -> std::io::Result<Vec<PathBuf>> {
    let labels: Vec<String> = ok
        .iter()
        .map(|r| format!("{key} = {}", r.params.first().copied().unwrap_or(f64::NAN)))
        .collect();
    let chart = Chart {
        title: "Lateral acceleration for each swept value",
        x_label: "time (s)",
        y_label: "lateral acceleration (m/s²)",
        lines: ok
            .iter()
            .zip(&labels)
            .enumerate()
            .map(|(k, (r, label))| {
                line(
                    label,
                    r.series[..t.len()].to_vec(),
                    PALETTE[k % PALETTE.len()],
                    false,
                )
            })
            .collect(),
        bands,
        note: crate::plot::SECTION_NOTE,
    };
    let mut files =
        crate::plot::write_chart(dir, "sweep_lateral_acceleration", &chart, t)?.to_vec();
    let x: Vec<f64> = ok
        .iter()
        .map(|r| r.params.first().copied().unwrap_or(f64::NAN))
        .collect();
    let title = format!("Comfort against {key}");
    let chart = Chart {
        title: &title,
        x_label: key,
        y_label: "P_CT (%), peak lateral acceleration (%g)",
        lines: vec![
            line(
                "P_CT standing",
                column(ok, "p_ct_standing"),
                "#1f77b4",
                false,
            ),
            line("P_CT seated", column(ok, "p_ct_seated"), "#2ca02c", false),
            line(
                "lat. acc. peak (%g)",
                column(ok, "lat_acc_peak_pct_g"),
                "#d62728",
                true,
            ),
        ],
        bands: Vec::new(),
        note: "",
    };
    files.extend(crate::plot::write_chart(dir, "sweep_comfort", &chart, &x)?);
    Ok(files)
}

fn write_plots(
    out: &Path,
    base: &Scenario,
    plan: &Plan,
    rows: &[Row],
) -> std::io::Result<Vec<PathBuf>> {
    let dir = out.join("plots");
    std::fs::create_dir_all(&dir)?;
    let ok: Vec<&Row> = rows.iter().filter(|r| r.status.completed()).collect();
    let n = ok.iter().map(|r| r.series.len()).min().unwrap_or(0);
    let t: Vec<f64> = (0..n).map(|i| (i + 1) as f64 * SERIES_DT).collect();
    let bands = crate::analysis::bands(base);
    match plan {
        Plan::MonteCarlo { .. } => monte_carlo_plots(&dir, &ok, &t, bands),
        Plan::Grid { key, .. } => grid_plots(&dir, key, &ok, &t, bands),
    }
}

fn parse_f64s<'a>(fields: impl Iterator<Item = &'a str>, what: &str) -> Result<Vec<f64>, String> {
    fields
        .map(|x| {
            x.parse::<f64>()
                .map_err(|_| format!("{what}: `{x}` is not a number"))
        })
        .collect()
}

/// The records of CSV `bytes` read from `path`, each with where it is (file and line).
fn records(path: &Path, bytes: &[u8]) -> Result<Vec<(String, csv::StringRecord)>, String> {
    let mut rd = csv::ReaderBuilder::new().flexible(true).from_reader(bytes);
    rd.records()
        .enumerate()
        .map(|(i, r)| {
            let at = format!("{} line {}", path.display(), i + 2);
            r.map(|r| (at.clone(), r)).map_err(|e| format!("{at}: {e}"))
        })
        .collect()
}

/// One record of `samples.csv`.
fn sample_row(at: &str, f: &csv::StringRecord, ncol: usize) -> Result<Row, String> {
    let want = 3 + ncol + METRICS.len();
    if f.len() != want {
        return Err(format!("{at}: {} fields, expected {want}", f.len()));
    }
    let status = &f[1 + ncol];
    Ok(Row {
        sample: f[0]
            .parse()
            .map_err(|_| format!("{at}: bad sample index `{}`", &f[0]))?,
        params: parse_f64s(f.iter().skip(1).take(ncol), at)?,
        status: SampleStatus::parse(status)
            .ok_or_else(|| format!("{at}: status `{status}` is neither completed nor failed"))?,
        metrics: parse_f64s(f.iter().skip(2 + ncol).take(METRICS.len()), at)?,
        flags: f[want - 1]
            .split("; ")
            .filter(|x| !x.is_empty())
            .map(str::to_string)
            .collect(),
        series: Vec::new(),
    })
}

/// A sweep's (or shard's) outputs as read back and verified: its meta, base scenario and rows,
/// each row with where it is in `samples.csv`.
pub struct Outputs {
    /// The directory.
    pub dir: PathBuf,
    /// `sweep.json`.
    pub meta: SweepFile,
    /// `scenario.toml`.
    pub base: Scenario,
    /// The rows with their place (`DIR/samples.csv line N`).
    pub rows: Vec<(String, Row)>,
    /// The samples `series.csv` has a line for.
    pub series: std::collections::BTreeSet<usize>,
    /// Lines of `series.csv` for samples not in `samples.csv`, each as its error.
    pub orphans: Vec<String>,
}

/// Reads a sweep's (or shard's) outputs back, each file checked against the checksum
/// `sweep.json` holds for it and the fingerprint against the scenario, plan and build.
pub fn read_outputs(dir: &Path) -> Result<Outputs, SweepError> {
    outputs(dir).map_err(SweepError::Files)
}

fn outputs(dir: &Path) -> Result<Outputs, String> {
    let meta_path = dir.join("sweep.json");
    let text =
        std::fs::read_to_string(&meta_path).map_err(|e| format!("{}: {e}", meta_path.display()))?;
    let meta: SweepFile = serde_json::from_str(&text).map_err(|e| {
        format!(
            "{}: {e} (not the sweep.json of a sweep of this version of tiltsim: run the sweep again)",
            meta_path.display()
        )
    })?;
    let verified = |name: &str| -> Result<Vec<u8>, String> {
        let p = dir.join(name);
        let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
        let want = meta
            .sha256
            .get(name)
            .ok_or_else(|| format!("{}: no checksum of {name}", meta_path.display()))?;
        if identity::sha256(&bytes) != *want {
            return Err(format!(
                "{}: changed since the sweep wrote it (its SHA-256 is not the one {} records)",
                p.display(),
                meta_path.display()
            ));
        }
        Ok(bytes)
    };
    let scenario_path = dir.join("scenario.toml");
    let scenario = String::from_utf8(verified("scenario.toml")?)
        .map_err(|e| format!("{}: {e}", scenario_path.display()))?;
    if identity::fingerprint(&scenario, &meta.plan, &meta.build) != meta.fingerprint {
        return Err(format!(
            "{}: its fingerprint is not that of its scenario.toml, plan and build",
            meta_path.display()
        ));
    }
    let base = Scenario::parse(&scenario, &scenario_path).map_err(|e| e.to_string())?;
    let ncol = meta.plan.columns().len();
    let samples_path = dir.join("samples.csv");
    let mut rows = records(&samples_path, &verified("samples.csv")?)?
        .iter()
        .map(|(at, f)| sample_row(at, f, ncol).map(|r| (at.clone(), r)))
        .collect::<Result<Vec<_>, _>>()?;
    let series_path = dir.join("series.csv");
    let mut seen = std::collections::BTreeSet::new();
    let mut orphans = Vec::new();
    for (at, f) in records(&series_path, &verified("series.csv")?)? {
        let j: usize = f
            .get(0)
            .and_then(|x| x.parse().ok())
            .ok_or_else(|| format!("{at}: bad sample index"))?;
        if !seen.insert(j) {
            return Err(format!("{at}: sample {j} appears twice"));
        }
        let series = parse_f64s(f.iter().skip(1), &at)?;
        match rows.iter_mut().find(|(_, r)| r.sample == j) {
            Some(row) => row.1.series = series,
            None => orphans.push(format!("{at}: sample {j} is not in samples.csv")),
        }
    }
    Ok(Outputs {
        dir: dir.to_path_buf(),
        meta,
        base,
        rows,
        series: seen,
        orphans,
    })
}

/// Joins shard outputs: each verified ([`read_outputs`]), all of one sweep (fingerprint:
/// scenario, plan, build), each shard of one split once, every sample of the plan exactly once
/// with the plan's parameters. Errors name the directory or the file and line.
pub fn merge(dirs: &[PathBuf]) -> Result<(Scenario, Plan, String, Vec<Row>), SweepError> {
    let mut all = Vec::new();
    for d in dirs {
        all.push(read_outputs(d)?);
    }
    join(all).map_err(SweepError::Merge)
}

fn join(shards: Vec<Outputs>) -> Result<(Scenario, Plan, String, Vec<Row>), String> {
    let first = shards.first().ok_or("no shard directories given")?;
    let (d0, m0) = (first.dir.clone(), first.meta.clone());
    let (base, plan) = (first.base.clone(), m0.plan.clone());
    let n = plan.len();
    let shard_of = |o: &Outputs| match &o.meta.shard {
        None => Ok(Shard { index: 0, count: 1 }),
        Some(t) => Shard::parse(t).map_err(|_| {
            format!(
                "{}: shard `{t}` is not I/N",
                o.dir.join("sweep.json").display()
            )
        }),
    };
    let split = shard_of(first)?.count;
    let mut taken: Vec<Option<PathBuf>> = vec![None; split];
    let mut rows: Vec<Row> = Vec::new();
    for o in &shards {
        let (d, m) = (&o.dir, &o.meta);
        if m.interrupted {
            return Err(format!(
                "{}: the sweep there was interrupted (sweep.json: \"interrupted\": true): start it again with the same arguments to finish it, then merge",
                d.display()
            ));
        }
        if m.plan != m0.plan {
            return Err(format!(
                "{}: a different sweep plan than {}",
                d.display(),
                d0.display()
            ));
        }
        if o.base != base {
            return Err(format!(
                "{}: a different base scenario than {}",
                d.display(),
                d0.display()
            ));
        }
        if m.build != m0.build {
            return Err(format!(
                "{}: computed by another build of tiltsim ({}) than {} ({}): run the shards with one build",
                d.display(),
                m.build,
                d0.display(),
                m0.build
            ));
        }
        if m.fingerprint != m0.fingerprint {
            return Err(format!(
                "{}: another sweep than {} (fingerprint differs)",
                d.display(),
                d0.display()
            ));
        }
        let sh = shard_of(o)?;
        let name = format!("{}/{}", sh.index, sh.count);
        if sh.count != split {
            return Err(format!(
                "{} is shard {name}, {} is shard {}: shards of different splits",
                d.display(),
                d0.display(),
                shard_name(first)
            ));
        }
        if let Some(other) = &taken[sh.index] {
            return Err(format!(
                "{} and {} are both shard {name}",
                other.display(),
                d.display()
            ));
        }
        taken[sh.index] = Some(d.clone());
        let mine = sh.samples(n);
        let mut seen = std::collections::BTreeSet::new();
        for (at, r) in &o.rows {
            if r.sample >= n {
                return Err(format!(
                    "{at}: sample {} is not in the plan ({n} samples)",
                    r.sample
                ));
            }
            if mine.binary_search(&r.sample).is_err() {
                return Err(format!("{at}: sample {} is not in shard {name}", r.sample));
            }
            if !seen.insert(r.sample) {
                return Err(format!("{at}: sample {} appears twice", r.sample));
            }
            check_params(&base, &plan, r).map_err(|e| format!("{at}: {e}"))?;
            if !o.series.contains(&r.sample) {
                return Err(format!(
                    "{at}: sample {} has no line in {}",
                    r.sample,
                    d.join("series.csv").display()
                ));
            }
        }
        let absent: Vec<usize> = mine.iter().filter(|j| !seen.contains(j)).copied().collect();
        if !absent.is_empty() {
            return Err(format!(
                "{}: {} of the {} samples of shard {name} missing (first: {:?})",
                d.join("samples.csv").display(),
                absent.len(),
                mine.len(),
                &absent[..absent.len().min(5)]
            ));
        }
        if let Some(e) = o.orphans.first() {
            return Err(e.clone());
        }
        if m.samples != seen.iter().copied().collect::<Vec<_>>() {
            return Err(format!(
                "{}: its list of samples is not that of samples.csv",
                d.join("sweep.json").display()
            ));
        }
        rows.extend(o.rows.iter().map(|(_, r)| r.clone()));
    }
    rows.sort_by_key(|r| r.sample);
    let missing: Vec<usize> = (0..n)
        .filter(|j| rows.binary_search_by_key(j, |r| r.sample).is_err())
        .collect();
    if !missing.is_empty() {
        let absent: Vec<String> = (0..split)
            .filter(|i| taken[*i].is_none())
            .map(|i| format!("{i}/{split}"))
            .collect();
        return Err(format!(
            "{} of {n} samples missing (first: {:?}): shard {} absent",
            missing.len(),
            &missing[..missing.len().min(5)],
            absent.join(", ")
        ));
    }
    Ok((base, plan, m0.build, rows))
}

fn shard_name(o: &Outputs) -> String {
    o.meta
        .shard
        .clone()
        .unwrap_or_else(|| "0/1 (a whole sweep)".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_specs_parse_to_exact_values_and_bad_ones_are_named() {
        let Plan::Grid { key, values } = parse_grid("run.seed=1:5:2").unwrap() else {
            panic!()
        };
        assert_eq!((key.as_str(), values), ("run.seed", vec![1.0, 3.0, 5.0]));
        let Plan::Grid { values, .. } = parse_grid("x=0:0.3:0.1").unwrap() else {
            panic!()
        };
        assert_eq!(values.len(), 4);
        let Plan::Grid { values, .. } = parse_grid("x=3,1.5").unwrap() else {
            panic!()
        };
        assert_eq!(values, vec![3.0, 1.5]);
        for bad in ["x", "x=1:2", "x=2:1:1", "x=a,b", "=1"] {
            assert!(parse_grid(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_shard_of_an_array_task_is_read_from_its_scheduler() {
        let env = |vars: &'static [(&'static str, &'static str)]| {
            move |k: &str| {
                vars.iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            }
        };
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ]);
        assert_eq!(
            Shard::auto(None, slurm).unwrap(),
            Shard { index: 4, count: 8 }
        );
        // `--array=0-6:2`: tasks 0, 2, 4, 6 are shards 0..3 of 4.
        for (id, index) in [("0", 0), ("2", 1), ("4", 2), ("6", 3)] {
            let vars: Vec<(&str, &str)> = vec![
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_MAX", "6"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ];
            let var = |k: &str| {
                vars.iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            };
            assert_eq!(Shard::auto(None, var).unwrap(), Shard { index, count: 4 });
        }
        // `sbatch --array=2`, task 2 of a larger array submitted again: refused, saying how.
        let single = env(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_MIN", "2"),
            ("SLURM_ARRAY_TASK_MAX", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ]);
        let e = Shard::auto(None, single).unwrap_err().to_string();
        assert!(e.contains("--shard 2/8") && e.contains("--array=2"), "{e}");
        // An array of one task numbered 0 is a sweep of one shard.
        let one = env(&[
            ("SLURM_ARRAY_TASK_ID", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ]);
        assert_eq!(
            Shard::auto(None, one).unwrap(),
            Shard { index: 0, count: 1 }
        );
        // `--array=1,2,5`: not evenly spaced, refused.
        let uneven = env(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ]);
        let e = Shard::auto(None, uneven).unwrap_err().to_string();
        assert!(
            e.contains("evenly spaced") && e.contains("--shard I/N"),
            "{e}"
        );
        let aws = env(&[
            ("AWS_BATCH_JOB_ARRAY_INDEX", "2"),
            ("AWS_BATCH_JOB_ARRAY_SIZE", "3"),
        ]);
        assert_eq!(
            Shard::auto(None, aws).unwrap(),
            Shard { index: 2, count: 3 }
        );
        let k8s = env(&[("JOB_COMPLETION_INDEX", "1")]);
        assert_eq!(
            Shard::auto(Some(4), k8s).unwrap(),
            Shard { index: 1, count: 4 }
        );
        let e = Shard::auto(None, k8s).unwrap_err().to_string();
        assert!(e.contains("--shards N"), "{e}");
        let e = Shard::auto(None, env(&[])).unwrap_err().to_string();
        assert!(
            e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"),
            "{e}"
        );
        let bad = env(&[
            ("AWS_BATCH_JOB_ARRAY_INDEX", "3"),
            ("AWS_BATCH_JOB_ARRAY_SIZE", "3"),
        ]);
        assert!(Shard::auto(None, bad).is_err());
    }

    #[test]
    fn monte_carlo_factors_are_within_the_spread_and_fixed_per_sample() {
        let base = Scenario::default();
        let plan = Plan::MonteCarlo {
            samples: 50,
            spread: 0.22,
            seed: 7,
        };
        let (s3, f3) = sample(&base, &plan, 3).unwrap();
        assert_eq!(
            sample(&base, &plan, 3).unwrap().1,
            f3,
            "a sample is reproducible"
        );
        assert_ne!(sample(&base, &plan, 4).unwrap().1, f3, "samples differ");
        assert!((s3.vehicle.m_v / base.vehicle.m_v - f3[0]).abs() < 1e-12);
        assert_eq!(s3.design_vehicle.as_ref(), Some(&base.vehicle));
        let mut lo: f64 = 1.0;
        let mut hi: f64 = 1.0;
        for j in 0..50 {
            for f in sample(&base, &plan, j).unwrap().1 {
                lo = lo.min(f);
                hi = hi.max(f);
            }
        }
        // 750 uniform draws: all inside ±22 %, and reaching near both ends.
        assert!(lo >= 0.78 && hi <= 1.22, "{lo} {hi}");
        assert!(lo < 0.80 && hi > 1.20, "{lo} {hi}");
    }

    #[test]
    fn keys_are_set_with_their_type_and_checked() {
        let base = Scenario::default();
        let s = with_key(&base, "vehicle.m_v", 21000.0).unwrap();
        assert_eq!(s.vehicle.m_v, 21000.0);
        let s = with_key(&base, "run.seed", 9.0).unwrap();
        assert_eq!(s.run.seed, 9);
        let e = with_key(&base, "run.seed", 1.5).unwrap_err().to_string();
        assert!(e.contains("whole numbers"), "{e}");
        let e = with_key(&base, "vehicle.m_vv", 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("m_vv"), "{e}");
        // An unknown section is named as the user wrote it, with no line of an internal
        // document.
        let e = with_key(&base, "foo.bar", 1.0).unwrap_err().to_string();
        assert!(
            e.contains("key `foo.bar`") && e.contains("unknown field `foo`"),
            "{e}"
        );
        assert!(!e.contains("line "), "{e}");
        let e = with_key(&base, "vehicle.m_v", -1.0).unwrap_err();
        assert!(matches!(e, SweepError::Argument(_)));
        assert!(e.to_string().contains("vehicle.m_v"), "{e}");
    }

    #[test]
    fn percentiles_interpolate_between_order_statistics() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(percentile(&v, 0.5), 3.0);
        assert_eq!(percentile(&v, 0.05), 1.2);
        assert_eq!(percentile(&v, 1.0), 5.0);
        assert!(percentile(&[], 0.5).is_nan());
    }
}
