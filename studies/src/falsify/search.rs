//! The search and its baseline, each with the same budget of evaluations. The search takes
//! three phases: the obvious adversaries (`adversaries`), then CMA-ES from the best of them
//! for three quarters of the rest
//! over the coordinates of `history` (a point x of ℝⁿ is the history at coordinates
//! `a = sat(1 / (1 + e^{−x}))`, `sat` stretching [0.05, 0.95] onto [0, 1] so that a coordinate
//! reaches its ends), then a (1 + λ) evolution of the histories themselves (`mutation`),
//! which reaches every admissible history. The baseline is uniform random sampling of the
//! coordinates. Every candidate is a projected history, so within bounds. An evaluation is
//! the in-process lock-step replay of the candidate's trace with the rows kept in memory. A
//! generation (or a batch of random points) is evaluated in parallel and its values combined
//! in the order of the points, so the result does not depend on `--jobs`. Every evaluation
//! is kept in `OUT/done/evals.csv` as it ends: run again with the same arguments, an
//! interrupted search takes the values it has and continues exactly as it would have.

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
use super::history::{History, Layout};
pub use super::kept::fingerprint;
use super::kept::Kept;
use super::objective::Objective;
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
    /// The timing margin of the requirements, searched after the search at the bounds given
    /// (`--margin`).
    pub margin: Option<super::margin::MarginPlan>,
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

/// Which phase of a method chose a candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Phase {
    /// The obvious adversaries, before the search.
    Adversary,
    /// CMA-ES over the coordinates.
    CmaEs,
    /// The evolution of the histories themselves.
    Mutation,
    /// Uniform random sampling of the coordinates (the baseline).
    Random,
}

impl Phase {
    /// The name in files.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Adversary => "adversary",
            Phase::CmaEs => "cma-es",
            Phase::Mutation => "mutation",
            Phase::Random => "random",
        }
    }
}

/// One evaluation, as `progress.csv` and `done/evals.csv` hold it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Eval {
    /// Which method chose the candidate: the search (`cma-es`, all its phases) or the
    /// random sampling.
    pub method: Method,
    /// Its place in the method's sequence (from 1).
    pub evaluation: usize,
    /// The phase of the method that chose it.
    pub phase: Phase,
    /// The metric's value (NaN when the replay failed).
    pub metric: f64,
    /// What the search maximises (the metric, or the requirements' margin negated).
    pub objective: f64,
    /// The requirements' margin (NaN when a metric is maximised or the replay failed).
    pub margin: f64,
    /// Whether a requirement is broken (a failed replay counts as broken; never when a
    /// metric is maximised).
    pub violated: bool,
    /// Largest `objective` of the method so far.
    pub best_so_far: f64,
    /// Whether the replay's comfort numbers are valid (`summary.json` `comfort_valid`: no
    /// oscillation, P_CT within the formula's range); false when it failed.
    pub valid: bool,
    /// The validity flags the replay raised, `;`-separated (`summary.json` `flags`).
    pub flags: String,
    /// Why the evaluation failed (empty: it did not).
    pub error: String,
}

/// The columns of `progress.csv` and `done/evals.csv`, in [`Eval`]'s order.
pub const EVAL_COLUMNS: [&str; 11] = [
    "method",
    "evaluation",
    "phase",
    "metric",
    "objective",
    "margin",
    "violated",
    "best_so_far",
    "valid",
    "flags",
    "error",
];

/// What one evaluation gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Scored {
    /// The metric (NaN when the replay failed).
    pub metric: f64,
    /// The objective (NaN when the replay failed).
    pub objective: f64,
    /// The requirements' margin (NaN when none or the replay failed).
    pub margin: f64,
    /// Whether a requirement is broken.
    pub violated: bool,
    /// `comfort_valid` of the replay.
    pub valid: bool,
    /// The flags raised, `;`-separated.
    pub flags: String,
    /// Why it failed (empty: it did not).
    pub error: String,
}

impl Scored {
    fn failed(requirement: bool, error: String) -> Scored {
        Scored {
            metric: f64::NAN,
            objective: f64::NAN,
            margin: f64::NAN,
            violated: requirement,
            valid: false,
            flags: String::new(),
            error,
        }
    }

    fn of(e: &Eval) -> Scored {
        Scored {
            metric: e.metric,
            objective: e.objective,
            margin: e.margin,
            violated: e.violated,
            valid: e.valid,
            flags: e.flags.clone(),
            error: e.error.clone(),
        }
    }
}

/// What a search found.
#[derive(Debug, Clone)]
pub struct Falsified {
    /// Every evaluation, the search's then the random sampling's.
    pub evals: Vec<Eval>,
    /// The worst history and which evaluation it was.
    pub worst: (History, Eval),
    /// Obvious adversaries evaluated first.
    pub adversaries: usize,
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

/// Where the logistic `u` of a coordinate is cut: `[EDGE, 1 − EDGE]` is stretched onto the
/// coordinate's whole `[0, 1]`, so that CMA-ES reaches its ends (x = ±2.94).
const EDGE: f64 = 0.05;

/// The coordinates of point `x` of ℝⁿ.
pub fn coords(x: &[f64]) -> Vec<f64> {
    squash(x)
        .into_iter()
        .map(|u| ((u - EDGE) / (1.0 - 2.0 * EDGE)).clamp(0.0, 1.0))
        .collect()
}

/// A point of ℝⁿ whose coordinates are `a` (the inverse of [`coords`] inside the cube).
pub fn point_of(a: &[f64]) -> Vec<f64> {
    a.iter()
        .map(|c| {
            let u = EDGE + (1.0 - 2.0 * EDGE) * c.clamp(0.0, 1.0);
            (u / (1.0 - u)).ln()
        })
        .collect()
}

/// Step size of the search's first generation (the cube's preimage: x = ±2 is u = 0.12, 0.88).
pub const SIGMA0: f64 = 2.0;

/// The validity and flags of a completed replay's summary.
fn validity(d: &tiltsim_master::Summary) -> (bool, String) {
    (d.comfort_valid, d.flags.raised().join(";"))
}

/// What `objective` makes of a completed run of `s` with summary `d` and rows `rows`.
pub fn judge(
    s: &Scenario,
    objective: &Objective,
    d: &tiltsim_master::Summary,
    rows: &[tiltsim_formats::table::Row],
) -> super::objective::Score {
    let raised = d.flags.raised();
    let trace = super::requirement::signals::Trace::new(s, rows);
    objective.score(&super::requirement::Judged {
        comfort: &d.comfort,
        comfort_valid: d.comfort_valid,
        raised: &raised,
        trace: &trace,
    })
}

/// One evaluation of history `h`: its trace, checked, replayed in process with its rows in
/// memory. Nothing is written: `dir` only names the run in messages.
pub(crate) fn evaluate(
    s: &Scenario,
    layout: &Layout,
    ticks: &[TickBound; 4],
    objective: &Objective,
    h: &History,
    dir: PathBuf,
    interrupt: &Arc<AtomicBool>,
) -> Scored {
    let failed = |e: String| Scored::failed(objective.is_requirement(), e);
    // Never expected to fail: every candidate is projected onto the bounds (tested).
    if let Err(e) = layout.admissible(h) {
        return failed(format!("candidate not admissible: {e}"));
    }
    let trace = layout.trace(s, h);
    if let Err(e) = super::timing::check(s, &trace, ticks) {
        return failed(format!("candidate not admissible: {e}"));
    }
    let mut opts = RunOptions::new(dir, PathBuf::new());
    opts.interrupt = interrupt.clone();
    opts.plots = false;
    opts.timing = false;
    let mut job = tiltsim_runner::pipeline::Job::new(s, s.name.clone(), opts);
    job.claim = false;
    job.outputs.rows_in_memory = true;
    job.replay_steps = Some(trace);
    match tiltsim_runner::pipeline::carry_out(job) {
        Ok(d) if d.summary.status == Status::Completed && d.summary.analysis_skipped.is_none() => {
            let score = judge(s, objective, &d.summary, &d.rows);
            let (valid, flags) = validity(&d.summary);
            Scored {
                metric: score.metric,
                objective: score.objective,
                margin: score.margin,
                violated: score.violated,
                valid,
                flags,
                error: String::new(),
            }
        }
        Ok(d) => failed(
            d.summary
                .error
                .or(d.summary.analysis_skipped)
                .unwrap_or_else(|| "the replay did not complete".into()),
        ),
        Err(e) => failed(e.to_string()),
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
    /// Evaluates one candidate, numbered `n` for `method`, or takes it from an earlier
    /// invocation. `None` when interrupted.
    fn one(&self, method: Method, phase: Phase, n: usize, h: &History) -> Option<Scored> {
        if let Some(e) = self.kept.values.get(&(method, n)) {
            return Some(Scored::of(e));
        }
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
            h,
            dir,
            &self.ex.interrupt,
        );
        if self.ex.interrupt.load(Ordering::Relaxed) {
            return None;
        }
        if let Ok(mut t) = self.timed.lock() {
            t.0 += thread_cpu_s() - t0;
            t.1 += 1;
        }
        self.kept.put(&Eval {
            method,
            evaluation: n,
            phase,
            metric: v.metric,
            objective: v.objective,
            margin: v.margin,
            violated: v.violated,
            best_so_far: f64::NAN,
            valid: v.valid,
            flags: v.flags.clone(),
            error: v.error.clone(),
        });
        Some(v)
    }

    /// Evaluates `hs`, numbered from `first` for `method`, on `jobs` threads. Returns the
    /// scores in the order of the candidates; `None` when interrupted.
    fn batch(
        &self,
        method: Method,
        phase: Phase,
        first: usize,
        hs: &[History],
    ) -> Option<Vec<Scored>> {
        crate::parallel::map(hs.len(), self.ex.jobs, &self.ex.interrupt, |i| {
            let v = self.one(method, phase, first + i, &hs[i])?;
            if let Some(d) = &self.ex.done {
                d.fetch_add(1, Ordering::Relaxed);
            }
            Some(v)
        })
        .into_iter()
        .collect()
    }
}

/// Population size of CMA-ES in `n` dimensions (the tutorial's Table 1).
pub fn lambda(n: usize) -> usize {
    4 + (3.0 * (n.max(1) as f64).ln()).floor() as usize
}

/// Generations of CMA-ES the default budget gives it in `n` dimensions: 5n evaluations, at
/// least 10 generations (three quarters of what follows the adversaries).
fn default_generations(n: usize) -> usize {
    (5 * n).div_ceil(lambda(n)).max(10)
}

/// The default budget for scenario `s` and bounds `bounds` (`from` names them in errors):
/// the obvious adversaries, CMA-ES for [`default_generations`], and a third as many
/// evaluations again for the evolution of the histories.
pub fn default_budget(s: &Scenario, bounds: &Bounds, from: &str) -> Result<usize, FalsifyError> {
    let ticks = bounds.ticks(s, from)?;
    let layout = Layout::new(s, &ticks);
    let n = layout.dims;
    let a = super::adversaries::adversaries(s, &layout).len();
    let cma = default_generations(n) * lambda(n);
    Ok(a + cma + cma.div_ceil(3))
}

/// Runs the search and the random sampling of `spec` on scenario `s` (validated, lock-step,
/// in process, without timing effects on its links).
pub fn run(s: &Scenario, spec: &Spec, ex: &Exec) -> Result<Falsified, FalsifyError> {
    let t0 = Instant::now();
    let ticks = spec.bounds.ticks(s, &spec.bounds_from)?;
    let layout = Layout::new(s, &ticks);
    std::fs::create_dir_all(&ex.out)
        .map_err(|e| FalsifyError::Files(format!("{}: {e}", ex.out.display())))?;
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
    let (mut search, mut best, adversaries) = run_search(&ctx).ok_or_else(interrupted)?;
    let (random, random_best) = run_random(&ctx).ok_or_else(interrupted)?;
    let worst_random = random_best.filter(|(_, e)| {
        best.as_ref()
            .is_none_or(|(_, b): &(History, Eval)| e.objective > b.objective)
    });
    if worst_random.is_some() {
        best = worst_random;
    }
    let worst = best.ok_or_else(|| {
        FalsifyError::Run("no evaluation completed (each one's error is in done/evals.csv)".into())
    })?;
    search.extend(random);
    let (spent, n) = ctx.timed.lock().map(|t| *t).unwrap_or((0.0, 0));
    Ok(Falsified {
        evals: search,
        worst,
        adversaries,
        ticks,
        dims: ctx.layout.dims,
        lambda: lambda(ctx.layout.dims),
        eval_s: if n > 0 { spent / n as f64 } else { f64::NAN },
        wall_s: t0.elapsed().as_secs_f64(),
        resumed,
    })
}

type Best = Option<(History, Eval)>;

/// Appends the evaluations of `values` (for candidates `hs`) to `evals`, keeping the best.
fn record(
    method: Method,
    phase: Phase,
    hs: &[History],
    values: Vec<Scored>,
    evals: &mut Vec<Eval>,
    best: &mut Best,
) {
    for (h, v) in hs.iter().zip(values) {
        let better =
            !v.objective.is_nan() && best.as_ref().is_none_or(|(_, b)| v.objective > b.objective);
        let prev = best.as_ref().map_or(f64::NAN, |(_, b)| b.objective);
        let e = Eval {
            method,
            evaluation: evals.len() + 1,
            phase,
            metric: v.metric,
            objective: v.objective,
            margin: v.margin,
            violated: v.violated,
            best_so_far: if better { v.objective } else { prev },
            valid: v.valid,
            flags: v.flags,
            error: v.error,
        };
        if better {
            *best = Some((h.clone(), e.clone()));
        }
        evals.push(e);
    }
}

/// The search: the obvious adversaries, CMA-ES from the best of them for three quarters of
/// what remains (whole generations), then the evolution of the histories for the rest. Returns
/// the evaluations, the best and the number of adversaries; `None` when interrupted.
fn run_search(ctx: &Ctx) -> Option<(Vec<Eval>, Best, usize)> {
    let budget = ctx.spec.budget;
    let layout = &ctx.layout;
    let mut evals = Vec::with_capacity(budget);
    let mut best: Best = None;
    let mut adv = super::adversaries::adversaries(ctx.s, layout);
    adv.truncate(budget);
    let hs: Vec<History> = adv.iter().map(|a| layout.history(&a.coords)).collect();
    let values = ctx.batch(Method::CmaEs, Phase::Adversary, 1, &hs)?;
    let start = values
        .iter()
        .enumerate()
        .filter(|(_, v)| !v.objective.is_nan())
        .max_by(|a, b| a.1.objective.total_cmp(&b.1.objective).then(b.0.cmp(&a.0)))
        .map_or_else(|| vec![0.0; layout.dims], |(i, _)| adv[i].coords.clone());
    record(
        Method::CmaEs,
        Phase::Adversary,
        &hs,
        values,
        &mut evals,
        &mut best,
    );
    let n = layout.dims;
    let remaining = budget - evals.len();
    let lam = lambda(n);
    // Three quarters of what remains in whole generations: CMA-ES learns the coordinates'
    // shape; the evolution of the histories refines its best where the coordinates cannot.
    let cma = if remaining >= 2 * lam {
        (3 * remaining / 4 / lam * lam).max(lam)
    } else {
        remaining
    };
    if n > 0 && cma < lam && ctx.spec.budget > 0 {
        eprintln!(
            "warning: a budget of {budget} evaluations holds {} obvious adversaries and {cma} of a \
             CMA-ES generation of {lam}: CMA-ES never adapts; a budget of {} or more gives it a \
             generation",
            adv.len(),
            adv.len() + 2 * lam
        );
    }
    run_cma_es(
        ctx,
        &point_of(&start),
        evals.len() + cma,
        &mut evals,
        &mut best,
    )?;
    run_mutation(ctx, budget, &mut evals, &mut best)?;
    Some((evals, best, adv.len()))
}

/// CMA-ES from `mean`: generations of λ points until `until` evaluations (a last generation
/// cut to what remains, without an update). `None` when interrupted.
fn run_cma_es(
    ctx: &Ctx,
    mean: &[f64],
    until: usize,
    evals: &mut Vec<Eval>,
    best: &mut Best,
) -> Option<()> {
    let mut es = CmaEs::new(mean.to_vec(), SIGMA0, ctx.spec.seed);
    while evals.len() < until {
        let xs = es.ask();
        let take = xs.len().min(until - evals.len());
        let hs: Vec<History> = xs[..take]
            .iter()
            .map(|x| ctx.layout.history(&coords(x)))
            .collect();
        let values = ctx.batch(Method::CmaEs, Phase::CmaEs, evals.len() + 1, &hs)?;
        let objectives: Vec<f64> = values.iter().map(|v| v.objective).collect();
        record(Method::CmaEs, Phase::CmaEs, &hs, values, evals, best);
        if take == xs.len() {
            es.tell(&objectives);
        }
    }
    Some(())
}

/// Seed of the evolution of the histories, apart from CMA-ES's.
const MUTATION_STREAM: u64 = 0x6a09_e667_f3bc_c909;

/// The (1 + λ) evolution of the histories from the best so far until `budget` evaluations.
/// `None` when interrupted.
fn run_mutation(ctx: &Ctx, budget: usize, evals: &mut Vec<Eval>, best: &mut Best) -> Option<()> {
    let mut m = super::mutation::Mutator::new(&ctx.layout, ctx.spec.seed ^ MUTATION_STREAM);
    let lam = lambda(ctx.layout.dims);
    while evals.len() < budget {
        let parent = match best {
            Some((h, _)) => h.clone(),
            None => ctx.layout.earliest(),
        };
        let take = lam.min(budget - evals.len());
        let hs: Vec<History> = (0..take).map(|_| m.child(&parent)).collect();
        let values = ctx.batch(Method::CmaEs, Phase::Mutation, evals.len() + 1, &hs)?;
        record(Method::CmaEs, Phase::Mutation, &hs, values, evals, best);
    }
    Some(())
}

/// Seed of the random sampling, apart from the search's.
const RANDOM_STREAM: u64 = 0x9e37_79b9_7f4a_7c15;

/// The uniform random sampling: `budget` points of the coordinates, in batches. `None` when
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
        let hs: Vec<History> = c.iter().map(|a| ctx.layout.history(a)).collect();
        let values = ctx.batch(Method::Random, Phase::Random, evals.len() + 1, &hs)?;
        record(
            Method::Random,
            Phase::Random,
            &hs,
            values,
            &mut evals,
            &mut best,
        );
    }
    Some((evals, best))
}
