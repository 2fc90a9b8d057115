//! `tiltsim route ROUTE.csv SCENARIO...`: a line's journey times, comfort at every transition,
//! ride on the straights and motion-sickness doses, per scenario (and per ρ and cant
//! deficiency when asked), every segment of every variant run in parallel.

use std::path::PathBuf;

use super::bounds::{self, End};
use super::common::{interrupt_and_exe, load, TransportArg};
use super::error::{CliError, CliResult};
use tiltsim_scenario::scenario::Transport;
use tiltsim_studies::route::outputs::{self, Cost, Journey};
use tiltsim_studies::route::run::{process_cpu_s, RouteExec};
use tiltsim_studies::route::{Grid, Limits, Running, Variant};

/// Which speed profile a scenario runs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunningArg {
    /// Conventional for the passive controller, tilting for the others.
    Auto,
    /// Every scenario on the conventional profile.
    Conventional,
    /// Every scenario on the tilting profile.
    Tilting,
}

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct RouteArgs {
    /// Route file (CSV: chainage_m,length_m,radius_m,cant_mm,transition_m,shape,
    /// vmax_conventional_kmh,vmax_tilting_kmh; docs/scenarios.md, "Routes").
    route: PathBuf,
    /// Scenario files (TOML) whose vehicle, actuator, controller, sensor and track
    /// irregularity run over the route; none: only the speed profiles and journey times.
    scenarios: Vec<PathBuf>,
    /// Cant deficiency of conventional running (mm).
    #[arg(long, default_value_t = 150.0, value_parser = bounds::real((0.0, End::Closed), (400.0, End::Closed), "mm"))]
    cd_conventional: f64,
    /// Cant deficiency of tilting running (mm) [default: 275]; several, comma-separated, run
    /// each tilting scenario at each (a speed sweep).
    #[arg(long, value_delimiter = ',')]
    cd_tilting: Vec<f64>,
    /// Acceleration between sections (m/s²).
    #[arg(long, default_value_t = 0.5, value_parser = bounds::real((0.0, End::Open), (5.0, End::Closed), "m/s²"))]
    accel: f64,
    /// Braking between sections (m/s²).
    #[arg(long, default_value_t = 0.6, value_parser = bounds::real((0.0, End::Open), (5.0, End::Closed), "m/s²"))]
    brake: f64,
    /// Compensation factors: each tilting scenario is run at each (the trade-off study);
    /// comma-separated, each in [0, 1].
    #[arg(long, value_delimiter = ',')]
    rho: Vec<f64>,
    /// Which profile each scenario runs.
    #[arg(long, value_enum, default_value = "auto")]
    running: RunningArg,
    /// Parallel runs [default: the number of CPUs].
    #[arg(long, value_parser = bounds::int(1..=256usize, ""))]
    jobs: Option<usize>,
    /// Transport of every segment's run [default: in-process].
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
    /// Output directory [default: out/route-<route name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Keep every segment's run directory under DIR/runs/.
    #[arg(long)]
    keep_runs: bool,
    /// No tables on standard output.
    #[arg(short, long)]
    quiet: bool,
}

/// The variants the arguments ask for.
fn variants(a: &RouteArgs, base: &Limits) -> Result<Vec<Variant>, CliError> {
    let grid = Grid {
        rho: a.rho.clone(),
        cd_tilting_mm: a.cd_tilting.clone(),
        running: match a.running {
            RunningArg::Auto => None,
            RunningArg::Conventional => Some(Running::Conventional),
            RunningArg::Tilting => Some(Running::Tilting),
        },
    };
    grid.check()
        .map_err(|e| CliError::Invalid(format!("--{e}")))?;
    let mut scenarios = Vec::new();
    for path in &a.scenarios {
        let mut s = load(path)?;
        s.run.transport = a.transport.map_or(Transport::InProcess, Into::into);
        if !s.network.is_local() {
            return Err(CliError::Invalid(format!(
                "{}: a route study runs every segment on this host; remove [network] remote",
                path.display()
            )));
        }
        scenarios.push(s);
    }
    Ok(tiltsim_studies::route::variants(&scenarios, base, &grid))
}

/// Runs the command.
pub fn exec(a: RouteArgs) -> CliResult {
    let route =
        tiltsim_studies::route::load(&a.route).map_err(|e| CliError::Invalid(e.to_string()))?;
    let limits = Limits {
        cant_deficiency_conventional_mm: a.cd_conventional,
        cant_deficiency_tilting_mm: a.cd_tilting.first().copied().unwrap_or(275.0),
        accel_m_s2: a.accel,
        brake_m_s2: a.brake,
    };
    let variants = variants(&a, &limits)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(format!("route-{}", route.name)));
    let (interrupt, exe) = interrupt_and_exe()?;
    let jobs = a.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let _lock = tiltsim_rundir::outdir::claim(&out, tiltsim_rundir::outdir::Kind::Sweep, "route")
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    let ex = RouteExec {
        out: out.clone(),
        jobs,
        keep_runs: a.keep_runs,
        exe,
        interrupt,
    };
    let (t0, c0) = (std::time::Instant::now(), process_cpu_s());
    let results = tiltsim_studies::route::study(&route, &variants, &ex).ok_or_else(|| {
        CliError::Interrupted(format!(
            "interrupted by {}: nothing written",
            tiltsim_rundir::signals::describe()
        ))
    })?;
    let cost = Cost {
        wall_s: t0.elapsed().as_secs_f64(),
        cpu_s: process_cpu_s() - c0,
        jobs,
    };
    outputs::write(&out, &route, &limits, &results, cost)
        .map_err(|e| CliError::Failed(format!("{}: {e}", out.display())))?;
    if !a.quiet {
        let j = Journey::of(&route, &limits);
        println!(
            "{}: {:.1} km, {} curves; journey {:.0} s conventional, {:.0} s tilting: {:.0} s saved ({:.1} %)",
            route.name,
            route.length_m() / 1000.0,
            route.curves(),
            j.conventional_s,
            j.tilting_s,
            j.saved_s,
            j.saved_pct
        );
        if !results.is_empty() {
            println!("{}", outputs::variants_table(&results));
            let segments: usize = results.iter().map(|r| r.segments).sum();
            let simulated: f64 = results.iter().map(|r| r.simulated_s).sum();
            println!(
                "{segments} segments, {simulated:.0} s simulated in {:.1} s wall, {:.1} s CPU, {jobs} parallel runs",
                cost.wall_s, cost.cpu_s
            );
        }
        println!("wrote {0}/route.md, transitions.csv, straights.csv, variants.csv, profile.csv, route.json, plots/", out.display());
    }
    let failed: Vec<String> = results
        .iter()
        .flat_map(|r| r.failed.iter().map(move |f| format!("{}: {f}", r.label)))
        .collect();
    if !failed.is_empty() {
        return Err(CliError::Failed(format!(
            "{} segments did not complete: {}",
            failed.len(),
            failed.join("; ")
        )));
    }
    Ok(())
}
