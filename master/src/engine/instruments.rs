//! The engine's own measurements of the lock-step, each told about every tick once its
//! exchanges are done, before the caller's observers (`super::observe`): the per-tick timing,
//! the participants' compute times and the QP solver, the link latency, the real-time pacing
//! and the drive's protection events. They fill the summary; the rows, trace, recording and
//! progress are the caller's observers (`super::outputs`). [`RowRecorder`] is the row sink
//! both the lock-step's [`super::outputs::Rows`] and a free run's row stream write through.

use std::time::{Duration, Instant};

use actuator_proc::bldc::limit;
use cosim::stats::{Percentiles, Timings};
use cosim::Role;
use tiltsim_formats::events::{EventKind, EventLog};
use tiltsim_formats::table::{Recorder, Row};
use tiltsim_scenario::roles::RoleMap;

use super::launch::Held;
use super::observe::Exchange;
use super::summary::{LinkLatency, PacingReport, SolverReport};

/// One finished tick, as the engine's instruments see it.
pub(crate) struct FinishedTick<'a> {
    /// Tick.
    pub k: u64,
    /// Every participant's latest output.
    pub held: &'a Held,
    /// What each receiver got, in `LinkId` order.
    pub rx: &'a [f64; 4],
    /// What each sender sent, in `LinkId` order.
    pub tx: &'a [f64; 4],
    /// The controller's request (when `controller_due`).
    pub to_controller: &'a cosim::msg::ToController,
    /// Whether the controller was stepped.
    pub controller_due: bool,
    /// Compute time per role this tick (ns; 0 for a participant not stepped).
    pub compute_ns: RoleMap<u64>,
    /// Compute on the critical path of the master algorithm (µs).
    pub critical_us: f64,
    /// When the tick began.
    pub started: Instant,
    /// The tick's exchanges.
    pub exchanges: &'a [Exchange],
}

/// Something that watches every tick.
pub(crate) trait Instrument {
    /// Before tick `k` starts (pacing waits here).
    fn before_tick(&mut self, _k: u64) {}
    /// After tick `t.k`; may log events. An error stops the run.
    fn after_tick(&mut self, t: &FinishedTick, events: &mut EventLog) -> std::io::Result<()>;
}

/// Streams every tick's [`Row`] to `timeseries.csv`, or keeps it in memory
/// (a sweep's samples), row 0 first.
pub(crate) struct RowRecorder {
    to: RowSink,
}

/// Where a [`RowRecorder`]'s rows go.
pub(crate) enum RowSink {
    /// To `timeseries.csv`.
    File(Box<Recorder>),
    /// In memory.
    Kept(Vec<Row>),
}

impl RowRecorder {
    /// Rows to `to`.
    pub fn new(to: RowSink) -> Self {
        RowRecorder { to }
    }

    /// Writes what is buffered (a no-op in memory).
    pub fn finish(&mut self) -> std::io::Result<()> {
        match &mut self.to {
            RowSink::File(r) => r.finish(),
            RowSink::Kept(_) => Ok(()),
        }
    }

    /// Writes one row.
    pub fn put(&mut self, row: Row) -> std::io::Result<()> {
        match &mut self.to {
            RowSink::File(r) => r.write(&row),
            RowSink::Kept(v) => {
                v.push(row);
                Ok(())
            }
        }
    }

    /// Ticks whose rows are complete (the row at the start time not counted).
    pub fn ticks(&self) -> u64 {
        let rows = match &self.to {
            RowSink::File(r) => r.rows_on_disk(),
            RowSink::Kept(v) => v.len() as u64,
        };
        rows.saturating_sub(1)
    }

    /// The rows kept in memory, if that is where they went.
    pub fn take_kept(&mut self) -> Option<Vec<Row>> {
        match &mut self.to {
            RowSink::File(_) => None,
            RowSink::Kept(v) => Some(std::mem::take(v)),
        }
    }
}

/// Tick wall time and coordination overhead (tick wall time minus the critical compute).
/// Every distribution an observer keeps is a [`Timings`]: constant memory over any run length.
#[derive(Default)]
pub(crate) struct TickTiming {
    /// Overhead per tick (µs).
    pub overhead: Timings,
    /// Wall time per tick (µs).
    pub ticks: Timings,
}

impl Instrument for TickTiming {
    fn after_tick(&mut self, t: &FinishedTick, _: &mut EventLog) -> std::io::Result<()> {
        let tick_us = t.started.elapsed().as_secs_f64() * 1e6;
        self.ticks.record(tick_us);
        self.overhead.record((tick_us - t.critical_us).max(0.0));
        Ok(())
    }
}

/// Each participant's compute time per call and the MPC's QP solves.
#[derive(Default)]
pub(crate) struct ComputeStats {
    /// Per role (µs per call).
    pub per_role: RoleMap<Timings>,
    solver_iterations: Timings,
    solver_failures: u64,
}

impl Instrument for ComputeStats {
    fn after_tick(&mut self, t: &FinishedTick, _: &mut EventLog) -> std::io::Result<()> {
        for role in [Role::Plant, Role::Actuator] {
            self.per_role[role].record(t.compute_ns[role] as f64 * 1e-3);
        }
        if t.controller_due {
            let c = &t.held.c;
            self.per_role[Role::Controller].record(t.compute_ns[Role::Controller] as f64 * 1e-3);
            match controller_proc::SolverStatus::from_raw(c.solver_status) {
                controller_proc::SolverStatus::NoQp => {}
                controller_proc::SolverStatus::Solved => {
                    self.solver_iterations.record(c.solver_iterations as f64)
                }
                controller_proc::SolverStatus::Failed => {
                    self.solver_iterations.record(c.solver_iterations as f64);
                    self.solver_failures += 1;
                }
            }
        }
        Ok(())
    }
}

impl ComputeStats {
    /// The QP solver's report, if a QP ran.
    pub fn solver(&mut self) -> Option<SolverReport> {
        (!self.solver_iterations.is_empty()).then(|| SolverReport {
            solves: self.solver_iterations.len() as u64,
            failures: self.solver_failures,
            iterations: self.solver_iterations.percentiles(),
        })
    }

    /// Compute per call, per role.
    pub fn percentiles(&mut self) -> RoleMap<Percentiles> {
        RoleMap::new(Role::ALL.map(|r| self.per_role[r].percentiles()))
    }
}

/// Wall-clock timing of the exchanges with one participant (µs).
#[derive(Default)]
struct LinkClock {
    request: Timings,
    reply: Timings,
    round_trip: Timings,
}

/// Request, reply and round-trip latency of every exchange.
#[derive(Default)]
pub(crate) struct Latency {
    clocks: RoleMap<LinkClock>,
}

fn us(a: u64, b: u64) -> f64 {
    b.saturating_sub(a) as f64 * 1e-3
}

impl Instrument for Latency {
    fn after_tick(&mut self, t: &FinishedTick, _: &mut EventLog) -> std::io::Result<()> {
        for x in t.exchanges {
            let c = &mut self.clocks[x.role];
            c.request.record(us(x.sent_ns, x.reply.recv_ns));
            c.reply.record(us(x.reply.sent_ns, x.received_ns));
            c.round_trip.record(us(x.sent_ns, x.received_ns));
        }
        Ok(())
    }
}

/// Every participant's request latency (orchestrator sent → participant received), binned:
/// 80 bins up to the largest 99.9th percentile of them, the last bin holding everything above.
pub struct LatencyHistogram {
    /// The bins' centres (µs).
    pub centres_us: Vec<f64>,
    /// The exchanges in each bin, for each participant in [`Role::ALL`]'s order.
    pub counts: Vec<(Role, Vec<f64>)>,
}

impl Latency {
    /// Request latency of one participant (µs).
    fn requests(&self, role: Role) -> &Timings {
        &self.clocks[role].request
    }

    /// The request latencies binned for the histogram figure.
    pub fn request_histogram(&self) -> LatencyHistogram {
        let top = Role::ALL
            .iter()
            .map(|r| self.requests(*r).quantile(0.999))
            .fold(1.0, f64::max);
        let bin = (top / 80.0).max(0.05);
        let nb = (top / bin).ceil() as usize + 1;
        let centres_us = (0..nb).map(|i| (i as f64 + 0.5) * bin).collect();
        let counts = Role::ALL
            .iter()
            .map(|role| {
                let t = self.requests(*role);
                let mut h: Vec<f64> = (0..nb)
                    .map(|i| t.count_between(i as f64 * bin, (i + 1) as f64 * bin) as f64)
                    .collect();
                // The last bin holds everything above it.
                h[nb - 1] += t.count_between(nb as f64 * bin, f64::MAX / 2e3) as f64;
                (*role, h)
            })
            .collect();
        LatencyHistogram { centres_us, counts }
    }

    /// The per-participant report.
    pub fn report(&mut self) -> Vec<LinkLatency> {
        Role::ALL
            .into_iter()
            .map(|r| {
                let c = &mut self.clocks[r];
                LinkLatency {
                    participant: r,
                    request_us: c.request.percentiles(),
                    reply_us: c.reply.percentiles(),
                    round_trip_us: c.round_trip.percentiles(),
                }
            })
            .collect()
    }
}

/// Real-time pacing (`--pace`): waits until tick k's wall-clock start, counts late ticks.
pub(crate) struct Pacing {
    factor: f64,
    dt: f64,
    start: Instant,
    overruns: u64,
    late_us: Timings,
    previous_late: bool,
    causes: [u64; 4],
    start_delay: Timings,
    compute: Timings,
    coordination: Timings,
    realtime: bool,
}

impl Pacing {
    /// `factor` simulated seconds per wall second at base tick `dt` (s); `realtime`: the
    /// processes run under SCHED_FIFO (reported).
    pub fn new(factor: f64, dt: f64, realtime: bool) -> Self {
        cosim::wait::tight_timer_slack();
        Pacing {
            factor,
            dt,
            start: Instant::now(),
            overruns: 0,
            late_us: Timings::default(),
            previous_late: false,
            causes: [0; 4],
            start_delay: Timings::default(),
            compute: Timings::default(),
            coordination: Timings::default(),
            realtime,
        }
    }

    /// Tick k's wall-clock start; `None` beyond what the clock can express (never for the
    /// factors `--pace` allows, but no factor can make it panic).
    fn deadline(&self, k: u64) -> Option<Instant> {
        let after = Duration::try_from_secs_f64(k as f64 * self.dt / self.factor).ok()?;
        self.start.checked_add(after)
    }

    /// The report over `ticks` ticks and `wall` seconds.
    pub fn report(&mut self, ticks: u64, wall: f64) -> PacingReport {
        PacingReport {
            factor: self.factor,
            overruns: self.overruns,
            ticks,
            lateness_us: self.late_us.percentiles(),
            achieved_realtime_factor: if wall > 0.0 {
                ticks as f64 * self.dt / wall
            } else {
                0.0
            },
            causes: super::summary::OverrunCauses {
                carried_over: self.causes[0],
                orchestrator: self.causes[1],
                compute: self.causes[2],
                coordination: self.causes[3],
                start_delay_us: self.start_delay.percentiles(),
                compute_us: self.compute.percentiles(),
                coordination_us: self.coordination.percentiles(),
            },
            realtime: self.realtime,
        }
    }
}

/// The longest single sleep of a paced wait: an interrupting signal (Ctrl-C, SIGTERM,
/// SIGHUP) ends the wait within this, however slow the pace.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Sleeps until the monotonic instant `target` (`None`: until a signal), spinning the last
/// 100 µs (the sleep's own wake-up latency; under SCHED_FIFO it is a few µs, otherwise up to
/// the scheduler's slack). Returns early once an interrupting signal has arrived; the loop
/// then stops before the next tick.
fn wait_until(target: Option<Instant>) {
    loop {
        if tiltsim_rundir::signals::received() {
            return;
        }
        let now = Instant::now();
        let left = match target {
            Some(t) if now >= t => return,
            Some(t) => t - now,
            None => SIGNAL_POLL,
        };
        if left > Duration::from_micros(200) {
            std::thread::sleep((left - Duration::from_micros(100)).min(SIGNAL_POLL));
        } else {
            std::hint::spin_loop();
        }
    }
}

impl Instrument for Pacing {
    fn before_tick(&mut self, k: u64) {
        if k == 0 {
            self.start = Instant::now();
        }
        wait_until(self.deadline(k));
    }
    fn after_tick(&mut self, t: &FinishedTick, _: &mut EventLog) -> std::io::Result<()> {
        let now = Instant::now();
        // A deadline beyond the clock's reach is never missed.
        let deadline = self.deadline(t.k + 1).unwrap_or(now);
        let late = now > deadline;
        if late {
            self.overruns += 1;
            self.late_us.record((now - deadline).as_secs_f64() * 1e6);
            let us = |d: Duration| d.as_secs_f64() * 1e6;
            let start_delay = us(t
                .started
                .saturating_duration_since(self.deadline(t.k).unwrap_or(t.started)));
            let compute = t.critical_us;
            let coordination = (us(now - t.started) - compute).max(0.0);
            self.start_delay.record(start_delay);
            self.compute.record(compute);
            self.coordination.record(coordination);
            let cause = if start_delay >= compute.max(coordination) {
                usize::from(!self.previous_late)
            } else if compute >= coordination {
                2
            } else {
                3
            };
            self.causes[cause] += 1;
        }
        self.previous_late = late;
        Ok(())
    }
}

/// Logs the drive's protections as they begin: an over-current or over-voltage trip and the
/// braking chopper switching on (value: the phase-current peak, A, or the link voltage, V).
#[derive(Default)]
pub(crate) struct DriveEvents {
    previous: u32,
}

impl Instrument for DriveEvents {
    fn after_tick(&mut self, t: &FinishedTick, ev: &mut EventLog) -> std::io::Result<()> {
        let a = &t.held.a;
        let rising = a.limits & !self.previous;
        self.previous = a.limits;
        for (bit, kind, value, detail) in [
            (
                limit::OVERCURRENT_TRIP,
                EventKind::OvercurrentTrip,
                a.phase_current_peak,
                "a phase current passed the current limit plus half the band; gates blocked",
            ),
            (
                limit::OVERVOLTAGE,
                EventKind::OvervoltageTrip,
                a.v_dc,
                "the DC link passed its over-voltage trip level; gates blocked",
            ),
            (
                limit::CHOPPER,
                EventKind::ChopperOn,
                a.v_dc,
                "the DC link reached the chopper threshold; braking energy dumped",
            ),
        ] {
            if rising & bit != 0 {
                ev.push(t.k, "actuator", kind, value, detail);
            }
        }
        Ok(())
    }
}
