//! What a lock-step run writes as it goes, each an [`Observer`] the caller adds to a
//! [`Run`](super::Run) in the order it wants them told: the rows ([`Rows`]: `timeseries.csv`,
//! or kept in memory), the exchanges' timestamps ([`TraceCsv`]: `trace.csv`), the recording
//! ([`McapRecording`]: `run.mcap`), and the progress ([`Progress`], [`TicksDone`]). The engine
//! itself writes only `events.csv`, `columns.csv` and `scenario.toml` (the run as it was run);
//! [`Outputs`] is the set a front end asks for, made into observers in the order every front
//! end uses.
//!
//! An observer that hands something back after the run (the rows in memory, the open
//! recording) does so through a [`Handle`] the caller keeps.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use cosim::msg::ToController;
use cosim::Role;
use tiltsim_formats::table::{Recorder, Row};
use tiltsim_scenario::scenario::Scenario;

use super::instruments::{RowRecorder, RowSink};
use super::mcap::{McapRecorder, TickData};
use super::observe::{Observer, Start, Tick};

/// What an observer hands back once the run has returned: the caller keeps a clone and
/// [`take`](Handle::take)s the value.
pub struct Handle<T>(Arc<Mutex<Option<T>>>);

impl<T> Clone for Handle<T> {
    fn clone(&self) -> Self {
        Handle(self.0.clone())
    }
}

impl<T> Handle<T> {
    fn new() -> Self {
        Handle(Arc::new(Mutex::new(None)))
    }

    fn put(&self, v: T) {
        if let Ok(mut slot) = self.0.lock() {
            *slot = Some(v);
        }
    }

    /// The value, once the run has returned (`None` before, or once taken).
    pub fn take(&self) -> Option<T> {
        self.0.lock().ok().and_then(|mut slot| slot.take())
    }
}

/// The outputs a front end asks for beside the ones every run writes (`tiltsim run`'s flags,
/// a sweep's samples, the Python package). [`Outputs::observers`] makes them into observers
/// for the lock-step; a free run (`crate::free`) reads `rows_in_memory` and `record` itself,
/// since its rows are composed from the participants' own clocks rather than told tick by
/// tick.
#[derive(Debug, Clone, Default)]
pub struct Outputs {
    /// Keep the rows in memory instead of writing `timeseries.csv` (a sweep's samples, whose
    /// directories are removed after their analysis).
    pub rows_in_memory: bool,
    /// Write `trace.csv` (every exchange's timestamps) and draw the latency histogram.
    pub trace: bool,
    /// Record the run as `run.mcap`.
    pub record: bool,
    /// Report the progress on standard error.
    pub progress: Option<ProgressStyle>,
    /// Store the ticks finished here after each tick (a notebook's progress bar).
    pub ticks_done: Option<Arc<AtomicU64>>,
}

/// How [`Progress`] reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressStyle {
    /// A bar for a person at a terminal.
    Bar,
    /// A JSON line at every percent (`--progress machine`).
    Lines,
}

/// The observers [`Outputs::observers`] made, and what they hand back.
pub struct Made {
    /// In the order every front end adds them: trace, progress, ticks done, recording, rows.
    pub observers: Vec<Box<dyn Observer>>,
    /// The rows, when kept in memory.
    pub rows: Option<Handle<Vec<Row>>>,
    /// `run.mcap`, open for the caller to close with the analysed summary.
    pub recording: Option<Handle<McapRecorder>>,
}

impl Outputs {
    /// The observers of these outputs for a run of `s` into `dir` (which must exist): the
    /// files are created here, each with its header, so a directory that cannot be written
    /// is named before any participant starts.
    pub fn observers(&self, s: &Scenario, dir: &Path) -> Result<Made, (PathBuf, std::io::Error)> {
        let dt = s.run.dt_s;
        let mut observers: Vec<Box<dyn Observer>> = Vec::new();
        if self.trace {
            let path = dir.join("trace.csv");
            let t = TraceCsv::create(&path, cosim::msg::now_ns(), dt).map_err(|e| (path, e))?;
            observers.push(Box::new(t));
        }
        if let Some(style) = self.progress {
            observers.push(Box::new(Progress::new(style, s.steps(), dt)));
        }
        if let Some(n) = &self.ticks_done {
            observers.push(Box::new(TicksDone(n.clone())));
        }
        let mut recording = None;
        if self.record {
            let path = dir.join("run.mcap");
            let (m, h) = McapRecording::create(&path, dt).map_err(|e| (path, e))?;
            observers.push(Box::new(m));
            recording = Some(h);
        }
        let mut rows = None;
        if self.rows_in_memory {
            let (r, h) = Rows::in_memory(dt, s.steps() as usize + 1);
            observers.push(Box::new(r));
            rows = Some(h);
        } else {
            let path = dir.join("timeseries.csv");
            let r = Rows::to_file(&path, dt).map_err(|e| (path, e))?;
            observers.push(Box::new(r));
        }
        Ok(Made {
            observers,
            rows,
            recording,
        })
    }
}

/// The run's rows (the row declaration of `tiltsim_formats::table`): row 0 with the outputs at t₀, then
/// one row per tick, to `timeseries.csv` as they complete or kept in memory.
pub struct Rows {
    dt: f64,
    rec: RowRecorder,
    kept: Option<Handle<Vec<Row>>>,
    /// The ticks held whole, once closed.
    closed_ticks: Option<u64>,
}

impl Rows {
    /// Rows of a grid of `dt` s to `path` (created now, header first).
    pub fn to_file(path: &Path, dt: f64) -> std::io::Result<Self> {
        let rec = Recorder::create(path)?;
        Ok(Rows {
            dt,
            rec: RowRecorder::new(RowSink::File(Box::new(rec))),
            kept: None,
            closed_ticks: None,
        })
    }

    /// Rows of a grid of `dt` s kept in memory (room for `capacity` made now); the handle
    /// gives them once the run has returned.
    pub fn in_memory(dt: f64, capacity: usize) -> (Self, Handle<Vec<Row>>) {
        let h = Handle::new();
        let rows = Rows {
            dt,
            rec: RowRecorder::new(RowSink::Kept(Vec::with_capacity(capacity))),
            kept: Some(h.clone()),
            closed_ticks: None,
        };
        (rows, h)
    }
}

impl Observer for Rows {
    fn name(&self) -> &str {
        "rows"
    }
    fn start(&mut self, s: &Start<'_>) -> std::io::Result<()> {
        let row = Row::at_start(self.dt, s.plant, s.actuator, s.controller);
        self.rec.put(row)
    }
    fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
        let rx = t.received.ordered();
        let row = Row::after_tick(t.k, self.dt, t.plant, t.actuator, t.controller, &rx);
        self.rec.put(row)
    }
    fn close(&mut self) -> std::io::Result<()> {
        let done = self.rec.finish();
        self.closed_ticks = Some(self.rec.ticks());
        if let Some(h) = &self.kept {
            h.put(self.rec.take_kept().unwrap_or_default());
        }
        done
    }
    fn ticks_kept(&self) -> Option<u64> {
        Some(self.closed_ticks.unwrap_or_else(|| self.rec.ticks()))
    }
}

/// Every exchange's timestamps, streamed to `trace.csv` (ns from the observer's creation) as
/// the run goes: one line per request and its reply.
pub struct TraceCsv {
    origin_ns: u64,
    dt: f64,
    path: PathBuf,
    out: csv::Writer<std::io::BufWriter<std::fs::File>>,
}

impl TraceCsv {
    /// Creates `path` with its header; times count from `origin_ns`, tick `k` is at `k·dt`.
    pub fn create(path: &Path, origin_ns: u64, dt: f64) -> std::io::Result<Self> {
        let file = std::io::BufWriter::with_capacity(1 << 16, std::fs::File::create(path)?);
        let mut out = csv::Writer::from_writer(file);
        out.write_record([
            "step",
            "t",
            "participant",
            "request_sent_ns",
            "request_received_ns",
            "step_started_ns",
            "step_finished_ns",
            "reply_sent_ns",
            "reply_received_ns",
        ])
        .map_err(std::io::Error::other)?;
        out.flush()?;
        Ok(TraceCsv {
            origin_ns,
            dt,
            path: path.to_path_buf(),
            out,
        })
    }

    fn named(&self, e: impl std::fmt::Display) -> std::io::Error {
        std::io::Error::other(format!("{}: {e}", self.path.display()))
    }
}

impl Observer for TraceCsv {
    fn name(&self) -> &str {
        "trace"
    }
    fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
        let rel = |t: u64| t.saturating_sub(self.origin_ns);
        for x in t.exchanges {
            let h = &x.reply;
            let r = self.out.serialize((
                x.step,
                tiltsim_formats::table::fmt_f64(x.step as f64 * self.dt),
                x.role.name(),
                rel(x.sent_ns),
                rel(h.recv_ns),
                rel(h.recv_ns),
                rel(h.recv_ns + h.compute_ns),
                rel(h.sent_ns),
                rel(x.received_ns),
            ));
            if let Err(e) = r {
                return Err(self.named(e));
            }
        }
        Ok(())
    }
    fn close(&mut self) -> std::io::Result<()> {
        self.out.flush().map_err(|e| self.named(e))
    }
}

/// `run.mcap` as the run goes (`crate::engine::mcap`); closed by the caller, through its
/// handle, with the analysed summary and the run's events.
pub struct McapRecording {
    rec: Option<McapRecorder>,
    handle: Handle<McapRecorder>,
    /// The request of a tick the controller is not stepped in (not written).
    idle: ToController,
}

impl McapRecording {
    /// Creates `path` for a run of base tick `dt` (s).
    pub fn create(path: &Path, dt: f64) -> std::io::Result<(Self, Handle<McapRecorder>)> {
        let handle = Handle::new();
        let m = McapRecording {
            rec: Some(McapRecorder::create(path, dt)?),
            handle: handle.clone(),
            idle: ToController::default(),
        };
        Ok((m, handle))
    }

    fn rec(&mut self) -> std::io::Result<&mut McapRecorder> {
        self.rec
            .as_mut()
            .ok_or_else(|| std::io::Error::other("run.mcap already closed"))
    }
}

impl Observer for McapRecording {
    fn name(&self) -> &str {
        "mcap"
    }
    fn start(&mut self, s: &Start<'_>) -> std::io::Result<()> {
        self.rec()?.at_start(s.plant, s.actuator)
    }
    fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
        let k = t.k;
        // Wall-clock times of this tick's step exchanges (the Init ones have step 0 too).
        let when = |role: Role| {
            t.exchanges
                .iter()
                .rev()
                .find(|x| x.role == role && x.step == k)
                .map(|x| (x.sent_ns, x.received_ns))
        };
        let wall = Role::ALL.map(when);
        let (rx, tx) = (t.received.ordered(), t.sent.ordered());
        let to_controller = *t.to_controller.unwrap_or(&self.idle);
        let rec = self.rec()?;
        rec.take_events(t.events);
        rec.write_tick(&TickData {
            k,
            due: t.controller_stepped,
            to_controller: &to_controller,
            p: t.plant,
            a: t.actuator,
            c: t.controller,
            rx: &rx,
            tx: &tx,
            wall,
        })
    }
    fn close(&mut self) -> std::io::Result<()> {
        if let Some(rec) = self.rec.take() {
            self.handle.put(rec);
        }
        Ok(())
    }
}

/// The progress on standard error: a bar, or one JSON line at every whole percent of the
/// run's ticks: `{"progress":P,"step":K,"steps":N,"t_s":T,"wall_s":W}` (wall seconds since
/// the observer was made). For people, wrappers and notebooks; never in a result file.
pub struct Progress {
    steps: u64,
    dt: f64,
    next: u64,
    started: Instant,
    bar: Option<indicatif::ProgressBar>,
}

impl Progress {
    /// Progress over `steps` ticks of `dt` (s) in `style`.
    pub fn new(style: ProgressStyle, steps: u64, dt: f64) -> Self {
        Progress {
            steps,
            dt,
            next: 1,
            started: Instant::now(),
            bar: (style == ProgressStyle::Bar).then(|| Self::bar(steps as f64 * dt)),
        }
    }

    /// A bar of simulated seconds, redrawn at every percent (the tick pays one comparison).
    fn bar(total_s: f64) -> indicatif::ProgressBar {
        let bar = indicatif::ProgressBar::new(100);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos:>3}% {msg} [{elapsed_precise}, {eta} left]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_message(format!("of {total_s:.1} s simulated"));
        bar
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

impl Observer for Progress {
    fn name(&self) -> &str {
        "progress"
    }
    fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
        let done = t.k + 1;
        // The percent reached with this tick (each percent once, 100 at the last tick).
        let percent = done * 100 / self.steps.max(1);
        if percent >= self.next {
            self.next = percent + 1;
            if let Some(b) = &self.bar {
                b.set_position(percent);
                return Ok(());
            }
            eprintln!(
                "{{\"progress\":{percent},\"step\":{done},\"steps\":{},\"t_s\":{},\"wall_s\":{:.3}}}",
                self.steps,
                tiltsim_formats::table::fmt_f64(done as f64 * self.dt),
                self.started.elapsed().as_secs_f64()
            );
        }
        Ok(())
    }
    fn close(&mut self) -> std::io::Result<()> {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
        Ok(())
    }
}

/// Stores the ticks finished so far after each tick, for a caller watching the run from
/// another thread.
pub struct TicksDone(pub Arc<AtomicU64>);

impl Observer for TicksDone {
    fn name(&self) -> &str {
        "ticks_done"
    }
    fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
        self.0.store(t.k + 1, Ordering::Relaxed);
        Ok(())
    }
}
