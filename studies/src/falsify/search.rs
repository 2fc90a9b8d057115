//! The search and its baseline: CMA-ES over the unit cube's preimage (a point x of ℝⁿ is the
//! timing of `u = 1 / (1 + e^{−x})`, so every point is within bounds) against uniform random
//! points of the cube, each with the same budget of evaluations. An evaluation is the
//! in-process lock-step replay of the point's trace with the rows kept in memory. A generation
//! (or a batch of random points) is evaluated in parallel and its values combined in the
//! order of the points, so the result does not depend on `--jobs`. Every evaluation is kept
//! in `OUT/done/evals.csv` as it ends: run again with the same arguments, an interrupted
//! search takes the values it has and continues exactly as it would have.

use std::collections::HashMap;
use std::io::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use rand::{Rng as _, SeedableRng as _};
use serde::{Deserialize, Serialize};
use tiltsim_master::engine::{RunOptions, Status};
use tiltsim_scenario::scenario::Scenario;

use super::bounds::{Bounds, TickBound};
use super::cmaes::CmaEs;
use super::objective::Objective;
use super::timing::Layout;
use super::FalsifyError;

/// What to search.
#[derive(Debug, Clone)]
pub struct Spec {
    /// The admissible timing.
    pub bounds: Bounds,
    /// Where the bounds came from (a file, or the recorded runs), for messages.
    pub bounds_from: String,
    /// What to maximise.
    pub objective: Objective,
    /// Evaluations of the search, and as many of the random sampling.
    pub budget: usize,
    /// Seed of both.
    pub seed: u64,
}

/// How to carry it out.
pub struct Exec {
    /// Output directory.
    pub out: PathBuf,
    /// Parallel evaluations.
    pub jobs: usize,
    /// Executable serving participants (not used in process; the run options want one).
    pub exe: PathBuf,
    /// Set by Ctrl-C.
    pub interrupt: Arc<AtomicBool>,
    /// Evaluations finished, for a caller watching from another thread.
    pub done: Option<Arc<AtomicUsize>>,
}

/// The two ways of choosing points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Method {
    /// CMA-ES.
    #[serde(rename = "cma-es")]
    CmaEs,
    /// Uniform random sampling of the unit cube.
    #[serde(rename = "random")]
    Random,
}

impl Method {
    /// The name in files.
    pub fn name(self) -> &'static str {
        match self {
            Method::CmaEs => "cma-es",
            Method::Random => "random",
        }
    }
}

/// One evaluation, as `progress.csv` and `done/evals.csv` hold it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Eval {
    /// Which method chose the point.
    pub method: Method,
    /// Its place in the method's sequence (from 1).
    pub evaluation: usize,
    /// The metric's value (NaN when the replay failed).
    pub metric: f64,
    /// What the search maximises (the metric, or a requirement's margin negated).
    pub objective: f64,
    /// Largest `objective` of the method so far.
    pub best_so_far: f64,
    /// Why the evaluation failed (empty: it did not).
    pub error: String,
}

/// What a search found.
#[derive(Debug, Clone)]
pub struct Falsified {
    /// Every evaluation, the search's then the random sampling's.
    pub evals: Vec<Eval>,
    /// The worst point (its coordinates in the unit cube) and which evaluation it was.
    pub worst: (Vec<f64>, Eval),
    /// The bounds in ticks.
    pub ticks: [TickBound; 4],
    /// Coordinates of a point.
    pub dims: usize,
    /// Population size of the search.
    pub lambda: usize,
    /// Mean CPU time of one evaluation (s).
    pub eval_s: f64,
    /// Wall time of the whole search and sampling (s).
    pub wall_s: f64,
    /// Evaluations taken from an earlier, interrupted invocation.
    pub resumed: usize,
}

/// CPU time of the calling thread (s): an in-process run's whole cost (its participants step
/// on the thread that runs it), unaffected by other work on the machine, as wall time is.
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for the call to fill.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// `u = 1 / (1 + e^{−x})`, each coordinate.
pub fn squash(x: &[f64]) -> Vec<f64> {
    x.iter().map(|v| 1.0 / (1.0 + (-v).exp())).collect()
}

/// Step size of the search's first generation (the cube's preimage: x = ±2 is u = 0.12, 0.88).
pub const SIGMA0: f64 = 2.0;

/// The evaluations kept by earlier invocations of the same search.
struct Kept {
    values: HashMap<(Method, usize), Eval>,
    file: Mutex<std::fs::File>,
}

fn files_error(what: &str, e: impl std::fmt::Display) -> FalsifyError {
    FalsifyError::Files(format!("{what}: {e}"))
}

impl Kept {
    /// Opens `out/done`: its evaluations when `fingerprint` is the one it was kept for, else
    /// emptied for this search.
    fn open(out: &std::path::Path, fingerprint: &str) -> Result<Kept, FalsifyError> {
        let dir = out.join("done");
        let id = dir.join("fingerprint");
        let csv = dir.join("evals.csv");
        let same = std::fs::read_to_string(&id).is_ok_and(|f| f.trim() == fingerprint);
        let mut values = HashMap::new();
        if same {
            if let Ok(mut r) = csv::ReaderBuilder::new().from_path(&csv) {
                // A line cut short by a kill does not parse: that evaluation is run again.
                for e in r.deserialize::<Eval>().flatten() {
                    values.insert((e.method, e.evaluation), e);
                }
            }
        } else {
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir)
                .map_err(|e| files_error(&dir.display().to_string(), e))?;
            std::fs::write(&id, format!("{fingerprint}\n"))
                .map_err(|e| files_error(&id.display().to_string(), e))?;
        }
        let fresh = !csv.exists();
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&csv)
            .map_err(|e| files_error(&csv.display().to_string(), e))?;
        if fresh {
            writeln!(file, "method,evaluation,metric,objective,best_so_far,error")
                .map_err(|e| files_error(&csv.display().to_string(), e))?;
        }
        Ok(Kept {
            values,
            file: Mutex::new(file),
        })
    }

    fn put(&self, e: &Eval) {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        if w.serialize(e).is_ok() {
            if let (Ok(line), Ok(mut f)) = (w.into_inner(), self.file.lock()) {
                let _ = f.write_all(&line);
            }
        }
    }
}

/// What the search's files are checked against: scenario, bounds, objective, budget, seed
/// and the program's build.
pub fn fingerprint(s: &Scenario, spec: &Spec) -> String {
    let text = format!(
        "tiltsim falsify 1\n{}\n{:?}\n{}\n{} {}\n{}",
        crate::sweep::identity::build(),
        spec.bounds,
        spec.objective.describe(),
        spec.budget,
        spec.seed,
        toml::to_string(s).unwrap_or_default()
    );
    crate::sweep::identity::sha256(text.as_bytes())
}

/// One evaluation of point `u`: its trace, checked, replayed in process with its rows in
/// memory. Nothing is written: `dir` only names the run in messages.
pub(crate) fn evaluate(
    s: &Scenario,
    layout: &Layout,
    ticks: &[TickBound; 4],
    objective: &Objective,
    u: &[f64],
    dir: PathBuf,
    interrupt: &Arc<AtomicBool>,
) -> (f64, f64, String) {
    // Never expected to fail: the mapping gives admissible timings only (tested).
    if let Err(e) = layout.check_budgets(u) {
        return (f64::NAN, f64::NAN, format!("candidate not admissible: {e}"));
    }
    let trace = layout.trace(s, u);
    if let Err(e) = super::timing::check(s, &trace, ticks) {
        return (f64::NAN, f64::NAN, format!("candidate not admissible: {e}"));
    }
    let mut opts = RunOptions::new(dir, PathBuf::new());
    opts.interrupt = interrupt.clone();
    opts.plots = false;
    opts.timing = false;
    let mut job = tiltsim_report::pipeline::Job::new(s, s.name.clone(), opts);
    job.claim = false;
    job.outputs.rows_in_memory = true;
    job.replay_steps = Some(trace);
    match tiltsim_report::pipeline::carry_out(job) {
        Ok(d) if d.summary.status == Status::Completed && d.summary.analysis_skipped.is_none() => {
            let c = &d.summary.comfort;
            let m = (tiltsim_assessment::comfort::METRICS[objective.metric()].get)(c);
            (m, objective.value(c), String::new())
        }
        Ok(d) => (
            f64::NAN,
            f64::NAN,
            d.summary
                .error
                .or(d.summary.analysis_skipped)
                .unwrap_or_else(|| "the replay did not complete".into()),
        ),
        Err(e) => (f64::NAN, f64::NAN, e.to_string()),
    }
}

/// Everything an evaluation needs, shared by the threads.
struct Ctx<'a> {
    s: &'a Scenario,
    spec: &'a Spec,
    layout: Layout,
    ticks: [TickBound; 4],
    ex: &'a Exec,
    kept: Kept,
    /// CPU time of the evaluations run here (s) and their number.
    timed: Mutex<(f64, usize)>,
}

impl Ctx<'_> {
    /// Evaluates `points` (unit-cube coordinates), numbered from `first` for `method`, on
    /// `jobs` threads; those kept by an earlier invocation are taken as they are. Returns
    /// (metric, objective, error) in the order of the points; `None` when interrupted.
    fn batch(
        &self,
        method: Method,
        first: usize,
        points: &[Vec<f64>],
    ) -> Option<Vec<(f64, f64, String)>> {
        let next = AtomicUsize::new(0);
        let out: Mutex<Vec<Option<(f64, f64, String)>>> = Mutex::new(vec![None; points.len()]);
        std::thread::scope(|sc| {
            for _ in 0..self.ex.jobs.clamp(1, points.len().max(1)) {
                sc.spawn(|| loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= points.len() || self.ex.interrupt.load(Ordering::Relaxed) {
                        break;
                    }
                    let n = first + i;
                    let v = match self.kept.values.get(&(method, n)) {
                        Some(e) => (e.metric, e.objective, e.error.clone()),
                        None => {
                            let dir = self
                                .ex
                                .out
                                .join("evals")
                                .join(format!("{}-{n:05}", method.name()));
                            let t0 = thread_cpu_s();
                            let v = evaluate(
                                self.s,
                                &self.layout,
                                &self.ticks,
                                &self.spec.objective,
                                &points[i],
                                dir,
                                &self.ex.interrupt,
                            );
                            if self.ex.interrupt.load(Ordering::Relaxed) {
                                break;
                            }
                            if let Ok(mut t) = self.timed.lock() {
                                t.0 += thread_cpu_s() - t0;
                                t.1 += 1;
                            }
                            self.kept.put(&Eval {
                                method,
                                evaluation: n,
                                metric: v.0,
                                objective: v.1,
                                best_so_far: f64::NAN,
                                error: v.2.clone(),
                            });
                            v
                        }
                    };
                    if let Some(d) = &self.ex.done {
                        d.fetch_add(1, Ordering::Relaxed);
                    }
                    if let Ok(mut o) = out.lock() {
                        o[i] = Some(v);
                    }
                });
            }
        });
        out.into_inner().ok()?.into_iter().collect()
    }
}

/// Runs the search and the random sampling of `spec` on scenario `s` (validated, lock-step,
/// in process, without timing effects on its links).
pub fn run(s: &Scenario, spec: &Spec, ex: &Exec) -> Result<Falsified, FalsifyError> {
    let t0 = Instant::now();
    let ticks = spec.bounds.ticks(s, &spec.bounds_from)?;
    let layout = Layout::new(s, &ticks);
    std::fs::create_dir_all(&ex.out).map_err(|e| files_error(&ex.out.display().to_string(), e))?;
    let kept = Kept::open(&ex.out, &fingerprint(s, spec))?;
    let resumed = kept.values.len();
    if resumed > 0 {
        eprintln!(
            "resuming: {resumed} of {} evaluations already done in {}",
            2 * spec.budget,
            ex.out.join("done").display()
        );
    }
    let ctx = Ctx {
        s,
        spec,
        layout,
        ticks,
        ex,
        kept,
        timed: Mutex::new((0.0, 0)),
    };
    let interrupted = || {
        FalsifyError::Run(format!(
            "interrupted by {}; run the same command again to resume from {}",
            tiltsim_rundir::signals::describe(),
            ex.out.join("done").display()
        ))
    };
    let (mut search, mut best_pt, lambda) = run_search(&ctx).ok_or_else(interrupted)?;
    let (random, random_best) = run_random(&ctx).ok_or_else(interrupted)?;
    let worst_random = random_best.filter(|(_, e)| {
        best_pt
            .as_ref()
            .is_none_or(|(_, b): &(Vec<f64>, Eval)| e.objective > b.objective)
    });
    if worst_random.is_some() {
        best_pt = worst_random;
    }
    let worst = best_pt.ok_or_else(|| {
        FalsifyError::Run("no evaluation completed (each one's error is in done/evals.csv)".into())
    })?;
    search.extend(random);
    let (spent, n) = ctx.timed.lock().map(|t| *t).unwrap_or((0.0, 0));
    Ok(Falsified {
        evals: search,
        worst,
        ticks,
        dims: ctx.layout.dims,
        lambda,
        eval_s: if n > 0 { spent / n as f64 } else { f64::NAN },
        wall_s: t0.elapsed().as_secs_f64(),
        resumed,
    })
}

type Best = Option<(Vec<f64>, Eval)>;

/// Appends the evaluations of `values` (for points `pts`) to `evals`, keeping the best.
fn record(
    method: Method,
    pts: &[Vec<f64>],
    values: Vec<(f64, f64, String)>,
    evals: &mut Vec<Eval>,
    best: &mut Best,
) {
    for (u, (metric, objective, error)) in pts.iter().zip(values) {
        let better =
            !objective.is_nan() && best.as_ref().is_none_or(|(_, b)| objective > b.objective);
        let prev = best.as_ref().map_or(f64::NAN, |(_, b)| b.objective);
        let e = Eval {
            method,
            evaluation: evals.len() + 1,
            metric,
            objective,
            best_so_far: if better { objective } else { prev },
            error,
        };
        if better {
            *best = Some((u.clone(), e.clone()));
        }
        evals.push(e);
    }
}

/// The CMA-ES part: generations of λ points until the budget is spent (a last generation cut
/// to what remains). `None` when interrupted.
fn run_search(ctx: &Ctx) -> Option<(Vec<Eval>, Best, usize)> {
    let budget = ctx.spec.budget;
    let mut es = CmaEs::new(vec![0.0; ctx.layout.dims], SIGMA0, ctx.spec.seed);
    let mut evals = Vec::with_capacity(budget);
    let mut best: Best = None;
    while evals.len() < budget {
        let xs = es.ask();
        let take = xs.len().min(budget - evals.len());
        let pts: Vec<Vec<f64>> = xs[..take].iter().map(|x| squash(x)).collect();
        let values = ctx.batch(Method::CmaEs, evals.len() + 1, &pts)?;
        let objectives: Vec<f64> = values.iter().map(|v| v.1).collect();
        record(Method::CmaEs, &pts, values, &mut evals, &mut best);
        if take == xs.len() {
            es.tell(&objectives);
        }
    }
    Some((evals, best, es.lambda))
}

/// Seed of the random sampling, apart from the search's.
const RANDOM_STREAM: u64 = 0x9e37_79b9_7f4a_7c15;

/// The uniform random sampling: `budget` points of the unit cube, in batches. `None` when
/// interrupted.
fn run_random(ctx: &Ctx) -> Option<(Vec<Eval>, Best)> {
    let budget = ctx.spec.budget;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(ctx.spec.seed ^ RANDOM_STREAM);
    let pts: Vec<Vec<f64>> = (0..budget)
        .map(|_| (0..ctx.layout.dims).map(|_| rng.random::<f64>()).collect())
        .collect();
    let mut evals = Vec::with_capacity(budget);
    let mut best: Best = None;
    let chunk = (4 * ctx.ex.jobs).max(8);
    for c in pts.chunks(chunk) {
        let values = ctx.batch(Method::Random, evals.len() + 1, c)?;
        record(Method::Random, c, values, &mut evals, &mut best);
    }
    Some((evals, best))
}
