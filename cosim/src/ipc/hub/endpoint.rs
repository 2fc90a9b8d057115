//! The orchestrator's handle on one participant process: send a request, wait for its reply
//! (re-sending a lost one), judge a silent participant, shut it down.

use std::process::Child;
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use std::sync::atomic::{AtomicBool, Ordering};

use crate::endpoint::{check_reply, Endpoint, ExchangeCounts, ExitReport, LinkError, ProcessFault};
use crate::ipc::supervise::{try_reap, Status};
use crate::ipc::{DropPlan, Resent};
use crate::msg::{exchange_key, Header, Kind, Message};
use crate::participant::Role;
use crate::wait::{Backoff, WaitStrategy};

use super::liveness::{judge, past_ceiling, Liveness, Looks, LOOK_EVERY};

/// The orchestrator's handle on a participant process.
pub struct IpcEndpoint<I: Message, O: Message> {
    pub(super) role: Role,
    pub(super) pid: u32,
    pub(super) child: Option<Child>,
    pub(super) exit: Option<ExitReport>,
    pub(super) publisher: Publisher<ipc::Service, I, ()>,
    pub(super) subscriber: Subscriber<ipc::Service, O, ()>,
    pub(super) req: PubSubFactory<ipc::Service, I, ()>,
    pub(super) rep: PubSubFactory<ipc::Service, O, ()>,
    pub(super) wait: WaitStrategy,
    /// Polls spent spinning before yielding: 0 when the participant shares this CPU.
    pub(super) spin_polls: u32,
    pub(super) deadline: Duration,
    pub(super) ceiling: Duration,
    /// Starved waits, re-sent requests, discarded repeats.
    pub(super) counts: ExchangeCounts,
    /// What the participant reports of its side.
    pub(super) status: Status,
    /// The request last sent (re-sent with the next attempt when its exchange goes silent).
    pub(super) last_request: Option<I>,
    /// The request last re-sent: answers to its repeats are expected.
    pub(super) resent: Option<Resent>,
    /// Samples dropped on purpose (tests only).
    pub(super) drops: DropPlan,
    /// The participant's standard error (`None` for one served in this process).
    pub(super) log: Option<std::path::PathBuf>,
    /// In a free run, the step after the newest sample taken from the participant: the one it
    /// was at when it is found gone (0 before its first).
    pub(super) free_pending: u64,
    /// The request sent ahead of the one pending ([`Endpoint::send_ahead`]): it becomes the
    /// request last sent once the pending reply is taken.
    pub(super) ahead: Option<I>,
    /// A reply to the request sent ahead that came while the pending one was waited for.
    pub(super) early: Option<O>,
}

/// Silence after which a pending exchange is looked into (the participant's status read) and
/// a request or reply found lost is re-sent. Ten times the 99th percentile of a round trip
/// measured on a quiet machine (under 50 µs, `tiltsim bench`), so the normal path never reaches it;
/// short enough that a loss costs well under a millisecond or two. Looking costs three loads
/// from shared memory, and a re-send happens only when the status shows a loss, so a long
/// wait (a starved participant) costs nothing either.
pub const RESEND_AFTER: Duration = Duration::from_micros(500);

impl<I: Message, O: Message> IpcEndpoint<I, O> {
    /// Stamps and publishes a request (unless the drop plan loses its first sending).
    fn publish_request(&mut self, mut req: I) -> Result<(), LinkError> {
        req.stamp();
        if self.drops.drops(true, req.header()) {
            return Ok(());
        }
        let undelivered =
            crate::ipc::publish(&self.publisher, req).map_err(|what| LinkError::Transport {
                role: self.role,
                what,
            })?;
        self.counts.lost_samples.undelivered_requests += undelivered;
        Ok(())
    }

    /// After the reply `h` was taken: a request sent ahead of it is now the one pending.
    fn took(&mut self, h: &Header) {
        if self.ahead.is_some_and(|a| a.header().step > h.step) {
            self.last_request = self.ahead.take();
        }
    }

    /// How the process ended, if it has, with the last line of its standard error (why it
    /// ended is usually the last thing it wrote).
    fn exited(&mut self) -> Option<String> {
        let status = match &self.exit {
            Some(r) => r.status.clone(),
            None => {
                self.child.as_ref()?;
                let report = try_reap(self.pid, false)?;
                self.child = None;
                let status = report.status.clone();
                self.exit = Some(report);
                status
            }
        };
        Some(match self.log.as_deref().and_then(super::logs::last_line) {
            Some(line) => format!("{status}; its standard error ends: {line}"),
            None => status,
        })
    }

    /// Waits until the participant's ports are connected. The liveness rule of every exchange
    /// applies from `startup` on: a participant that is runnable or uses CPU (starting under
    /// load) is waited for, counted, up to the ceiling; a stopped, gone or idle one fails.
    /// Returns `false`, not connected, once `interrupt` is set.
    pub(super) fn await_connection(
        &mut self,
        startup: Duration,
        interrupt: Option<&AtomicBool>,
    ) -> Result<bool, LinkError> {
        let started = Instant::now();
        let mut look_at = startup;
        let mut previous = None;
        let mut first = None;
        let mut idle_looks = 0;
        loop {
            let subs = self.req.dynamic_config().number_of_subscribers();
            let pubs = self.rep.dynamic_config().number_of_publishers();
            if subs >= 1 && pubs >= 1 {
                return Ok(true);
            }
            if interrupt.is_some_and(|f| f.load(Ordering::Relaxed)) {
                return Ok(false);
            }
            if let Some(status) = self.exited() {
                return Err(LinkError::Exited {
                    role: self.role,
                    pid: self.pid,
                    step: 0,
                    status,
                });
            }
            let elapsed = started.elapsed();
            if elapsed > look_at {
                // Not connected yet: never "computing", never polling.
                let (verdict, look) = judge(self.pid, false, 0, previous, &mut idle_looks);
                previous = look;
                first = first.or(look);
                let limit = match verdict {
                    Liveness::Hung | Liveness::Idle => Some(startup),
                    Liveness::Running if past_ceiling(self.ceiling, elapsed, first, look) => {
                        Some(self.ceiling)
                    }
                    Liveness::Running => None,
                };
                if let Some(limit) = limit {
                    return Err(LinkError::Timeout {
                        role: self.role,
                        pid: self.pid,
                        step: 0,
                        deadline_ms: limit.as_millis() as u64,
                    });
                }
                self.counts.starved_waits += 1;
                look_at = elapsed + LOOK_EVERY;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    /// Takes every reply waiting and keeps in `found` the one sample for `step`; any other
    /// sample is an error. The answer to a repeated request ([`Resent`]) that comes besides
    /// the one taken is discarded and counted; any other extra, stale or early sample stays an
    /// error.
    fn drain(&mut self, step: u64, kind: Kind, found: &mut Option<O>) -> Result<(), LinkError> {
        let role = self.role;
        loop {
            let sample = self
                .subscriber
                .receive()
                .map_err(|e| LinkError::Transport {
                    role,
                    what: format!("receive: {e:?}"),
                })?;
            let Some(sample) = sample else { return Ok(()) };
            let value: O = *sample;
            drop(sample);
            let h = value.header();
            if self.resent.is_some_and(|r| r.answers_repeat(h)) {
                // The answer to a repeat is taken only as the first answer to the pending
                // request (the original request or reply was lost); any other is an expected
                // extra.
                let pending = Header::new(step, kind);
                let first_for_pending = found.is_none()
                    && crate::msg::exchange_key(h) == crate::msg::exchange_key(&pending);
                if !first_for_pending {
                    self.counts.lost_samples.repeats_discarded += 1;
                    continue;
                }
            }
            let got = h.step;
            if self.early.is_none()
                && self
                    .ahead
                    .is_some_and(|a| a.header().step == got && a.header().kind == h.kind)
            {
                // The request sent ahead is answered already: kept for its own receive.
                self.early = Some(value);
                continue;
            }
            if got < step {
                return Err(LinkError::Stale {
                    role,
                    expected: step,
                    got,
                });
            }
            if got > step {
                return Err(LinkError::OutOfOrder {
                    role,
                    expected: step,
                    got,
                });
            }
            if found.is_some() {
                return Err(LinkError::Duplicate { role, step });
            }
            *found = Some(value);
        }
    }

    /// A look at a participant whose reply is past the deadline: a reply that came since the
    /// last drain is taken (`Ok(true)`); else a hung participant, or one past the ceiling, is
    /// an error, one that polls without taking the request gets it once more, and a running
    /// one (starved by other load, or computing) is waited for, the wait counted.
    fn look_at_deadline(
        &mut self,
        key: u64,
        step: u64,
        kind: Kind,
        elapsed: Duration,
        looks: &mut Looks,
        found: &mut Option<O>,
    ) -> Result<bool, LinkError> {
        self.drain(step, kind, found)?;
        if found.is_some() {
            return Ok(true);
        }
        let w = self.status.words();
        let computing = w.taken.load(Ordering::Acquire) == key + 1
            && w.answered.load(Ordering::Acquire) != key + 1;
        let polls = w.empty_polls.load(Ordering::Acquire);
        let (verdict, look) = judge(self.pid, computing, polls, looks.previous, &mut looks.idle);
        looks.previous = look;
        looks.first = looks.first.or(look);
        let limit = match verdict {
            Liveness::Hung => Some(self.deadline),
            _ if past_ceiling(self.ceiling, elapsed, looks.first, look) => Some(self.ceiling),
            Liveness::Idle => {
                // Polling, yet the request is not taken: send it once more.
                self.resend(key)?;
                None
            }
            Liveness::Running => None,
        };
        if let Some(limit) = limit {
            return Err(LinkError::Timeout {
                role: self.role,
                pid: self.pid,
                step,
                deadline_ms: limit.as_millis() as u64,
            });
        }
        self.counts.starved_waits += 1;
        Ok(false)
    }

    /// Looks into an exchange that has been silent for a while: the participant's status says
    /// whether it published the reply (then, if the reply is not here, the reply was lost) or
    /// keeps polling without having taken the request (the request was lost); either way the
    /// request is re-sent and the loss counted. Returns whether a reply came meanwhile.
    fn look_into_silence(
        &mut self,
        key: u64,
        step: u64,
        kind: Kind,
        silence: &mut Silence,
        found: &mut Option<O>,
    ) -> Result<bool, LinkError> {
        let w = self.status.words();
        let answered = w.answered.load(Ordering::Acquire);
        let taken = w.taken.load(Ordering::Acquire);
        let polls = w.empty_polls.load(Ordering::Acquire);
        let repeats = w.repeats.load(Ordering::Acquire);
        if taken > key + 1 {
            // Past this request (it took the one sent ahead), so its reply was published
            // first: the next drain takes it. Nothing is re-sent.
            return Ok(false);
        }
        if answered == key + 1 {
            // Published before the load above, so a drain now finds it unless it was lost.
            self.drain(step, kind, found)?;
            if found.is_some() {
                return Ok(true);
            }
            if silence.repeats.is_some_and(|r| repeats <= r) {
                // The repeat sent last is not answered yet.
                return Ok(false);
            }
            self.counts.lost_samples.lost_replies += 1;
            silence.repeats = Some(repeats);
            self.resend(key)?;
        } else if taken != key + 1 {
            match silence.polls {
                Some(p) if polls >= p + 2 => {
                    // Two polls since the last look, none found the request.
                    self.counts.lost_samples.lost_requests += 1;
                    silence.polls = None;
                    self.resend(key)?;
                }
                Some(_) => {}
                None => silence.polls = Some(polls),
            }
        }
        Ok(false)
    }

    /// Sends the pending request again with the next attempt; the participant answers it from
    /// its last reply if it had answered it already.
    fn resend(&mut self, key: u64) -> Result<(), LinkError> {
        let Some(mut req) = self.last_request else {
            return Ok(());
        };
        let h = req.header_mut();
        h.attempt = h.attempt.saturating_add(1);
        self.resent = Some(Resent {
            key,
            attempts: h.attempt,
        });
        self.last_request = Some(req);
        self.counts.lost_samples.resends += 1;
        // A repeat (attempt 1 or more) is never in the drop plan.
        self.publish_request(req)
    }
}

/// What [`IpcEndpoint::receive`] keeps between two looks into a silent exchange.
#[derive(Debug, Default)]
struct Silence {
    /// The participant's empty polls at the previous look (a request not taken is lost once
    /// it has polled twice more since).
    polls: Option<u64>,
    /// Repeats the participant had answered when a lost reply's request was last re-sent
    /// (re-sent again only once it has answered that one too).
    repeats: Option<u64>,
}

impl<I: Message, O: Message> Endpoint<I, O> for IpcEndpoint<I, O> {
    fn role(&self) -> Role {
        self.role
    }
    fn pid(&self) -> u32 {
        self.pid
    }
    fn send(&mut self, req: &I) -> Result<(), LinkError> {
        let mut req = *req;
        req.header_mut().attempt = 0;
        self.last_request = Some(req);
        self.publish_request(req)
    }
    fn send_ahead(&mut self, req: &I) -> Result<bool, LinkError> {
        // Not with samples dropped on purpose: a re-sent request must be the last one sent.
        if self.ahead.is_some() || self.exit.is_some() || !self.drops.is_empty() {
            return Ok(false);
        }
        let mut req = *req;
        req.header_mut().attempt = 0;
        self.ahead = Some(req);
        self.publish_request(req)?;
        Ok(true)
    }
    fn receive(&mut self, step: u64, kind: Kind) -> Result<O, LinkError> {
        let mut backoff = Backoff::with_spin(self.wait, self.spin_polls);
        let mut found = None;
        let key = exchange_key(&Header::new(step, kind)).unwrap_or(0);
        let mut check_at = RESEND_AFTER;
        let mut silence = Silence::default();
        let mut look_at = self.deadline;
        let mut looks = Looks::default();
        if let Some(reply) = self.early.take() {
            // The reply to a request sent ahead, taken while the one before was waited for.
            check_reply::<I, O>(self.role, &reply, step, kind)?;
            self.took(reply.header());
            return Ok(reply);
        }
        if let Some(r) = &self.exit {
            // Already known to be gone (a kill fault reaps at once).
            return Err(LinkError::Exited {
                role: self.role,
                pid: self.pid,
                step,
                status: r.status.clone(),
            });
        }
        loop {
            self.drain(step, kind, &mut found)?;
            if let Some(reply) = found {
                check_reply::<I, O>(self.role, &reply, step, kind)?;
                self.took(reply.header());
                return Ok(reply);
            }
            // A dead process is noticed within ~1k polls. After a short silence the status
            // tells whether the request or its reply was lost (then it is re-sent). At the
            // deadline a stopped, idle or sleeping process is declared stalled; one that runs
            // (starved by other load, or computing) is waited for, looked at again every
            // 100 ms, until it has used the ceiling in CPU time (`past_ceiling`).
            let elapsed = backoff.elapsed();
            if backoff.polls() % 1024 == 1023 || elapsed > check_at {
                if let Some(status) = self.exited() {
                    return Err(LinkError::Exited {
                        role: self.role,
                        pid: self.pid,
                        step,
                        status,
                    });
                }
                if elapsed > check_at {
                    check_at = elapsed + RESEND_AFTER;
                    if self.look_into_silence(key, step, kind, &mut silence, &mut found)? {
                        continue;
                    }
                }
                if elapsed > look_at {
                    if self.look_at_deadline(key, step, kind, elapsed, &mut looks, &mut found)? {
                        continue;
                    }
                    look_at = elapsed + LOOK_EVERY;
                }
            }
            backoff.pause();
        }
    }
    fn take_arrived(&mut self, out: &mut Vec<O>) -> Result<(), LinkError> {
        let before = out.len();
        crate::ipc::free::take_arrived(self.role, &self.subscriber, out)?;
        if let Some(newest) = out[before..].iter().map(|o| o.header().step).max() {
            self.free_pending = self.free_pending.max(newest + 1);
        }
        if out.len() == before {
            if let Some(status) = self.exited() {
                return Err(LinkError::Exited {
                    role: self.role,
                    pid: self.pid,
                    step: self.free_pending,
                    status,
                });
            }
        }
        Ok(())
    }
    fn counts(&self) -> ExchangeCounts {
        let mut c = self.counts;
        c.lost_samples.repeats_answered = self.status.words().repeats.load(Ordering::Relaxed);
        c.lost_samples.undelivered_replies =
            self.status.words().undelivered.load(Ordering::Relaxed);
        let cue = &self.status.words().cue;
        c.cue = crate::endpoint::CueCounts {
            given: cue.given.load(Ordering::Relaxed),
            cued_waits: cue.cued_waits.load(Ordering::Relaxed),
            steps_aside: cue.steps_aside.load(Ordering::Relaxed),
        };
        c
    }
    fn set_shares_cpu(&mut self, shared: bool) {
        self.spin_polls = if shared { 0 } else { crate::wait::SPIN_POLLS };
    }
    fn set_cue_next(&mut self, next: Option<(Role, u64)>) {
        let word = crate::ipc::supervise::encode_next(next);
        self.status.words().cue.next.store(word, Ordering::Release);
    }
    fn await_pending(&mut self) {
        // Bounded well below the deadline: a participant that does not answer soon is left
        // to `receive`, which tells a dead, stalled or starved one apart.
        let started = Instant::now();
        let limit = self.deadline.min(crate::wait::YIELD_FOR);
        while self.exit.is_none()
            && !self.subscriber.has_samples().unwrap_or(true)
            && started.elapsed() < limit
        {
            std::thread::yield_now();
        }
    }
    fn inject(&mut self, fault: ProcessFault) {
        let pid = self.pid as libc::pid_t;
        match fault {
            ProcessFault::Kill => {
                // SAFETY: a signal to our own child, which we have not reaped yet.
                unsafe { libc::kill(pid, libc::SIGKILL) };
                // Reap it now, so that the next exchange finds it gone, deterministically.
                let until = Instant::now() + Duration::from_secs(2);
                while self.exited().is_none() && Instant::now() < until {
                    std::thread::sleep(Duration::from_micros(200));
                }
            }
            ProcessFault::Stall(d) => {
                // SAFETY: as above; the thread resumes it after `d` (a no-op if it died).
                unsafe { libc::kill(pid, libc::SIGSTOP) };
                std::thread::spawn(move || {
                    std::thread::sleep(d);
                    unsafe { libc::kill(pid, libc::SIGCONT) };
                });
            }
        }
    }
    fn shutdown(&mut self) -> ExitReport {
        if let Some(report) = &self.exit {
            return report.clone();
        }
        let Some(mut child) = self.child.take() else {
            return ExitReport {
                status: "unknown".into(),
                cpu_s: None,
            };
        };
        // Ask politely (again every 50 ms, should a Stop be lost), then insist: a stopped or
        // hung participant is killed.
        let stop = |attempt: u32| {
            let mut m = I::default();
            *m.header_mut() = Header::new(u64::MAX, Kind::Stop);
            m.header_mut().attempt = attempt;
            m
        };
        let _ = crate::ipc::publish(&self.publisher, stop(0));
        let started = Instant::now();
        let mut report = None;
        let mut attempt = 0;
        while report.is_none() && started.elapsed() < Duration::from_millis(500) {
            report = try_reap(self.pid, false);
            if report.is_none() {
                // A free-running participant held back by a full reply buffer reads its
                // Stop only once it has room again: its last replies are let through.
                while let Ok(Some(_)) = self.subscriber.receive() {}
                std::thread::sleep(Duration::from_millis(1));
                let due = started.elapsed().as_millis() as u32 / 50;
                if due > attempt {
                    attempt = due;
                    let _ = crate::ipc::publish(&self.publisher, stop(attempt));
                }
            }
        }
        let report = report.unwrap_or_else(|| {
            // SIGKILL also ends a stopped (SIGSTOP) or hung process.
            let _ = child.kill();
            try_reap(self.pid, true).unwrap_or(ExitReport {
                status: "unknown".into(),
                cpu_s: None,
            })
        });
        self.exit = Some(report.clone());
        report
    }
}

impl<I: Message, O: Message> Drop for IpcEndpoint<I, O> {
    fn drop(&mut self) {
        if self.child.is_some() {
            self.shutdown();
        }
    }
}
