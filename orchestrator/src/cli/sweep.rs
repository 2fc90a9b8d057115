//! `tiltsim sweep SCENARIO --samples N | --grid KEY=...`: many runs in parallel, a table of
//! comfort metrics and plots.

use std::path::PathBuf;

use super::bounds::{self, End};
use super::common::{interrupt_and_exe, load, TransportArg};
use super::error::{CliError, CliResult};
use tiltsim_scenario::scenario::{Scenario, Transport};
use tiltsim_studies::sweep::{Exec, Plan, Shard};

/// The most samples of a Monte Carlo sweep (`--samples`).
pub const MAX_SAMPLES: usize = 100_000;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Monte Carlo samples (uniform factors on masses, inertias and suspension).
    /// At most 100000: a sample's outputs (its row of samples.csv and its lateral
    /// acceleration in series.csv) are held until the tables are written, about 14 kB each
    /// on the paper's track; more samples are a sweep of sweeps (`--seed`).
    #[arg(long, conflicts_with = "grid", required_unless_present = "grid",
          value_parser = bounds::int(1..=MAX_SAMPLES, ""))]
    samples: Option<usize>,
    /// Relative half-width of the Monte Carlo factors.
    #[arg(long, default_value_t = 0.22,
          value_parser = bounds::real((0.0, End::Closed), (1.0, End::Open), ""))]
    spread: f64,
    /// Seed of the Monte Carlo draws.
    #[arg(long, default_value_t = 1, value_parser = bounds::int(0..=u64::MAX, ""))]
    seed: u64,
    /// Vary one scenario key instead: KEY=START:STOP:STEP or KEY=V1,V2,...
    /// (e.g. links.actuator_command.delay_ticks=0:100:10).
    #[arg(long)]
    grid: Option<String>,
    /// Run only samples j with j mod N = I, for a batch scheduler; merge with sweep-merge.
    /// `auto`: I and N from the array task's environment (Slurm, AWS Batch, or a Kubernetes
    /// indexed job with --shards N).
    #[arg(long, value_name = "I/N|auto")]
    shard: Option<String>,
    /// With --shard auto in a Kubernetes indexed job: the number of completions.
    #[arg(long, value_name = "N", requires = "shard", value_parser = bounds::int(1..=MAX_SAMPLES, ""))]
    shards: Option<usize>,
    /// Print the plan as JSON lines (sample, seed, the settings it changes) and run nothing;
    /// `tiltsim run SCENARIO --set KEY=VALUE ...` with a line's settings runs that sample.
    #[arg(long)]
    plan_only: bool,
    /// Parallel runs [default: the number of CPUs].
    #[arg(long, value_parser = bounds::int(1..=256usize, ""))]
    jobs: Option<usize>,
    /// Transport of every run [default: in-process].
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
    /// Output directory [default: out/sweep-<scenario name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Keep every sample's run directory (timeseries, summary, plots) under DIR/runs/.
    #[arg(long)]
    keep_runs: bool,
    /// No progress bar and no table on standard output.
    #[arg(short, long)]
    quiet: bool,
}

/// The plan the arguments ask for, every sample's scenario checked before anything runs.
fn plan(a: &SweepArgs, s: &Scenario) -> Result<Plan, CliError> {
    let plan = match (&a.grid, a.samples) {
        (Some(g), _) => {
            tiltsim_studies::sweep::parse_grid(g).map_err(|e| CliError::Invalid(e.to_string()))?
        }
        (None, Some(n)) => Plan::MonteCarlo {
            samples: n,
            spread: a.spread,
            seed: a.seed,
        },
        (None, None) => {
            return Err(CliError::Invalid(
                "give --samples N or --grid KEY=START:STOP:STEP".into(),
            ))
        }
    };
    tiltsim_studies::sweep::check_plan(s, &plan)
        .map_err(|e| CliError::Invalid(format!("{}: {e}", a.scenario.display())))?;
    Ok(plan)
}

/// `--plan-only`: one JSON line per sample of the shard.
fn print_plan(s: &Scenario, plan: &Plan, shard: Option<Shard>) -> CliResult {
    use std::io::Write as _;
    let interrupt = tiltsim_rundir::signals::install();
    let mut out = std::io::stdout().lock();
    for j in shard
        .unwrap_or(Shard { index: 0, count: 1 })
        .samples(plan.len())
    {
        if interrupt.load(std::sync::atomic::Ordering::Relaxed) {
            let _ = out.flush();
            return Err(CliError::Interrupted(format!(
                "interrupted by {}: the plan printed up to sample {j}",
                tiltsim_rundir::signals::describe()
            )));
        }
        let set: serde_json::Map<String, serde_json::Value> =
            tiltsim_studies::sweep::overrides(s, plan, j)
                .map_err(|e| CliError::Invalid(e.to_string()))?
                .into_iter()
                .map(|(k, v)| (k, serde_json::to_value(v).unwrap_or_default()))
                .collect();
        let line = serde_json::json!({ "sample": j, "seed": s.run.seed, "set": set });
        match writeln!(out, "{line}") {
            Ok(()) => {}
            // The reader has what it wanted (`| head`).
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(()),
            Err(e) => return Err(CliError::Failed(format!("standard output: {e}"))),
        }
    }
    Ok(())
}

/// Runs the command.
pub fn exec(a: SweepArgs) -> CliResult {
    let mut s = load(&a.scenario)?;
    // In-process by default: a sample then costs no process start, and the results are the
    // same bytes either way.
    s.run.transport = a.transport.map_or(Transport::InProcess, Into::into);
    if !s.network.is_local() {
        return Err(CliError::Invalid(format!(
            "{}: network.remote = {:?}: a sweep runs every sample on this host; remove [network] remote",
            a.scenario.display(),
            s.network.remote.iter().map(|r| r.name()).collect::<Vec<_>>()
        )));
    }
    let plan = plan(&a, &s)?;
    let shard = super::common::shard_of(a.shard.as_deref(), a.shards)?;
    if a.plan_only {
        tiltsim_rundir::signals::end_quietly_on_closed_pipe();
        return print_plan(&s, &plan, shard);
    }
    let (interrupt, exe) = interrupt_and_exe()?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(format!("sweep-{}", s.name)));
    let jobs = a.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let ex = Exec {
        out: out.clone(),
        jobs,
        keep_runs: a.keep_runs,
        exe,
        interrupt,
        progress: !a.quiet,
        samples_done: None,
    };
    // Held until the sweep ends: one sweep (or shard) per directory.
    let _lock = tiltsim_rundir::outdir::claim(&out, tiltsim_rundir::outdir::Kind::Sweep, "sweep")
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    let started = std::time::Instant::now();
    let swept = tiltsim_studies::sweep::run(&s, &plan, shard, &ex).map_err(|e| match e {
        tiltsim_studies::sweep::SweepError::Files(m) => CliError::Failed(m),
        e => CliError::Invalid(e.to_string()),
    })?;
    let rows = swept.rows;
    let wall = started.elapsed().as_secs_f64();
    let build = tiltsim_studies::sweep::identity::build();
    tiltsim_studies::sweep::write_outputs(&out, &s, &plan, shard, &rows, swept.interrupted, build)
        .map_err(|e| CliError::Failed(format!("{}: {e}", out.display())))?;
    if swept.interrupted {
        // What finished stays on disk, marked as such in sweep.json.
        return Err(CliError::Interrupted(format!(
            "interrupted by {}: the {} samples that had finished are written to {} (sweep.json: \"interrupted\": true)",
            tiltsim_rundir::signals::describe(),
            rows.len(),
            out.display()
        )));
    }
    if !a.quiet {
        if let Ok(t) = std::fs::read_to_string(out.join("table.md")) {
            println!("{t}");
        }
        let failed = rows.iter().filter(|r| !r.status.completed()).count();
        println!(
            "{} samples ({} failed) in {wall:.1} s wall with {jobs} parallel runs ({:.2} s per sample)",
            rows.len(),
            failed,
            wall * jobs as f64 / rows.len().max(1) as f64
        );
        println!(
            "wrote {0}/table.md, table.csv, samples.csv, series.csv, sweep.json, plots/",
            out.display()
        );
    }
    Ok(())
}
