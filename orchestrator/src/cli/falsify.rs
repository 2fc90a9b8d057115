//! `tiltsim falsify SCENARIO`: the admissible timing that hurts the ride most, found by
//! CMA-ES against uniform random sampling with the same budget, replayable exactly.

use std::path::{Path, PathBuf};

use super::bounds;
use super::common::{interrupt_and_exe, load};
use super::error::{CliError, CliResult};
use tiltsim_scenario::scenario::Scenario;
use tiltsim_studies::falsify::{self, Bounds, Exec, FalsifyError, Objective, Spec};

/// The most evaluations of a search (`--budget`).
pub const MAX_BUDGET: usize = 100_000;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct FalsifyArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// The admissible timing per link: a TOML file with a table per link
    /// (`[actuator_command] delay_ms = [0, 60]  jitter_ms = 10  loss_pct = 1  freeze_ms = 0`).
    #[arg(
        long,
        required_unless_present = "envelope",
        conflicts_with = "envelope"
    )]
    bounds: Option<PathBuf>,
    /// Take the admissible timing as the envelope of the free runs in these directories
    /// (their timing.csv); repeatable.
    #[arg(long, value_name = "RUN_DIR")]
    envelope: Vec<PathBuf>,
    /// The metric to maximise: a key of the comfort metrics (p_ct_en12299_standing_pct, ...)
    /// or p_ct, p_ct_seated, lat_acc_peak, tilt_error, n_mv, jerk_peak, roll_speed_peak.
    #[arg(long, conflicts_with = "requirement")]
    objective: Option<String>,
    /// A requirement whose margin is minimised; repeatable (all at once): on a metric,
    /// `METRIC OP VALUE` ("p_ct < 35"); on validity, `valid`, `no flags` or `no FLAG`
    /// (oscillation, bump_stop, drive_limit, chopper, thermal, p_ct_range); on signals, a
    /// temporal formula ("always |lat_acc| < 1.2",
    /// "always (transition_end -> always[0,3] |tilt_error| < 0.5deg)").
    #[arg(long, value_name = "R")]
    requirement: Vec<String>,
    /// Evaluations of the search (and as many of the random sampling it is compared with)
    /// [default: from the number of coordinates searched: the obvious adversaries, CMA-ES
    /// for max(10, 5n/λ) generations of λ, and a third as many of the histories' evolution].
    #[arg(long)]
    budget: Option<i64>,
    /// Seed of the search and of the random sampling.
    #[arg(long, default_value_t = 1, value_parser = bounds::int(0..=u64::MAX, ""))]
    seed: u64,
    /// Parallel evaluations [default: the number of CPUs]; the result does not depend on it.
    #[arg(long, value_parser = bounds::int(1..=256usize, ""))]
    jobs: Option<usize>,
    /// Change a scenario setting before the search, KEY=VALUE as `tiltsim run --set`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Run one shard of the search, as sweeps are sharded: shard I of N is an independent
    /// CMA-ES restart (its own seed) with its share of the budget, beside its share of the
    /// random sampling; join the shards with falsify-merge. `auto`: I and N from the array
    /// task's environment (Slurm, AWS Batch, or a Kubernetes indexed job with --shards N).
    #[arg(long, value_name = "I/N|auto", conflicts_with = "restarts")]
    shard: Option<String>,
    /// With --shard auto in a Kubernetes indexed job: the number of completions.
    #[arg(long, value_name = "N", requires = "shard", value_parser = bounds::int(1..=MAX_BUDGET, ""))]
    shards: Option<usize>,
    /// Run the search as N shards one after the other (OUT/restarts/<i>) and merge them into
    /// OUT: the same result as N shards run apart and merged with falsify-merge.
    #[arg(long, value_name = "N", value_parser = bounds::int(1..=MAX_BUDGET, ""))]
    restarts: Option<usize>,
    /// After the search, the requirements' timing margin: the bounds scaled by k (k = 0 the
    /// lock-step timing, 1 the bounds given), a search of the same budget at each scale, by
    /// doubling up to --margin-max and bisection: the largest scale not falsified and the
    /// smallest falsified, with its counterexample in OUT/margin/worst.
    #[arg(long, requires = "requirement", conflicts_with_all = ["shard", "restarts"])]
    margin: bool,
    /// The largest scale --margin tries.
    #[arg(long, value_name = "K", default_value_t = 4.0, requires = "margin",
          value_parser = bounds::real((1.0, bounds::End::Closed), (100.0, bounds::End::Closed), ""))]
    margin_max: f64,
    /// Bisection steps of --margin (each a search).
    #[arg(long, value_name = "N", default_value_t = 4, requires = "margin",
          value_parser = bounds::int(0..=20usize, ""))]
    margin_steps: usize,
    /// Output directory [default: out/falsify-<scenario name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// No table on standard output.
    #[arg(short, long)]
    quiet: bool,
}

/// The exit of a search's error: bad input exits 2.
pub fn invalid(e: FalsifyError) -> CliError {
    match e {
        FalsifyError::Invalid(m) => CliError::Invalid(m),
        FalsifyError::Files(m) | FalsifyError::Run(m) => CliError::Failed(m),
    }
}

/// The scenario as the search replays it: lock-step, in process, `--set` applied; its links
/// must not have timing effects of their own (the search's timing takes their place).
fn scenario(a: &FalsifyArgs) -> Result<Scenario, CliError> {
    let mut s = load(&a.scenario)?;
    for kv in &a.set {
        let bad = || CliError::Invalid(format!("command line: --set {kv}: expected KEY=VALUE"));
        let (k, v) = kv.split_once('=').ok_or_else(bad)?;
        s = s
            .with_setting(k.trim(), v)
            .map_err(|e| CliError::Invalid(format!("command line: --set {kv}: {e}")))?;
    }
    falsify::prepare(&mut s, &a.scenario.display().to_string()).map_err(invalid)?;
    Ok(s)
}

/// The bounds: the file's, or the envelope of the recorded runs.
fn bounds_of(a: &FalsifyArgs, s: &Scenario) -> Result<(Bounds, String), CliError> {
    if let Some(b) = &a.bounds {
        return Ok((Bounds::read(b).map_err(invalid)?, b.display().to_string()));
    }
    let mut seen = Vec::new();
    for dir in &a.envelope {
        seen.push(envelope_of(dir, s)?);
    }
    let names: Vec<String> = a.envelope.iter().map(|d| d.display().to_string()).collect();
    Ok((
        Bounds::envelope(&seen, s),
        format!("the envelope of {}", names.join(", ")),
    ))
}

/// What the free run in `dir` shows of each link's timing.
fn envelope_of(dir: &Path, s: &Scenario) -> Result<[falsify::timing::LinkObs; 4], CliError> {
    let path = dir.join(tiltsim_master::free::trace::TIMING_CSV);
    let t = tiltsim_master::free::trace::read(
        &path,
        s.run.dt_s,
        s.steps(),
        s.controller_period_ticks(),
    )
    .map_err(|e| CliError::Invalid(format!("--envelope: {e}")))?;
    if let Some(p) = &t.partial {
        return Err(CliError::Invalid(format!(
            "--envelope {}: {p}; allowed: the trace of a whole free run",
            path.display()
        )));
    }
    falsify::timing::observe_all(s, &t)
        .map_err(|e| CliError::Invalid(format!("--envelope {}: {e}", path.display())))
}

/// Runs the command.
pub fn exec(a: FalsifyArgs) -> CliResult {
    if let Some(b) = a.budget.filter(|b| *b < 1 || *b > MAX_BUDGET as i64) {
        return Err(CliError::Invalid(format!(
            "--budget {b}: allowed a whole number of evaluations from 1 to {MAX_BUDGET}"
        )));
    }
    let objective = match (&a.objective, a.requirement.is_empty()) {
        (Some(o), _) => Objective::maximise(o),
        (None, false) => Objective::requirements(&a.requirement),
        (None, true) => Objective::maximise("p_ct"),
    }
    .map_err(invalid)?;
    let shard = super::common::shard_of(a.shard.as_deref(), a.shards)?;
    let s = scenario(&a)?;
    let (bounds, bounds_from) = bounds_of(&a, &s)?;
    // Checked before anything runs: every range holds a whole tick of this scenario.
    bounds.ticks(&s, &bounds_from).map_err(invalid)?;
    let budget = match a.budget {
        Some(b) => b as usize,
        None => falsify::search::default_budget(&s, &bounds, &bounds_from)
            .map_err(invalid)?
            .min(MAX_BUDGET),
    };
    if let Some(sh) = shard.filter(|sh| sh.count > budget) {
        return Err(CliError::Invalid(format!(
            "--shard {}/{}: {} shards for --budget {budget}; allowed: at most as many shards as evaluations",
            sh.index, sh.count, sh.count
        )));
    }
    if let Some(n) = a.restarts.filter(|n| *n > budget) {
        return Err(CliError::Invalid(format!(
            "--restarts {n}: more restarts than --budget {budget}; allowed: 1 to {budget}"
        )));
    }
    let spec = Spec {
        bounds,
        bounds_from,
        objective,
        budget,
        seed: a.seed,
        margin: a.margin.then_some(falsify::margin::MarginPlan {
            max_scale: a.margin_max,
            steps: a.margin_steps,
        }),
    };
    let (interrupt, exe) = interrupt_and_exe()?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(format!("falsify-{}", s.name)));
    let jobs = a.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let _lock = tiltsim_rundir::outdir::claim(&out, tiltsim_rundir::outdir::Kind::Sweep, "falsify")
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    let ex = Exec {
        out: out.clone(),
        jobs,
        exe,
        interrupt: interrupt.clone(),
        done: None,
    };
    let done = match a.restarts {
        Some(n) if n > 1 => falsify::shards::restarts(&s, &spec, n, &ex)
            .map(|(evals, o)| (evals.into_iter().map(|(_, e)| e).collect(), o)),
        _ => falsify::falsify_part(&s, &spec, shard, &ex).map(|(f, o)| (f.evals, o)),
    };
    let (evals, o) = done.map_err(|e| {
        if interrupt.load(std::sync::atomic::Ordering::Relaxed) {
            CliError::Interrupted(e.to_string())
        } else {
            invalid(e)
        }
    })?;
    if !a.quiet {
        print_report(&spec.bounds_from, &evals, &o, &out, Some(jobs));
    }
    verdict(&o, &out)
}

/// Exit 3 for a requirement the search falsified, naming each broken one and the
/// counterexample.
pub fn verdict(o: &falsify::Outcome, out: &Path) -> CliResult {
    if o.violated != Some(true) {
        return Ok(());
    }
    let broken: Vec<String> = o
        .requirements
        .iter()
        .flatten()
        .filter(|j| !j.holds)
        .map(|j| format!("`{}` (margin {:.4})", j.requirement, j.margin))
        .collect();
    Err(CliError::Falsified(format!(
        "falsified: requirement {} broken at the timing in {}/worst/timing.csv \
         (`tiltsim replay-timing {}/worst`)",
        if broken.is_empty() {
            format!("`{}`", o.objective)
        } else {
            broken.join(", ")
        },
        out.display(),
        out.display()
    )))
}

/// Which bounds the worst timing owes most to.
fn print_sensitivity(o: &falsify::Outcome) {
    let Some(shares) = o.sensitivity.as_ref().filter(|s| !s.is_empty()) else {
        return;
    };
    let list: Vec<String> = shares
        .iter()
        .take(4)
        .map(|s| format!("{}.{} {:.4}", s.link, s.parameter, s.drop))
        .collect();
    println!(
        "the worst timing's objective without each bound (drop, largest first): {}",
        list.join(", ")
    );
}

/// The table of a search (or of merged shards) on standard output.
pub fn print_report(
    bounds_from: &str,
    evals: &[falsify::search::Eval],
    o: &falsify::Outcome,
    out: &Path,
    jobs: Option<usize>,
) {
    println!("{}: {} within {}", o.scenario, o.objective, bounds_from);
    println!("| evaluations | CMA-ES best so far | random sampling best so far |");
    println!("|---:|---:|---:|");
    for (k, s, r) in falsify::outputs::checkpoints(evals, o.budget) {
        println!("| {k} | {s:.4} | {r:.4} |");
    }
    print_worst(o);
    print_requirements(o, evals.len());
    print_sensitivity(o);
    print_evidence(o, out);
    print_cost(evals.len(), o, out, jobs);
}

/// The nominal and the worst timing's metric, and whether the worst run is valid.
fn print_worst(o: &falsify::Outcome) {
    println!(
        "nominal (lock-step timing) {}: {:.4}; worst found ({} evaluation {}, {}): {:.4}{}",
        o.metric,
        o.nominal_metric,
        o.worst_found_by,
        o.worst_evaluation,
        o.worst_phase,
        o.worst_metric,
        if o.worst_valid {
            String::new()
        } else {
            format!(
                " (NOT VALID: {})",
                if o.worst_flags.is_empty() {
                    "the replay failed".to_string()
                } else {
                    o.worst_flags.join(", ")
                }
            )
        }
    );
}

/// Each requirement at the worst timing, and the verdict on all of them.
fn print_requirements(o: &falsify::Outcome, evaluations: usize) {
    for j in o.requirements.iter().flatten() {
        println!(
            "requirement `{}` at the worst timing: {}, margin {:.4}",
            j.requirement,
            if j.holds { "holds" } else { "VIOLATED" },
            j.margin
        );
    }
    if let (Some(v), Some(m)) = (o.violated, o.margin) {
        if v {
            println!("requirements {} VIOLATED (margin {m:.4})", o.objective);
        } else {
            println!(
                "requirements {} not falsified within {} evaluations: margin {m:.4} at the \
                 worst timing found (the timings evaluated keep them; that is not a proof that \
                 every admissible one does)",
                o.objective, evaluations
            );
        }
    }
}

/// The evidence beyond the worst found: the timing margin and the random sampling's bound.
fn print_evidence(o: &falsify::Outcome, out: &Path) {
    if let Some(m) = &o.timing_margin {
        let k = |v: Option<f64>| v.map_or("none".to_string(), |k| format!("{k}"));
        println!(
            "timing margin: not falsified with the bounds scaled up to {}, falsified at {} ({} \
             scales searched{})",
            k(m.holds_up_to_scale),
            k(m.broken_at_scale),
            m.steps.len(),
            m.counterexample.as_ref().map_or(String::new(), |c| format!(
                "; counterexample {}/{c}",
                out.display()
            ))
        );
    }
    if let (Some(n), Some(k), Some(p)) =
        (o.random_samples, o.random_broken, o.random_broken_upper_95)
    {
        println!(
            "random sampling: {k} of {n} timings drawn uniformly from the bounds break it; the \
             probability that one so drawn breaks it is below {p:.4} (95 % upper bound, \
             Clopper-Pearson)"
        );
    }
}

/// What the search cost, and the files it wrote.
fn print_cost(evaluations: usize, o: &falsify::Outcome, out: &Path, jobs: Option<usize>) {
    let parallel = jobs.map_or_else(
        || "summed over the shards".into(),
        |j| format!("with {j} parallel"),
    );
    println!(
        "{} evaluations in {:.1} s wall {parallel} ({:.3} s CPU per evaluation; a plain in-process run: {:.3} s CPU){}",
        evaluations,
        o.search_s,
        o.evaluation_cpu_s,
        o.plain_run_cpu_s,
        if o.resumed_evaluations > 0 {
            format!("; {} resumed", o.resumed_evaluations)
        } else {
            String::new()
        }
    );
    println!(
        "wrote {0}/worst/ (timing.csv: `tiltsim replay-timing {0}/worst`), progress.csv, progress.svg, result.json, bounds.toml",
        out.display()
    );
}
