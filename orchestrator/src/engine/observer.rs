//! Observers: everything that watches the lock-step without changing it. Each implements
//! [`Observer`] and is told about every tick once its exchanges are done: the recorder, the
//! per-tick timing, the participants' compute times and the QP solver, the link latency, the
//! trace, the real-time pacing and the drive's protection events.

use std::path::Path;
use std::time::{Duration, Instant};

use actuator_proc::bldc::limit;
use cosim::stats::{percentiles, Percentiles};
use cosim::Role;

use super::summary::{LinkLatency, PacingReport, SolverReport};
use super::team::{Exchange, Held};
use crate::events::{EventKind, EventLog};
use crate::record::{Recorder, Row};
use crate::roles::RoleMap;

/// One finished tick, as the observers see it.
pub(crate) struct TickRecord<'a> {
    /// Tick.
    pub k: u64,
    /// Every participant's latest output.
    pub held: &'a Held,
    /// What each receiver got, in `LinkId` order.
    pub rx: &'a [f64; 4],
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
pub(crate) trait Observer {
    /// Before tick `k` starts (pacing waits here).
    fn before_tick(&mut self, _k: u64) {}
    /// After tick `t.k`; may log events. An error stops the run.
    fn after_tick(&mut self, t: &TickRecord, events: &mut EventLog) -> std::io::Result<()>;
}

/// Streams every tick's [`Row`] to `timeseries.csv`.
pub(crate) struct RowRecorder(pub Recorder);

impl Observer for RowRecorder {
    fn after_tick(&mut self, t: &TickRecord, _: &mut EventLog) -> std::io::Result<()> {
        let h = t.held;
        self.0.write(&Row::new(t.k, &h.p, &h.a, &h.c, t.rx))
    }
}

/// Tick wall time and coordination overhead (tick wall time minus the critical compute).
#[derive(Default)]
pub(crate) struct TickTiming {
    /// Overhead per tick (µs).
    pub overhead: Vec<f64>,
    /// Wall time per tick (µs).
    pub ticks: Vec<f64>,
}

impl Observer for TickTiming {
    fn after_tick(&mut self, t: &TickRecord, _: &mut EventLog) -> std::io::Result<()> {
        let tick_us = t.started.elapsed().as_secs_f64() * 1e6;
        self.ticks.push(tick_us);
        self.overhead.push((tick_us - t.critical_us).max(0.0));
        Ok(())
    }
}

/// Each participant's compute time per call and the MPC's QP solves.
#[derive(Default)]
pub(crate) struct ComputeStats {
    /// Per role (µs per call).
    pub per_role: RoleMap<Vec<f64>>,
    solver_iterations: Vec<f64>,
    solver_failures: u64,
}

impl Observer for ComputeStats {
    fn after_tick(&mut self, t: &TickRecord, _: &mut EventLog) -> std::io::Result<()> {
        for role in [Role::Plant, Role::Actuator] {
            self.per_role[role].push(t.compute_ns[role] as f64 * 1e-3);
        }
        if t.controller_due {
            let c = &t.held.c;
            self.per_role[Role::Controller].push(t.compute_ns[Role::Controller] as f64 * 1e-3);
            match controller_proc::SolverStatus::from_raw(c.solver_status) {
                controller_proc::SolverStatus::NoQp => {}
                controller_proc::SolverStatus::Solved => {
                    self.solver_iterations.push(c.solver_iterations as f64)
                }
                controller_proc::SolverStatus::Failed => {
                    self.solver_iterations.push(c.solver_iterations as f64);
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
            iterations: percentiles(&mut self.solver_iterations),
        })
    }

    /// Compute per call, per role.
    pub fn percentiles(&mut self) -> RoleMap<Percentiles> {
        RoleMap::new(Role::ALL.map(|r| percentiles(&mut self.per_role[r])))
    }
}

/// Wall-clock timing of the exchanges with one participant (µs).
#[derive(Default)]
struct LinkClock {
    request: Vec<f64>,
    reply: Vec<f64>,
    round_trip: Vec<f64>,
}

/// Request, reply and round-trip latency of every exchange.
#[derive(Default)]
pub(crate) struct Latency {
    clocks: RoleMap<LinkClock>,
}

fn us(a: u64, b: u64) -> f64 {
    b.saturating_sub(a) as f64 * 1e-3
}

impl Observer for Latency {
    fn after_tick(&mut self, t: &TickRecord, _: &mut EventLog) -> std::io::Result<()> {
        for x in t.exchanges {
            let c = &mut self.clocks[x.role];
            c.request.push(us(x.sent_ns, x.reply.recv_ns));
            c.reply.push(us(x.reply.sent_ns, x.received_ns));
            c.round_trip.push(us(x.sent_ns, x.received_ns));
        }
        Ok(())
    }
}

impl Latency {
    /// Request latencies of every participant (µs), for the histogram.
    pub fn requests(&self) -> RoleMap<Vec<f64>> {
        RoleMap::new(Role::ALL.map(|r| self.clocks[r].request.clone()))
    }

    /// The per-participant report.
    pub fn report(&mut self) -> Vec<LinkLatency> {
        Role::ALL
            .into_iter()
            .map(|r| {
                let c = &mut self.clocks[r];
                LinkLatency {
                    participant: r,
                    request_us: percentiles(&mut c.request),
                    reply_us: percentiles(&mut c.reply),
                    round_trip_us: percentiles(&mut c.round_trip),
                }
            })
            .collect()
    }
}

/// Every exchange's timestamps for `trace.csv` (ns from the start of the loop).
pub(crate) struct Trace {
    origin_ns: u64,
    rows: Vec<Exchange>,
}

impl Trace {
    /// A trace whose times count from `origin_ns`.
    pub fn new(origin_ns: u64) -> Self {
        Trace {
            origin_ns,
            rows: Vec::new(),
        }
    }

    /// Writes `trace.csv` with the `csv` crate.
    pub fn write(&self, path: &Path, dt: f64) -> std::io::Result<()> {
        let mut w = csv::Writer::from_path(path).map_err(std::io::Error::other)?;
        w.write_record([
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
        let rel = |t: u64| t.saturating_sub(self.origin_ns).to_string();
        for x in &self.rows {
            let h = &x.reply;
            w.write_record([
                x.step.to_string(),
                (x.step as f64 * dt).to_string(),
                x.role.name().to_string(),
                rel(x.sent_ns),
                rel(h.recv_ns),
                rel(h.recv_ns),
                rel(h.recv_ns + h.compute_ns),
                rel(h.sent_ns),
                rel(x.received_ns),
            ])
            .map_err(std::io::Error::other)?;
        }
        w.flush()
    }
}

impl Observer for Trace {
    fn after_tick(&mut self, t: &TickRecord, _: &mut EventLog) -> std::io::Result<()> {
        self.rows.extend_from_slice(t.exchanges);
        Ok(())
    }
}

/// Real-time pacing (`--pace`): waits until tick k's wall-clock start, counts late ticks.
pub(crate) struct Pacing {
    factor: f64,
    dt: f64,
    start: Instant,
    overruns: u64,
    late_us: Vec<f64>,
}

impl Pacing {
    /// `factor` simulated seconds per wall second at base tick `dt` (s).
    pub fn new(factor: f64, dt: f64) -> Self {
        Pacing {
            factor,
            dt,
            start: Instant::now(),
            overruns: 0,
            late_us: Vec::new(),
        }
    }

    fn deadline(&self, k: u64) -> Instant {
        self.start + Duration::from_secs_f64(k as f64 * self.dt / self.factor)
    }

    /// The report over `ticks` ticks and `wall` seconds.
    pub fn report(&mut self, ticks: u64, wall: f64) -> PacingReport {
        PacingReport {
            factor: self.factor,
            overruns: self.overruns,
            ticks,
            lateness_us: percentiles(&mut self.late_us),
            achieved_realtime_factor: if wall > 0.0 {
                ticks as f64 * self.dt / wall
            } else {
                0.0
            },
        }
    }
}

/// Sleeps until the monotonic instant `target`, spinning the last 100 µs.
fn wait_until(target: Instant) {
    loop {
        let now = Instant::now();
        if now >= target {
            return;
        }
        let left = target - now;
        if left > Duration::from_micros(200) {
            std::thread::sleep(left - Duration::from_micros(100));
        } else {
            std::hint::spin_loop();
        }
    }
}

impl Observer for Pacing {
    fn before_tick(&mut self, k: u64) {
        if k == 0 {
            self.start = Instant::now();
        }
        wait_until(self.deadline(k));
    }
    fn after_tick(&mut self, t: &TickRecord, _: &mut EventLog) -> std::io::Result<()> {
        let deadline = self.deadline(t.k + 1);
        let now = Instant::now();
        if now > deadline {
            self.overruns += 1;
            self.late_us.push((now - deadline).as_secs_f64() * 1e6);
        }
        Ok(())
    }
}

/// Logs the drive's protections as they begin: an over-current or over-voltage trip and the
/// braking chopper switching on (value: the phase-current peak, A, or the link voltage, V).
#[derive(Default)]
pub(crate) struct DriveEvents {
    previous: u32,
}

impl Observer for DriveEvents {
    fn after_tick(&mut self, t: &TickRecord, ev: &mut EventLog) -> std::io::Result<()> {
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
