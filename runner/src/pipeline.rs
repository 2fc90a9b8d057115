//! One run, whatever its execution and whichever front end asks for it (`tiltsim run`,
//! `--free-run`, `replay-timing`, `compare`, `sweep`, the Python package): the output-size
//! check, the directory claim, the engine of the mode (lock-step, free, or the lock-step
//! replay of a free run's timing), the rows streamed as they complete, the analysis, one
//! typed `summary.json` and one `perf.json`, `run.mcap` closed with the summary, and the
//! figures. A front end builds a [`Job`], calls [`carry_out`] and prints what it returns.

use std::path::PathBuf;

use tiltsim_formats::table::{Row, Rows};
use tiltsim_master::engine::manipulate::Manipulator;
use tiltsim_master::engine::observe::Observer;
use tiltsim_master::engine::outputs::Outputs;
use tiltsim_master::engine::{RunError, RunMode, RunOptions, Status, Summary};
use tiltsim_master::free::{FreeError, TraceError};
use tiltsim_rundir::budget::{self, Verdict};
use tiltsim_scenario::scenario::{Execution, Scenario};

/// Makes `s` the system a replay of a free run's timing runs: lock-step, and with no busy
/// wait in the controller (a study's wall-clock load, which changes no value). Every front
/// end that replays a timing trace applies this before validating the scenario.
pub fn as_timing_replay(s: &mut Scenario) {
    s.run.execution = tiltsim_scenario::scenario::Execution::LockStep;
    s.run.controller_busy_wait_s = 0.0;
    // A free run across hosts is replayed on one machine: its trace holds the network's
    // timing, on the orchestrator's clock.
    s.network = Default::default();
}

/// What to run and how.
pub struct Job<'a> {
    /// The scenario, validated.
    pub scenario: &'a Scenario,
    /// Where it came from, for the summary (a path, or a name).
    pub scenario_file: String,
    /// How to run it.
    pub opts: RunOptions,
    /// What it writes beside its summary (`outputs.rows_in_memory` keeps the rows in memory
    /// and writes no file at all).
    pub outputs: Outputs,
    /// The caller's observers of a lock-step run, told after the outputs' own, or of a timing
    /// replay (a free run takes none: [`carry_out`] refuses them).
    pub observers: Vec<Box<dyn Observer>>,
    /// The caller's manipulators of a lock-step run or a timing replay, after the scenario's
    /// own (refused for a free run; a replay calls only their `carry`).
    pub manipulators: Vec<Box<dyn Manipulator>>,
    /// Replay this free run's timing trace in lock-step instead of running the scenario's
    /// execution (`tiltsim replay-timing`).
    pub replay_trace: Option<PathBuf>,
    /// Replay this trace, held in memory, in place of a file's (`replay_trace` then only
    /// names it): a trace made by a program (`tiltsim falsify`'s candidates).
    pub replay_steps: Option<tiltsim_master::free::trace::Trace>,
    /// Take the output directory for this run (refused while another run holds it; an
    /// earlier run's files there are removed). A caller that has taken it already (a
    /// comparison's directory, a sweep's sample) sets this false.
    pub claim: bool,
}

impl<'a> Job<'a> {
    /// A job that runs `scenario` as its file says, claiming `opts.out_dir`.
    pub fn new(scenario: &'a Scenario, scenario_file: impl Into<String>, opts: RunOptions) -> Self {
        Job {
            scenario,
            scenario_file: scenario_file.into(),
            opts,
            outputs: Outputs::default(),
            observers: Vec::new(),
            manipulators: Vec::new(),
            replay_trace: None,
            replay_steps: None,
            claim: true,
        }
    }

    /// Whether it writes files (not when its rows are kept in memory).
    pub fn writes_files(&self) -> bool {
        !self.outputs.rows_in_memory
    }

    /// How this job runs.
    pub fn mode(&self) -> RunMode {
        let replays = self.replay_trace.is_some() || self.replay_steps.is_some();
        match (replays, self.scenario.run.execution) {
            (true, _) => RunMode::ReplayTiming,
            (false, Execution::Free) => RunMode::Free,
            (false, Execution::LockStep) => RunMode::LockStep,
        }
    }
}

/// What a finished run hands back (its files are in `opts.out_dir`).
#[derive(Debug)]
pub struct Done {
    /// The run's summary, analysed (as written to `summary.json`).
    pub summary: Summary,
    /// The rows, when kept in memory (`outputs.rows_in_memory`); empty otherwise.
    pub rows: Vec<Row>,
    /// What the user should know that did not stop the run (a large share of the disk, a
    /// figure not drawn, a file not written).
    pub warnings: Vec<String>,
    /// The run replaced the files of an earlier run in its directory (removed when it took
    /// the directory).
    pub replaced_earlier_run: bool,
}

/// Why a run could not be carried out (a run that started and then failed is a [`Done`]
/// whose summary says so).
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// Bad input: the message names the file, the field and what is allowed.
    #[error("{0}")]
    Invalid(String),
    /// The participants could not be started, or a file not written.
    #[error(transparent)]
    Run(#[from] RunError),
    /// The timing trace does not belong to the scenario.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// The run's outputs could not be read back (the Python package's arrays).
    #[error("{0}")]
    Failed(String),
}

impl From<FreeError> for JobError {
    fn from(e: FreeError) -> Self {
        match e {
            FreeError::Run(r) => JobError::Run(r),
            FreeError::Trace(t) => JobError::Trace(t),
        }
    }
}

/// Carries out `job`: see the module's description. Refuses before anything is written when
/// the outputs would not fit on the disk or the directory is another run's.
pub fn carry_out(mut job: Job) -> Result<Done, JobError> {
    let s = job.scenario;
    let files = job.writes_files();
    let mut warnings = Vec::new();
    // A free run's steps are timed by the participants' own clocks, not told by a master:
    // nothing can act on them as they go, and what is watched is the trace, replayed.
    if job.mode() == RunMode::Free && !job.observers.is_empty() {
        return Err(JobError::Invalid(format!(
            "{}: observers watch a lock-step run or a timing replay; this one is a free run (run.execution = \"free\"): replay its timing.csv with them",
            job.scenario_file
        )));
    }
    if job.mode() == RunMode::Free && !job.manipulators.is_empty() {
        return Err(JobError::Invalid(format!(
            "{}: manipulators act on a lock-step run or a timing replay; this one is a free run (run.execution = \"free\")",
            job.scenario_file
        )));
    }
    if files {
        let extras = budget::Extras {
            trace: job.outputs.trace,
            record: job.outputs.record,
        };
        match budget::check(s, &job.opts.out_dir, extras) {
            Verdict::Fits => {}
            Verdict::Warn(m) => warnings.push(format!("{}: {m}", job.scenario_file)),
            Verdict::Refuse(m) => {
                return Err(JobError::Invalid(format!("{}: {m}", job.scenario_file)))
            }
        }
    }
    let lock = if files && job.claim {
        Some(
            tiltsim_rundir::outdir::claim_run(&job.opts.out_dir, "run")
                .map_err(|e| JobError::Invalid(e.to_string()))?,
        )
    } else {
        None
    };
    let ran = match job.mode() {
        RunMode::LockStep => lock_step(&mut job, &mut warnings)?,
        RunMode::Free => free(&job)?,
        RunMode::ReplayTiming => replay(&mut job)?,
    };
    let mut done = finish(&job, ran, warnings);
    done.replaced_earlier_run = lock.as_ref().is_some_and(|l| l.replaced() > 0);
    Ok(done)
}

/// What an engine hands to the analysis.
struct Ran {
    summary: Summary,
    rows: Vec<Row>,
    recording: Option<Recording>,
    /// The whole car's samples (`vehicle.model = "full"`).
    car: Option<crate::full_car::CarSamples>,
}

/// `run.mcap`, open until the summary closes it.
enum Recording {
    LockStep(
        tiltsim_master::engine::mcap::McapRecorder,
        tiltsim_formats::events::EventLog,
    ),
    Free(tiltsim_master::free::recording::FreeRecording),
}

/// The lock-step: the outputs' observers first, then the caller's.
fn lock_step(job: &mut Job, warnings: &mut Vec<String>) -> Result<Ran, JobError> {
    let opts = &job.opts;
    let s = job.scenario;
    std::fs::create_dir_all(&opts.out_dir).map_err(RunError::io(opts.out_dir.clone()))?;
    let made = job
        .outputs
        .observers(s, &opts.out_dir)
        .map_err(|(path, source)| RunError::Io { path, source })?;
    let mut run = tiltsim_master::engine::Run::new(s, &job.scenario_file, opts);
    for o in made.observers.into_iter().chain(job.observers.drain(..)) {
        run = run.add_observer(o);
    }
    let (car_observer, car) = car_observer(job)?;
    if let Some(o) = car_observer {
        run = run.add_observer(o);
    }
    for m in job.manipulators.drain(..) {
        run = run.add_manipulator(m);
    }
    let ran = run.simulate()?;
    let mut summary = ran.summary;
    // Over IPC, other work on the machine slows the exchanges; in-process gives the same bytes.
    if summary.transport == tiltsim_scenario::scenario::Transport::Ipc {
        if let Some(note) = summary.timing.machine.as_ref().and_then(|m| m.note()) {
            warnings.push(note);
        }
    }
    // With `--trace`: a figure that cannot be written fails the run, as the trace would.
    if let Some(h) = ran.latency_histogram.filter(|_| job.outputs.trace) {
        if let Err(e) =
            tiltsim_report::analysis::latency_histogram(&opts.out_dir, &job.scenario.name, &h)
        {
            if summary.error.is_none() {
                summary.status = Status::Failed;
                summary.error = Some(format!("cannot write {e}"));
            } else {
                warnings.push(format!("latency histogram not drawn: {e}"));
            }
        }
    }
    Ok(Ran {
        summary,
        rows: made.rows.and_then(|h| h.take()).unwrap_or_default(),
        recording: made
            .recording
            .and_then(|h| h.take())
            .map(|r| Recording::LockStep(r, ran.events)),
        car,
    })
}

/// The whole car's observer and the handle its assessment is read through after the run.
type CarObserved = (
    Option<Box<dyn Observer>>,
    Option<crate::full_car::CarSamples>,
);

/// The whole car's observer (`vehicle.model = "full"`) and the handle its assessment is read
/// through after the run; none for the half vehicle.
fn car_observer(job: &Job) -> Result<CarObserved, JobError> {
    let s = job.scenario;
    if s.vehicle.model != vehicle_model::VehicleModel::Full {
        return Ok((None, None));
    }
    let dir = &job.opts.out_dir;
    let spill = job.writes_files().then_some(dir.as_path());
    if spill.is_some() {
        std::fs::create_dir_all(dir).map_err(RunError::io(dir.clone()))?;
    }
    let (o, samples) = crate::full_car::CarObserver::new(s, spill)
        .map_err(RunError::io(dir.join(crate::full_car::SPILL_FILE)))?;
    Ok((Some(Box::new(o)), Some(samples)))
}

fn free(job: &Job) -> Result<Ran, JobError> {
    let s = job.scenario;
    let (car_observer, car) = car_observer(job)?;
    let observers = car_observer.into_iter().collect();
    let mut r = tiltsim_master::free::run(s, &job.opts, &job.outputs, observers)?;
    let summary = tiltsim_master::free::summary_of_run(s, &job.scenario_file, &mut r);
    Ok(Ran {
        summary,
        rows: r.rows.take().unwrap_or_default(),
        recording: r.recording.take().map(Recording::Free),
        car,
    })
}

fn replay(job: &mut Job) -> Result<Ran, JobError> {
    let s = job.scenario;
    let trace = job
        .replay_trace
        .clone()
        .unwrap_or_else(|| PathBuf::from("(in memory)"));
    let (car_observer, car) = car_observer(job)?;
    let mut observers = std::mem::take(&mut job.observers);
    observers.extend(car_observer);
    let attached = tiltsim_master::free::timing_replay::Attached {
        observers,
        manipulators: std::mem::take(&mut job.manipulators),
    };
    let mut r = match job.replay_steps.take() {
        Some(steps) => tiltsim_master::free::timing_replay::replay_trace(
            s,
            steps,
            &trace,
            &job.opts,
            &job.outputs,
            attached,
        )?,
        None => tiltsim_master::free::replay_timing(s, &trace, &job.opts, &job.outputs, attached)?,
    };
    let trace = trace.as_path();
    let summary = tiltsim_master::free::summary_of_replay(s, &job.scenario_file, trace, &mut r);
    Ok(Ran {
        summary,
        rows: r.rows.take().unwrap_or_default(),
        recording: None,
        car,
    })
}

/// Fills the summary's results, comfort and flags from the run's rows (on disk, or `rows`
/// when kept in memory), or says why they were not computed (an interrupt, a series that
/// could not be read whole).
fn analyse(job: &Job, summary: &mut Summary, rows: &[Row]) {
    let s = job.scenario;
    let opts = &job.opts;
    let files = job.writes_files();
    let interrupted = opts.interrupt.load(std::sync::atomic::Ordering::Relaxed);
    if interrupted {
        // An hour's series takes tens of seconds to analyse: `tiltsim plot DIR` draws it later.
        summary.analysis_skipped = Some(format!(
            "interrupted by {}: comfort, flags and figures not computed",
            tiltsim_rundir::signals::describe()
        ));
    } else {
        let source = if files {
            Rows::File(&opts.out_dir)
        } else {
            Rows::Kept(rows)
        };
        match tiltsim_report::analysis::assess(s, source) {
            Ok(a) => {
                // The run's own verdict on its timing (a replay's, from the free run's trace).
                let not_real_time = summary.flags.not_real_time.take();
                summary.results = a.results;
                summary.comfort = a.comfort;
                summary.flags = a.flags;
                summary.flags.not_real_time = not_real_time;
            }
            // Results from part of a series would read as the run's: none are given.
            Err(e) => {
                summary.analysis_skipped =
                    Some(format!("comfort, flags and results not computed: {e}"))
            }
        }
        if let Some(f) = &summary.free_run {
            summary.flags.not_real_time = Some(tiltsim_assessment::validity::NotRealTime {
                raised: f.not_real_time,
                plant_max_lateness_s: f.plant_max_lateness_s,
                margin_s: f.not_real_time_margin_s,
            });
        }
        if tiltsim_rundir::signals::received() {
            summary.analysis_skipped = Some(format!(
                "interrupted by {} during the analysis: comfort and flags incomplete, figures not drawn",
                tiltsim_rundir::signals::describe()
            ));
        }
    }
}

/// The analysis, `summary.json`, `perf.json`, the recording's close and the figures.
fn finish(job: &Job, ran: Ran, mut warnings: Vec<String>) -> Done {
    let s = job.scenario;
    let opts = &job.opts;
    let files = job.writes_files();
    let Ran {
        mut summary,
        rows,
        recording,
        car,
    } = ran;
    analyse(job, &mut summary, &rows);
    if let Some(car) = car.filter(|_| summary.analysis_skipped.is_none()) {
        let source = if files {
            Rows::File(&opts.out_dir)
        } else {
            Rows::Kept(&rows)
        };
        crate::full_car::assess(s, &mut summary, &car, source);
    }
    summary.comfort_valid =
        summary.analysis_skipped.is_none() && !summary.flags.comfort_not_valid();
    if files {
        // The summary takes the disk's space before the figures do.
        for (name, value) in [
            ("summary.json", serde_json::to_value(&summary)),
            ("perf.json", Ok(summary.perf())),
        ] {
            let path = opts.out_dir.join(name);
            let text = value
                .map(|v| serde_json::to_string_pretty(&v).unwrap_or_default() + "\n")
                .unwrap_or_default();
            if let Err(e) = tiltsim_rundir::files::write_atomic(&path, text) {
                let what = format!("cannot write {}: {e}", path.display());
                if summary.error.is_none() && summary.status == Status::Completed {
                    summary.status = Status::Failed;
                    summary.error = Some(what);
                } else {
                    warnings.push(what);
                }
            }
        }
    }
    if let Some(rec) = recording {
        let closed = match rec {
            Recording::LockStep(r, events) => r.finish(&events, &summary),
            Recording::Free(r) => {
                let det = tiltsim_master::engine::summary::deterministic(
                    serde_json::to_value(&summary).unwrap_or_default(),
                );
                r.finish(&det, &summary.perf())
            }
        };
        if let Err(e) = closed {
            warnings.push(format!("recording not completed: {e}"));
        }
    }
    let drawn = files && opts.plots && summary.analysis_skipped.is_none();
    if drawn {
        if let Err(e) = tiltsim_report::analysis::write_plots(s, &opts.out_dir) {
            warnings.push(format!("plots not written: {e}"));
        }
        if summary.execution == RunMode::Free {
            // A run that ended early has a partial trace: no timing figures (the trace stays).
            if let Err(e) = tiltsim_report::analysis::write_timing_plots(s, &opts.out_dir) {
                warnings.push(format!("timing plots not drawn: {e}"));
            }
        }
    }
    Done {
        summary,
        rows,
        warnings,
        replaced_earlier_run: false,
    }
}
