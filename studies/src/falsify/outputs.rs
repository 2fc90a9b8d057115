//! What a search leaves in its directory: `progress.csv` and `progress.svg`/`.png` (the
//! objective per evaluation, search against random sampling), `worst/` (the worst timing as
//! `worst/timing.csv`, replayable with `tiltsim replay-timing OUT/worst`, and its replay's run
//! directory with figures), `bounds.toml` (the bounds searched, also when taken from recorded
//! runs) and `result.json`.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use serde::Serialize;
use tiltsim_assessment::comfort::METRICS;
use tiltsim_master::engine::{RunOptions, Status};
use tiltsim_master::free::trace::{TraceWriter, TIMING_CSV};
use tiltsim_report::plot::{Chart, Line};
use tiltsim_scenario::scenario::Scenario;

use super::history::Layout;
use super::objective::Score;
use super::search::{Eval, Falsified, Method, Spec};
use super::FalsifyError;
use crate::sweep::Shard;

/// The method's citation, as `result.json` and the figure give it.
pub const CMA_ES_CITATION: &str =
    "CMA-ES: N. Hansen, The CMA Evolution Strategy: A Tutorial, arXiv:1604.00772 (2016)";

/// The verdict on a requirement from whether the worst timing breaks it (`None`: no
/// requirement).
pub fn verdict(violated: Option<bool>) -> Option<&'static str> {
    violated.map(|v| if v { "violated" } else { "not-falsified" })
}

/// One requirement's judgement of the worst timing, in `result.json` → `requirements`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Judgement {
    /// The requirement as it reads.
    pub requirement: String,
    /// Its margin at the worst timing (negative: broken by that much; `null` when it is not
    /// a finite number: +∞ for a formula nothing in the run put to the test).
    pub margin: f64,
    /// Whether it holds there.
    pub holds: bool,
}

/// `result.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    /// The scenario's name.
    pub scenario: String,
    /// What was maximised (`maximise KEY`, or the requirement).
    pub objective: String,
    /// The metric's key.
    pub metric: String,
    /// The search method.
    pub method: &'static str,
    /// Evaluations of the search (and of the random sampling).
    pub budget: usize,
    /// The seed.
    pub seed: u64,
    /// Coordinates of a point.
    pub dims: usize,
    /// CMA-ES population size.
    pub lambda: usize,
    /// The metric with the lock-step timing (a plain run of the scenario).
    pub nominal_metric: f64,
    /// The best objective the search found, and the random sampling.
    pub search_best: f64,
    /// See `search_best`.
    pub random_best: f64,
    /// The worst timing: who found it, at which evaluation, its metric and objective.
    pub worst_found_by: String,
    /// The phase of the method that found it (`adversary`, `cma-es`, `mutation`, `random`).
    pub worst_phase: String,
    /// Whether the worst timing's replay has valid comfort numbers (`comfort_valid`).
    pub worst_valid: bool,
    /// The validity flags the worst timing's replay raised.
    pub worst_flags: Vec<String>,
    /// Obvious adversaries the search evaluated first (each shard's, summed when merged).
    pub adversaries: usize,
    /// See `worst_found_by`.
    pub worst_evaluation: usize,
    /// The metric of the worst timing.
    pub worst_metric: f64,
    /// The objective of the worst timing.
    pub worst_objective: f64,
    /// The metric of the worst trace's replay written to `worst/` (equal to `worst_metric`).
    pub worst_run_metric: f64,
    /// For a requirement: whether the worst timing breaks it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub violated: Option<bool>,
    /// For requirements: their margin at the worst timing (negative: broken by that much;
    /// several: the least of their margins each as a fraction of its bound).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub margin: Option<f64>,
    /// For requirements: each one's judgement of the worst timing's replay.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub requirements: Option<Vec<Judgement>>,
    /// What the worst timing owes to each bound: the objective without it, largest drop
    /// first (not for merged shards).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensitivity: Option<Vec<super::margin::Share>>,
    /// For requirements, with `--margin`: the largest scale of the bounds at which they were
    /// not falsified and the smallest at which they were, with its counterexample.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timing_margin: Option<super::margin::TimingMargin>,
    /// For a requirement: `violated` (the worst timing found breaks it: `worst/timing.csv` is
    /// the counterexample) or `not-falsified` (no timing evaluated breaks it, which is not a
    /// proof that none does). `tiltsim falsify` exits 3 when violated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub verdict: Option<&'static str>,
    /// For a requirement: the random sampling's timings, drawn uniformly from the bounds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub random_samples: Option<usize>,
    /// For a requirement: of them, those that broke it (a failed replay counts as broken).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub random_broken: Option<usize>,
    /// For a requirement: the one-sided 95 % upper bound (Clopper-Pearson) on the probability
    /// that a timing drawn from the sampler breaks it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub random_broken_upper_95: Option<f64>,
    /// Evaluations that failed.
    pub failed_evaluations: usize,
    /// Mean CPU time of one evaluation (s).
    pub evaluation_cpu_s: f64,
    /// CPU time of a plain in-process run of the scenario, rows in memory (s), for comparison.
    pub plain_run_cpu_s: f64,
    /// Wall time of the search and the sampling (s).
    pub search_s: f64,
    /// Evaluations taken from an earlier invocation.
    pub resumed_evaluations: usize,
    /// The shard this directory holds (`I/N`), when the search was split.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<String>,
    /// Shards merged here (`falsify-merge`, `--restarts`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub merged_shards: Option<usize>,
    /// The shard whose worst timing is the worst found (merged).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worst_shard: Option<usize>,
}

fn files_error(path: &Path, e: impl std::fmt::Display) -> FalsifyError {
    FalsifyError::Files(format!("{}: {e}", path.display()))
}

/// A plain lock-step run of `s` in process, rows in memory: the nominal metric and the CPU
/// time of the run (the cost an evaluation is measured against).
pub fn nominal(s: &Scenario, spec: &Spec, out: &Path, interrupt: &Arc<AtomicBool>) -> (f64, f64) {
    let dir = out.join("evals").join("nominal");
    let mut opts = RunOptions::new(dir.clone(), PathBuf::new());
    opts.interrupt = interrupt.clone();
    opts.plots = false;
    opts.timing = false;
    let mut job = tiltsim_runner::pipeline::Job::new(s, s.name.clone(), opts);
    job.claim = false;
    job.outputs.rows_in_memory = true;
    let t0 = super::search::thread_cpu_s();
    let done = tiltsim_runner::pipeline::carry_out(job);
    let wall = super::search::thread_cpu_s() - t0;
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir(out.join("evals"));
    let m = match done {
        Ok(d) if d.summary.status == Status::Completed => {
            (METRICS[spec.objective.metric()].get)(&d.summary.comfort)
        }
        _ => f64::NAN,
    };
    (m, wall)
}

/// Writes the worst timing's trace to `out/worst/timing.csv` and replays it there (a run
/// directory with its figures); returns what the objective makes of the replay.
pub fn write_worst(
    s: &Scenario,
    spec: &Spec,
    f: &Falsified,
    out: &Path,
    interrupt: &Arc<AtomicBool>,
) -> Result<Score, FalsifyError> {
    let trace = Layout::new(s, &f.ticks).trace(s, &f.worst.0);
    replay_worst(s, spec, out, interrupt, |path| {
        let mut w = TraceWriter::create(path, &trace.head).map_err(|e| files_error(path, e))?;
        for t in &trace.steps {
            w.push(t).map_err(|e| files_error(path, e))?;
        }
        w.finish().map_err(|e| files_error(path, e))
    })
}

/// Takes `out/worst`, has `write` put the worst timing's trace in `out/worst/timing.csv`,
/// and replays it there (a run directory with its figures); returns what the objective makes
/// of the replay.
pub fn replay_worst(
    s: &Scenario,
    spec: &Spec,
    out: &Path,
    interrupt: &Arc<AtomicBool>,
    write: impl FnOnce(&Path) -> Result<(), FalsifyError>,
) -> Result<Score, FalsifyError> {
    let dir = out.join("worst");
    let lock = tiltsim_rundir::outdir::claim_run(&dir, "falsify")
        .map_err(|e| FalsifyError::Invalid(e.to_string()))?;
    let path = dir.join(TIMING_CSV);
    write(&path)?;
    let mut opts = RunOptions::new(dir.clone(), PathBuf::new());
    opts.interrupt = interrupt.clone();
    let mut job = tiltsim_runner::pipeline::Job::new(s, s.name.clone(), opts);
    job.claim = false;
    job.replay_trace = Some(path);
    let done =
        tiltsim_runner::pipeline::carry_out(job).map_err(|e| FalsifyError::Run(e.to_string()))?;
    drop(lock);
    if done.summary.status != Status::Completed {
        return Err(FalsifyError::Run(format!(
            "the replay of the worst timing in {} failed: {}",
            dir.display(),
            done.summary.error.unwrap_or_default()
        )));
    }
    let rows = if spec.objective.on_signals() {
        tiltsim_formats::table::read_rows(&dir).map_err(|e| files_error(&dir, e))?
    } else {
        Vec::new()
    };
    Ok(super::search::judge(
        s,
        &spec.objective,
        &done.summary,
        &rows,
    ))
}

/// Each requirement's judgement in `score` (`None` when a metric is maximised).
pub fn judgements(spec: &Spec, score: &Score) -> Option<Vec<Judgement>> {
    spec.objective.is_requirement().then(|| {
        spec.objective
            .each()
            .into_iter()
            .zip(&score.checks)
            .map(|(requirement, c)| Judgement {
                requirement,
                margin: c.margin,
                holds: c.holds,
            })
            .collect()
    })
}

/// Writes `progress.csv` and the progress figure.
pub fn write_progress(
    out: &Path,
    s: &Scenario,
    spec: &Spec,
    evals: &[Eval],
) -> Result<(), FalsifyError> {
    let csv_path = out.join("progress.csv");
    let mut w = csv::Writer::from_path(&csv_path).map_err(|e| files_error(&csv_path, e))?;
    for e in evals {
        w.serialize(e).map_err(|e| files_error(&csv_path, e))?;
    }
    w.flush().map_err(|e| files_error(&csv_path, e))?;
    write_chart(out, s, spec, evals)
}

/// `progress.csv` of merged shards: each evaluation with the shard it came from first.
pub fn write_merged_progress(
    out: &Path,
    s: &Scenario,
    spec: &Spec,
    evals: &[(usize, Eval)],
) -> Result<(), FalsifyError> {
    let csv_path = out.join("progress.csv");
    let mut w = csv::Writer::from_path(&csv_path).map_err(|e| files_error(&csv_path, e))?;
    let io = |e: csv::Error| files_error(&csv_path, e);
    let header: Vec<&str> = std::iter::once("shard")
        .chain(super::search::EVAL_COLUMNS)
        .collect();
    w.write_record(&header).map_err(io)?;
    for (shard, e) in evals {
        w.serialize((
            shard,
            e.method,
            e.evaluation,
            e.phase,
            e.metric,
            e.objective,
            e.margin,
            e.violated,
            e.best_so_far,
            e.valid,
            &e.flags,
            &e.error,
        ))
        .map_err(io)?;
    }
    w.flush().map_err(|e| files_error(&csv_path, e))?;
    let plain: Vec<Eval> = evals.iter().map(|(_, e)| e.clone()).collect();
    write_chart(out, s, spec, &plain)
}

/// The progress figure: each method's best so far, and each evaluation of the search.
fn write_chart(out: &Path, s: &Scenario, spec: &Spec, evals: &[Eval]) -> Result<(), FalsifyError> {
    let series = |m: Method, best: bool| -> Vec<f64> {
        evals
            .iter()
            .filter(|e| e.method == m)
            .map(|e| {
                let v = if best { e.best_so_far } else { e.objective };
                // A requirement is shown by its margin (the objective negated).
                if spec.objective.is_requirement() {
                    -v
                } else {
                    v
                }
            })
            .collect()
    };
    let n = evals.iter().filter(|e| e.method == Method::CmaEs).count();
    let x: Vec<f64> = (1..=n).map(|i| i as f64).collect();
    let requirement = spec.objective.is_requirement();
    let y_label = if requirement {
        format!("margin of {} (lowest so far)", spec.objective.describe())
    } else {
        format!(
            "{} (largest so far)",
            METRICS[spec.objective.metric()].label
        )
    };
    let title = format!(
        "{}: falsifying timing, CMA-ES against uniform random sampling ({} evaluations each)",
        s.name, spec.budget
    );
    let mut lines = vec![
        Line {
            label: "CMA-ES, each evaluation",
            y: series(Method::CmaEs, false),
            colour: "#9ecae1",
            ..Default::default()
        },
        Line {
            label: "CMA-ES, best so far",
            y: series(Method::CmaEs, true),
            colour: "#08519c",
            ..Default::default()
        },
        Line {
            label: "random sampling, best so far",
            y: series(Method::Random, true),
            colour: "#d94801",
            dashed: true,
            ..Default::default()
        },
    ];
    if requirement {
        lines.push(Line {
            label: "requirement broken below 0",
            y: vec![0.0; n],
            colour: "#000000",
            dashed: true,
            ..Default::default()
        });
    }
    let chart = Chart {
        title: &title,
        x_label: "evaluation",
        y_label: &y_label,
        lines,
        note: CMA_ES_CITATION,
        ..Default::default()
    };
    if n > 0 {
        tiltsim_report::plot::write_chart(out, "progress", &chart, &x)
            .map_err(|e| files_error(&out.join("progress.svg"), e))?;
    }
    Ok(())
}

/// The best-so-far of each method after `k` evaluations, at a few points of the budget (the
/// table `tiltsim falsify` prints).
pub fn checkpoints(evals: &[Eval], budget: usize) -> Vec<(usize, f64, f64)> {
    let mut at: Vec<usize> = [10, 25, 50, 100]
        .iter()
        .map(|p| (budget * p).div_ceil(100).max(1))
        .collect();
    at.dedup();
    let best = |m: Method, k: usize| {
        evals
            .iter()
            .filter(|e| e.method == m && e.evaluation == k)
            .map(|e| e.best_so_far)
            .next()
            .unwrap_or(f64::NAN)
    };
    at.into_iter()
        .map(|k| (k, best(Method::CmaEs, k), best(Method::Random, k)))
        .collect()
}

/// The flags of an evaluation (`;`-separated) as a list.
pub fn flag_list(flags: &str) -> Vec<String> {
    flags
        .split(';')
        .filter(|f| !f.is_empty())
        .map(str::to_string)
        .collect()
}

/// `result.json` and `bounds.toml`.
pub fn write_result(out: &Path, spec: &Spec, o: &Outcome) -> Result<(), FalsifyError> {
    let path = out.join("result.json");
    let text = serde_json::to_string_pretty(o).unwrap_or_default() + "\n";
    tiltsim_rundir::files::write_atomic(&path, text).map_err(|e| files_error(&path, e))?;
    let path = out.join("bounds.toml");
    let text = format!(
        "# The admissible timing searched ({}), in the format of `--bounds`.\n{}",
        spec.bounds_from,
        spec.bounds.to_toml()
    );
    tiltsim_rundir::files::write_atomic(&path, text).map_err(|e| files_error(&path, e))
}

/// Carries out a whole search into `ex.out`: the nominal run, the search and the sampling,
/// the worst timing's replay, the progress and the result.
pub fn falsify(
    s: &Scenario,
    spec: &Spec,
    ex: &super::Exec,
) -> Result<(Falsified, Outcome), FalsifyError> {
    falsify_part(s, spec, None, ex)
}

/// [`falsify`] of shard `shard` of the search `spec` (`None`: all of it): the shard's share
/// of the budget with its own seed, and `shard.json` saying which part of which search the
/// directory holds.
pub fn falsify_part(
    s: &Scenario,
    whole: &Spec,
    shard: Option<Shard>,
    ex: &super::Exec,
) -> Result<(Falsified, Outcome), FalsifyError> {
    std::fs::create_dir_all(&ex.out).map_err(|e| files_error(&ex.out, e))?;
    let part = match shard {
        Some(sh) => super::shards::shard_spec(whole, sh, "--shard")?,
        None => whole.clone(),
    };
    let spec = &part;
    if shard.is_none() {
        // The directory of an earlier shard is no longer one.
        let path = ex.out.join(super::shards::SHARD_JSON);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|e| files_error(&path, e))?;
        }
    }
    if let Some(sh) = shard {
        super::shards::write_info(
            &ex.out,
            &super::shards::ShardInfo {
                index: sh.index,
                count: sh.count,
                search: super::search::fingerprint(s, whole),
                budget: whole.budget,
                seed: whole.seed,
                shard_seed: spec.seed,
                objective: spec.objective.describe(),
                bounds_from: spec.bounds_from.clone(),
            },
        )?;
    }
    let (nominal_metric, plain_run_s) = nominal(s, spec, &ex.out, &ex.interrupt);
    let f = super::run(s, spec, ex)?;
    let replayed = write_worst(s, spec, &f, &ex.out, &ex.interrupt)?;
    let sensitivity = super::margin::sensitivity(s, spec, &f, ex)?;
    let timing_margin = match spec.margin {
        Some(plan) if spec.objective.is_requirement() && shard.is_none() => {
            Some(super::margin::timing_margin(s, spec, &f, ex, plan)?)
        }
        _ => None,
    };
    write_progress(&ex.out, s, spec, &f.evals)?;
    let found = Found {
        nominal_metric,
        plain_run_s,
        replayed,
        sensitivity,
        timing_margin,
    };
    let o = outcome(s, spec, shard, &f, found);
    write_result(&ex.out, spec, &o)?;
    if shard.is_some() {
        super::shards::write_digests(&ex.out)?;
    } else {
        // A directory that held a shard before holds a whole search now.
        let _ = std::fs::remove_file(ex.out.join(super::shards::DIGESTS));
    }
    Ok((f, o))
}

/// What a search's result holds beside its evaluations.
struct Found {
    nominal_metric: f64,
    plain_run_s: f64,
    replayed: Score,
    sensitivity: Vec<super::margin::Share>,
    timing_margin: Option<super::margin::TimingMargin>,
}

/// `result.json` of the search `f` of `spec` (shard `shard`).
fn outcome(
    s: &Scenario,
    spec: &Spec,
    shard: Option<Shard>,
    f: &Falsified,
    found: Found,
) -> Outcome {
    let best = |m: Method| {
        f.evals
            .iter()
            .filter(|e| e.method == m)
            .map(|e| e.best_so_far)
            .next_back()
            .unwrap_or(f64::NAN)
    };
    let w = &f.worst.1;
    let requirement = spec.objective.is_requirement();
    let sampled = requirement.then(|| super::evidence::sampled(&spec.objective, f.evals.iter()));
    Outcome {
        scenario: s.name.clone(),
        objective: spec.objective.describe(),
        metric: spec.objective.key().to_string(),
        method: CMA_ES_CITATION,
        budget: spec.budget,
        seed: spec.seed,
        dims: f.dims,
        lambda: f.lambda,
        nominal_metric: found.nominal_metric,
        search_best: best(Method::CmaEs),
        random_best: best(Method::Random),
        worst_found_by: w.method.name().to_string(),
        worst_phase: w.phase.name().to_string(),
        worst_valid: w.valid,
        worst_flags: flag_list(&w.flags),
        adversaries: f.adversaries,
        worst_evaluation: w.evaluation,
        worst_metric: w.metric,
        worst_objective: w.objective,
        worst_run_metric: found.replayed.metric,
        violated: requirement.then_some(w.violated),
        margin: requirement.then_some(w.margin),
        requirements: judgements(spec, &found.replayed),
        sensitivity: Some(found.sensitivity),
        timing_margin: found.timing_margin,
        verdict: verdict(requirement.then_some(w.violated)),
        random_samples: sampled.map(|e| e.n),
        random_broken: sampled.map(|e| e.broken),
        random_broken_upper_95: sampled.map(|e| e.upper_95),
        failed_evaluations: f.evals.iter().filter(|e| !e.error.is_empty()).count(),
        evaluation_cpu_s: f.eval_s,
        plain_run_cpu_s: found.plain_run_s,
        search_s: f.wall_s,
        resumed_evaluations: f.resumed,
        shard: shard.map(|sh| format!("{}/{}", sh.index, sh.count)),
        merged_shards: None,
        worst_shard: None,
    }
}
