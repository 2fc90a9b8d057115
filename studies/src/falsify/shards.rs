//! A search split into shards, as sweeps are (`--shard I/N`, `--shard auto` for a batch
//! scheduler's array tasks): each shard is an independent CMA-ES restart with its own seed
//! and its share of the budget, beside its share of the random sampling; `falsify-merge`
//! (or `--restarts N`, the N shards in one process) joins them into one result.
//!
//! * Shard `i` of `n` spends `budget / n` evaluations of each method, one more when
//!   `i < budget mod n`; its seed is the search's for shard 0 and a mix of the seed and `i`
//!   for the others, so shard 0 of 1 is the unsharded search.
//! * The merge lists, for the search and then for the random sampling, shard 0's evaluations,
//!   then shard 1's, ..., numbered from 1 in that order, with the best so far over that
//!   sequence; the worst timing is the first evaluation of that order with the largest
//!   objective (CMA-ES before random sampling), which is its own shard's worst; its trace is
//!   that shard's `worst/timing.csv`, replayed again in the merged directory.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use tiltsim_master::free::trace::TIMING_CSV;
use tiltsim_scenario::scenario::Scenario;

use super::objective::Score;
use super::outputs::{replay_worst, write_merged_progress, write_result, Outcome, CMA_ES_CITATION};
use super::search::{Eval, Method, Spec};
use super::{Bounds, FalsifyError, Objective};
use crate::sweep::Shard;

/// The file that says which shard of which search a directory holds.
pub const SHARD_JSON: &str = "shard.json";

/// The seed of shard `index`: the search's own for shard 0, else a SplitMix64 mix of the two.
pub fn shard_seed(seed: u64, index: usize) -> u64 {
    if index == 0 {
        return seed;
    }
    let mut z = seed.wrapping_add((index as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Evaluations of each method shard `shard` of a search of `budget` spends.
pub fn share(budget: usize, shard: Shard) -> usize {
    budget / shard.count + usize::from(shard.index < budget % shard.count)
}

/// What shard `shard` of `spec` searches: its share of the budget, with its own seed.
/// Refused when a shard would have no evaluation (`flag` names the option in the error).
pub fn shard_spec(spec: &Spec, shard: Shard, flag: &str) -> Result<Spec, FalsifyError> {
    if spec.budget < shard.count {
        return Err(FalsifyError::Invalid(format!(
            "{flag}: {} shards for --budget {}; allowed: at most as many shards as evaluations",
            shard.count, spec.budget
        )));
    }
    Ok(Spec {
        budget: share(spec.budget, shard),
        seed: shard_seed(spec.seed, shard.index),
        ..spec.clone()
    })
}

/// `sha256.txt`: the SHA-256 of each file of a finished shard the merge reads, in the form
/// `sha256sum -c` checks, written last.
pub const DIGESTS: &str = "sha256.txt";

/// The files of a shard the merge reads, as [`DIGESTS`] lists them.
const DIGESTED: [&str; 5] = [
    SHARD_JSON,
    "result.json",
    "progress.csv",
    "bounds.toml",
    "worst/timing.csv",
];

/// The SHA-256 of a file, in hex.
fn sha256_hex(path: &Path) -> Result<String, FalsifyError> {
    use sha2::Digest;
    let bytes = std::fs::read(path).map_err(|e| files_error(path, e))?;
    Ok(sha2::Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// Writes `dir/sha256.txt` for a shard whose files are all written.
pub fn write_digests(dir: &Path) -> Result<(), FalsifyError> {
    let mut text = String::new();
    for f in DIGESTED {
        text.push_str(&format!("{}  {f}\n", sha256_hex(&dir.join(f))?));
    }
    let path = dir.join(DIGESTS);
    tiltsim_rundir::files::write_atomic(&path, text).map_err(|e| files_error(&path, e))
}

/// Checks each file of shard `dir` against the digest written with it: a file changed,
/// replaced or cut short after the shard finished is refused by name.
fn check_digests(dir: &Path) -> Result<(), FalsifyError> {
    let path = dir.join(DIGESTS);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        invalid(
            &path,
            format!("{e}: a finished shard writes it last; run the shard again to complete it"),
        )
    })?;
    let listed: std::collections::HashMap<&str, &str> = text
        .lines()
        .filter_map(|l| l.split_once("  ").map(|(h, f)| (f, h)))
        .collect();
    for f in DIGESTED {
        let Some(want) = listed.get(f) else {
            return Err(invalid(&path, format!("{f}: not listed")));
        };
        let file = dir.join(f);
        if sha256_hex(&file)? != *want {
            return Err(invalid(
                &file,
                format!(
                    "its SHA-256 is not the one {} holds: the file was changed after the shard \
                     finished; run the shard again",
                    path.display()
                ),
            ));
        }
    }
    Ok(())
}

/// `shard.json`: which shard of which search a directory holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardInfo {
    /// This shard (0-based).
    pub index: usize,
    /// Shards of the search.
    pub count: usize,
    /// The whole search's identity (scenario, bounds, objective, budget, seed, build).
    pub search: String,
    /// The whole search's budget (each method).
    pub budget: usize,
    /// The whole search's seed.
    pub seed: u64,
    /// This shard's seed.
    pub shard_seed: u64,
    /// The objective, as `result.json` describes it.
    pub objective: String,
    /// Where the bounds came from.
    pub bounds_from: String,
}

fn files_error(path: &Path, e: impl std::fmt::Display) -> FalsifyError {
    FalsifyError::Files(format!("{}: {e}", path.display()))
}

fn invalid(path: &Path, what: impl std::fmt::Display) -> FalsifyError {
    FalsifyError::Invalid(format!("{}: {what}", path.display()))
}

/// Writes `dir/shard.json`.
pub fn write_info(dir: &Path, info: &ShardInfo) -> Result<(), FalsifyError> {
    let path = dir.join(SHARD_JSON);
    let text = serde_json::to_string_pretty(info).unwrap_or_default() + "\n";
    tiltsim_rundir::files::write_atomic(&path, text).map_err(|e| files_error(&path, e))
}

/// One shard's directory, read for the merge.
#[derive(Debug, Clone)]
pub struct ShardDir {
    /// The directory.
    pub dir: PathBuf,
    /// Its `shard.json`.
    pub info: ShardInfo,
    /// Its `progress.csv`.
    pub evals: Vec<Eval>,
    /// Its `result.json`'s figures the merge keeps.
    pub result: ShardResult,
}

/// What the merge takes from a shard's `result.json`.
#[derive(Debug, Clone, Deserialize)]
pub struct ShardResult {
    /// The scenario's name.
    pub scenario: String,
    /// Coordinates of a point.
    pub dims: usize,
    /// CMA-ES population size.
    pub lambda: usize,
    /// The metric with the lock-step timing (`null`, NaN in `result.json`: not computed).
    #[serde(deserialize_with = "nan_if_null")]
    pub nominal_metric: f64,
    /// Mean CPU time of one evaluation run by the shard's last invocation (s; NaN when it
    /// took every evaluation from an earlier one).
    #[serde(deserialize_with = "nan_if_null")]
    pub evaluation_cpu_s: f64,
    /// CPU time of a plain in-process run (s).
    #[serde(deserialize_with = "nan_if_null")]
    pub plain_run_cpu_s: f64,
    /// Wall time of the search and the sampling (s).
    #[serde(deserialize_with = "nan_if_null")]
    pub search_s: f64,
    /// Evaluations taken from an earlier invocation.
    pub resumed_evaluations: usize,
    /// Obvious adversaries the shard evaluated.
    pub adversaries: usize,
}

/// A number of `result.json`, where serde_json writes NaN as `null`.
fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Reads shard directory `dir`: `shard.json`, `result.json`, `progress.csv` (whole: its
/// share of each method), `worst/timing.csv` present.
pub fn read_shard(dir: &Path) -> Result<ShardDir, FalsifyError> {
    let path = dir.join(SHARD_JSON);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        invalid(
            &path,
            format!("{e}; allowed: the output directory of `tiltsim falsify --shard I/N`"),
        )
    })?;
    let info: ShardInfo = serde_json::from_str(&text).map_err(|e| invalid(&path, e))?;
    check_digests(dir)?;
    if info.count == 0 || info.index >= info.count || info.budget < info.count {
        return Err(invalid(
            &path,
            format!(
                "index {}, count {}, budget {}: allowed a count of 1 to the budget and an index \
                 below the count",
                info.index, info.count, info.budget
            ),
        ));
    }
    let path = dir.join("result.json");
    let text = std::fs::read_to_string(&path).map_err(|e| {
        invalid(
            &path,
            format!("{e}: the shard has not finished; run it again to complete it"),
        )
    })?;
    let result: ShardResult = serde_json::from_str(&text).map_err(|e| invalid(&path, e))?;
    let path = dir.join("progress.csv");
    let mut evals = Vec::new();
    let mut r = csv::Reader::from_path(&path).map_err(|e| invalid(&path, e))?;
    for e in r.deserialize::<Eval>() {
        evals.push(e.map_err(|e| invalid(&path, e))?);
    }
    let want = share(
        info.budget,
        Shard {
            index: info.index,
            count: info.count,
        },
    );
    for m in [Method::CmaEs, Method::Random] {
        let n = evals.iter().filter(|e| e.method == m).count();
        if n != want {
            return Err(invalid(
                &path,
                format!(
                    "{n} {} evaluations; shard {}/{} of a budget of {} has {want}",
                    m.name(),
                    info.index,
                    info.count,
                    info.budget
                ),
            ));
        }
    }
    let trace = dir.join("worst").join(TIMING_CSV);
    if !trace.is_file() {
        return Err(invalid(&trace, "missing: the shard has not finished"));
    }
    Ok(ShardDir {
        dir: dir.to_path_buf(),
        info,
        evals,
        result,
    })
}

/// Reads `dirs` and checks they are the shards of one search, each once and none missing;
/// returns them in shard order.
pub fn read_all(dirs: &[PathBuf]) -> Result<Vec<ShardDir>, FalsifyError> {
    let mut shards = Vec::new();
    for d in dirs {
        shards.push(read_shard(d)?);
    }
    let Some(first) = shards.first().cloned() else {
        return Err(FalsifyError::Invalid(
            "falsify-merge: no shard directory given".into(),
        ));
    };
    for s in &shards[1..] {
        if s.info.search != first.info.search || s.info.count != first.info.count {
            return Err(invalid(
                &s.dir.join(SHARD_JSON),
                format!(
                    "search: a shard of another search than {} (scenario, bounds, objective, budget, seed and build must be the same)",
                    first.dir.display()
                ),
            ));
        }
    }
    shards.sort_by_key(|s| s.info.index);
    for (i, s) in shards.iter().enumerate() {
        if s.info.index != i {
            let what = if s.info.index < i {
                format!("index: shard {} given twice", s.info.index)
            } else {
                format!("index: shard {i} of {} is missing", first.info.count)
            };
            return Err(invalid(&s.dir.join(SHARD_JSON), what));
        }
    }
    if shards.len() != first.info.count {
        return Err(FalsifyError::Invalid(format!(
            "falsify-merge: {} shard directories given; the search has {} shards (missing: {} to {})",
            shards.len(),
            first.info.count,
            shards.len(),
            first.info.count - 1
        )));
    }
    Ok(shards)
}

/// The merged evaluations (see the module's description) with, for each, the shard it came
/// from; and the place in them of the worst.
pub fn combine(shards: &[ShardDir]) -> (Vec<(usize, Eval)>, Option<usize>) {
    let mut out: Vec<(usize, Eval)> = Vec::new();
    let mut worst: Option<usize> = None;
    for m in [Method::CmaEs, Method::Random] {
        let mut best = f64::NAN;
        let mut n = 0;
        for s in shards {
            for e in s.evals.iter().filter(|e| e.method == m) {
                n += 1;
                let better = !e.objective.is_nan() && (best.is_nan() || e.objective > best);
                if better {
                    best = e.objective;
                }
                let beats_worst =
                    !e.objective.is_nan() && worst.is_none_or(|w| e.objective > out[w].1.objective);
                if beats_worst {
                    worst = Some(out.len());
                }
                out.push((
                    s.info.index,
                    Eval {
                        evaluation: n,
                        best_so_far: best,
                        ..e.clone()
                    },
                ));
            }
        }
    }
    (out, worst)
}

/// The objective `result.json` describes (`maximise KEY`, or a requirement).
fn objective_of(described: &str, path: &Path) -> Result<Objective, FalsifyError> {
    match described.strip_prefix("maximise ") {
        Some(key) => Objective::maximise(key),
        None => Objective::requirement(described),
    }
    .map_err(|e| invalid(path, format!("objective: {e}")))
}

/// The worst is derived again: its trace, replayed to `replayed`, gives the metric, the
/// objective and the verdict the shard in `dir` claims for evaluation `we`, bit for bit (a
/// replay is deterministic); a shard whose files do not agree is refused naming its
/// `progress.csv`.
fn check_worst_claim(
    dir: &Path,
    objective: &Objective,
    we: &Eval,
    replayed: &Score,
) -> Result<(), FalsifyError> {
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let derived = replayed.objective;
    if same(replayed.metric, we.metric)
        && same(derived, we.objective)
        && same(replayed.margin, we.margin)
        && replayed.violated == we.violated
    {
        return Ok(());
    }
    let replayed = replayed.metric;
    Err(invalid(
        &dir.join("progress.csv"),
        format!(
            "evaluation {} ({}) claims {} = {} (objective {}), but its worst/timing.csv \
             replays to {} (objective {}): the shard's files do not agree",
            we.evaluation,
            we.method.name(),
            objective.key(),
            we.metric,
            we.objective,
            replayed,
            derived
        ),
    ))
}

/// Merges the shard directories `dirs` into `out`: `progress.csv` and its figure, the worst
/// timing's trace and its replay in `out/worst`, `result.json` and `bounds.toml`. Returns the
/// merged evaluations (each with its shard) and the result.
pub fn merge(
    dirs: &[PathBuf],
    out: &Path,
    interrupt: &Arc<AtomicBool>,
) -> Result<(Vec<(usize, Eval)>, Outcome), FalsifyError> {
    let shards = read_all(dirs)?;
    let (evals, worst) = combine(&shards);
    let w = worst.ok_or_else(|| {
        FalsifyError::Run("no evaluation of any shard completed (see their progress.csv)".into())
    })?;
    let (worst_shard, we) = evals[w].clone();
    let src = &shards[worst_shard];
    let first = &shards[0];
    let path = src.dir.join("worst").join("scenario.toml");
    let s = Scenario::load(&path).map_err(|e| invalid(&path, e))?;
    let spec = Spec {
        bounds: Bounds::read(&first.dir.join("bounds.toml"))?,
        bounds_from: first.info.bounds_from.clone(),
        objective: objective_of(&first.info.objective, &first.dir.join(SHARD_JSON))?,
        budget: first.info.budget,
        seed: first.info.seed,
        margin: None,
    };
    std::fs::create_dir_all(out).map_err(|e| files_error(out, e))?;
    // An unsharded search's kept evaluations are not this one's.
    let _ = std::fs::remove_dir_all(out.join("done"));
    // A merged search is not a shard, whatever the directory held before.
    let _ = std::fs::remove_file(out.join(SHARD_JSON));
    let _ = std::fs::remove_file(out.join(DIGESTS));
    let trace = src.dir.join("worst").join(TIMING_CSV);
    let replayed = replay_worst(&s, &spec, out, interrupt, |p| {
        std::fs::copy(&trace, p)
            .map(|_| ())
            .map_err(|e| files_error(p, e))
    })?;
    check_worst_claim(&src.dir, &spec.objective, &we, &replayed)?;
    write_merged_progress(out, &s, &spec, &evals)?;
    let o = merged_outcome(&s, &spec, &shards, &evals, (worst_shard, &we), &replayed);
    write_result(out, &spec, &o)?;
    Ok((evals, o))
}

/// The result of the merged search: the shards' evaluations `evals` joined, the worst
/// (`worst`: its shard and evaluation) and its replay here, their costs summed.
fn merged_outcome(
    s: &Scenario,
    spec: &Spec,
    shards: &[ShardDir],
    evals: &[(usize, Eval)],
    worst: (usize, &Eval),
    replayed: &Score,
) -> Outcome {
    let (worst_shard, we) = worst;
    let first = &shards[0];
    let best = |m: Method| {
        evals
            .iter()
            .filter(|(_, e)| e.method == m)
            .map(|(_, e)| e.best_so_far)
            .next_back()
            .unwrap_or(f64::NAN)
    };
    let n = shards.len() as f64;
    let sum = |f: &dyn Fn(&ShardResult) -> f64| shards.iter().map(|s| f(&s.result)).sum::<f64>();
    let requirement = spec.objective.is_requirement();
    let sampled = requirement
        .then(|| super::evidence::sampled(&spec.objective, evals.iter().map(|(_, e)| e)));
    Outcome {
        scenario: s.name.clone(),
        objective: spec.objective.describe(),
        metric: spec.objective.key().to_string(),
        method: CMA_ES_CITATION,
        budget: spec.budget,
        seed: spec.seed,
        dims: first.result.dims,
        lambda: first.result.lambda,
        nominal_metric: first.result.nominal_metric,
        search_best: best(Method::CmaEs),
        random_best: best(Method::Random),
        worst_found_by: we.method.name().to_string(),
        worst_phase: we.phase.name().to_string(),
        worst_valid: we.valid,
        worst_flags: super::outputs::flag_list(&we.flags),
        adversaries: shards.iter().map(|s| s.result.adversaries).sum(),
        worst_evaluation: we.evaluation,
        worst_metric: we.metric,
        worst_objective: we.objective,
        worst_run_metric: replayed.metric,
        violated: requirement.then_some(we.violated),
        margin: requirement.then_some(we.margin),
        requirements: super::outputs::judgements(spec, replayed),
        sensitivity: None,
        timing_margin: None,
        verdict: super::outputs::verdict(requirement.then_some(we.violated)),
        random_samples: sampled.map(|e| e.n),
        random_broken: sampled.map(|e| e.broken),
        random_broken_upper_95: sampled.map(|e| e.upper_95),
        failed_evaluations: evals.iter().filter(|(_, e)| !e.error.is_empty()).count(),
        evaluation_cpu_s: mean_evaluation_cpu(shards),
        plain_run_cpu_s: sum(&|r| r.plain_run_cpu_s) / n,
        search_s: sum(&|r| r.search_s),
        resumed_evaluations: shards.iter().map(|s| s.result.resumed_evaluations).sum(),
        shard: None,
        merged_shards: Some(shards.len()),
        worst_shard: Some(worst_shard),
    }
}

/// The mean CPU time of the evaluations the shards' last invocations ran: each shard's mean
/// weighted by the evaluations it ran (NaN when every evaluation was taken from earlier ones).
fn mean_evaluation_cpu(shards: &[ShardDir]) -> f64 {
    let (mut spent, mut ran) = (0.0, 0usize);
    for s in shards {
        let n = s.evals.len().saturating_sub(s.result.resumed_evaluations);
        if n > 0 && s.result.evaluation_cpu_s.is_finite() {
            spent += s.result.evaluation_cpu_s * n as f64;
            ran += n;
        }
    }
    if ran > 0 {
        spent / ran as f64
    } else {
        f64::NAN
    }
}

/// `--restarts N`: the search as `n` shards run one after the other in this process, each in
/// `ex.out/restarts/<i>` (resumable as any search), then merged into `ex.out`: the same
/// files as `n` shards run apart and merged with `falsify-merge`.
pub fn restarts(
    s: &Scenario,
    spec: &Spec,
    n: usize,
    ex: &super::Exec,
) -> Result<(Vec<(usize, Eval)>, Outcome), FalsifyError> {
    if n == 0 || spec.budget < n {
        return Err(FalsifyError::Invalid(format!(
            "--restarts {n}: allowed 1 to --budget ({}) restarts",
            spec.budget
        )));
    }
    let mut dirs = Vec::with_capacity(n);
    for index in 0..n {
        let dir = ex.out.join("restarts").join(index.to_string());
        let sub = super::Exec {
            out: dir.clone(),
            jobs: ex.jobs,
            exe: ex.exe.clone(),
            interrupt: ex.interrupt.clone(),
            done: ex.done.clone(),
        };
        super::falsify_part(s, spec, Some(Shard { index, count: n }), &sub)?;
        dirs.push(dir);
    }
    merge(&dirs, &ex.out, &ex.interrupt)
}
