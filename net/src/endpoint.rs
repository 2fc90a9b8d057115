//! One remote participant, as the orchestrator drives it: the same [`Endpoint`] as on one
//! host. Replies are checked as every transport checks them; their wall-clock stamps are moved
//! onto the orchestrator's clock with the offset measured at joining.

use std::marker::PhantomData;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use zenoh::Wait;

use cosim::endpoint::{check_reply, ExitReport, LinkError, ProcessFault};
use cosim::msg::{Kind, Message};
use cosim::{Endpoint, Role};

use crate::hub::{idx, Joined, Ports, Shared};

/// The longest the endpoint blocks on its reply channel before it looks at the participant's
/// liveliness again.
const LOOK: Duration = Duration::from_millis(20);

/// How long a stopped participant has to leave the run before it is reported as still there.
const LEAVE: Duration = Duration::from_millis(1000);

/// The orchestrator's handle on a participant on another host.
pub struct NetEndpoint<I: Message, O: Message> {
    joined: Joined,
    ports: Ports,
    shared: Arc<Shared>,
    /// Kept open for as long as the endpoint is.
    _session: zenoh::Session,
    deadline: Duration,
    gone: Option<String>,
    /// The step of the newest reply taken (for naming a free run's failure).
    last_step: u64,
    /// The relay number and send instant of the requests sent lately, newest last: a reply
    /// is never stamped as read before the request it answers was sent.
    sent: std::collections::VecDeque<(u64, u64)>,
    _samples: PhantomData<(I, O)>,
}

impl<I: Message, O: Message> NetEndpoint<I, O> {
    pub(crate) fn new(
        joined: Joined,
        ports: Ports,
        shared: Arc<Shared>,
        session: zenoh::Session,
        deadline: Duration,
    ) -> Self {
        NetEndpoint {
            joined,
            ports,
            shared,
            _session: session,
            deadline,
            gone: None,
            last_step: 0,
            sent: std::collections::VecDeque::new(),
            _samples: PhantomData,
        }
    }

    /// The participant as it joined: host, pid, clock offset.
    pub fn joined(&self) -> &Joined {
        &self.joined
    }

    fn role_(&self) -> Role {
        self.joined.role
    }

    fn alive(&self) -> bool {
        self.shared.alive[idx(self.role_())].load(Ordering::Acquire)
    }

    fn transport(&self, what: String) -> LinkError {
        LinkError::Transport {
            role: self.role_(),
            what,
        }
    }

    /// The participant left the run (its session closed or its link's lease ran out).
    fn left(&self, step: u64) -> LinkError {
        let note = self
            .shared
            .note(self.role_())
            .map(|n| format!(": {n}"))
            .unwrap_or_default();
        LinkError::Remote {
            role: self.role_(),
            host: self.joined.host.clone(),
            step,
            cause: "exited",
            what: format!(
                "left the run (its connection closed, or went silent past the lease){note}"
            ),
        }
    }

    /// Moves the participant's clock readings onto the orchestrator's clock: by the offset
    /// measured at joining, never before the request read was sent and never after the reply
    /// `arrived` here (the offset is known to within half a round trip; causality is known
    /// exactly, and a participant here reads a remote output only after it arrived).
    fn stamps_to_local(&self, h: &mut cosim::msg::Header, arrived: u64) {
        let sent_then = self
            .sent
            .iter()
            .rev()
            .find(|(relay, _)| *relay == h.relay)
            .map_or(0, |&(_, t)| t);
        let arrived = arrived.max(sent_then);
        if h.recv_ns != 0 {
            h.recv_ns = self.to_local(h.recv_ns).clamp(sent_then, arrived);
        }
        if h.sent_ns != 0 {
            h.sent_ns = self.to_local(h.sent_ns).clamp(h.recv_ns, arrived);
        }
    }

    fn to_local(&self, ns: u64) -> u64 {
        if ns == 0 {
            return 0;
        }
        (ns as i128 + self.joined.clock_offset_ns as i128).max(1) as u64
    }

    fn decode(&self, sample: &zenoh::sample::Sample, step: u64) -> Result<O, LinkError> {
        let arrived = cosim::msg::now_ns();
        let bytes = sample.payload().to_bytes();
        let mut o = O::from_wire(&bytes).map_err(|e| LinkError::Malformed {
            role: self.role_(),
            step,
            what: e.to_string(),
        })?;
        self.stamps_to_local(o.header_mut(), arrived);
        Ok(o)
    }
}

impl<I: Message, O: Message> Endpoint<I, O> for NetEndpoint<I, O> {
    fn role(&self) -> Role {
        self.role_()
    }

    fn pid(&self) -> u32 {
        self.joined.pid
    }

    fn send(&mut self, req: &I) -> Result<(), LinkError> {
        let mut r = *req;
        r.stamp();
        if self.sent.len() == 4096 {
            self.sent.pop_front();
        }
        self.sent.push_back((r.header().relay, r.header().sent_ns));
        self.shared
            .step
            .store(r.header().step, std::sync::atomic::Ordering::Relaxed);
        if crate::watch::tls_refusals_pending() {
            self.shared.collect_tls_refusals();
        }
        self.ports
            .request
            .put(r.to_wire())
            .wait()
            .map_err(|e| self.transport(format!("sending step {}: {e}", r.header().step)))
    }

    fn receive(&mut self, step: u64, kind: Kind) -> Result<O, LinkError> {
        if self.gone.is_some() {
            return Err(self.left(step));
        }
        let end = Instant::now() + self.deadline;
        loop {
            let now = Instant::now();
            let wait = end.saturating_duration_since(now).min(LOOK);
            match self.ports.replies.recv_timeout(wait) {
                Ok(Some(sample)) => {
                    let o = self.decode(&sample, step)?;
                    check_reply::<I, O>(self.role_(), &o, step, kind)?;
                    return Ok(o);
                }
                Ok(None) => {}
                Err(e) => return Err(self.transport(format!("receiving step {step}: {e}"))),
            }
            if !self.alive() {
                // A reply sent just before it left is taken first.
                if let Ok(Some(sample)) = self.ports.replies.try_recv() {
                    let o = self.decode(&sample, step)?;
                    check_reply::<I, O>(self.role_(), &o, step, kind)?;
                    return Ok(o);
                }
                self.gone = Some("left".into());
                return Err(self.left(step));
            }
            if Instant::now() >= end {
                return Err(LinkError::Remote {
                    role: self.role_(),
                    host: self.joined.host.clone(),
                    step,
                    cause: "stalled",
                    what: format!(
                        "did not answer within {} ms (its connection is still open)",
                        self.deadline.as_millis()
                    ),
                });
            }
        }
    }

    fn take_arrived(&mut self, out: &mut Vec<O>) -> Result<(), LinkError> {
        loop {
            match self.ports.replies.try_recv() {
                Ok(Some(sample)) => {
                    let o = self.decode(&sample, self.last_step)?;
                    self.last_step = o.header().step;
                    out.push(o);
                }
                Ok(None) => break,
                Err(e) => return Err(self.transport(format!("receiving: {e}"))),
            }
        }
        if !self.alive() {
            self.gone = Some("left".into());
            return Err(self.left(self.last_step));
        }
        Ok(())
    }

    fn inject(&mut self, fault: ProcessFault) {
        let order = match fault {
            ProcessFault::Kill => "kill".to_string(),
            ProcessFault::Stall(d) => format!("stall {}", d.as_nanos()),
        };
        let _ = self.ports.control.put(order.into_bytes()).wait();
    }

    fn shutdown(&mut self) -> ExitReport {
        let host = self.joined.host.clone();
        if self.alive() {
            let mut stop = I::default();
            *stop.header_mut() = cosim::msg::Header::new(0, Kind::Stop);
            stop.stamp();
            let _ = self.ports.request.put(stop.to_wire()).wait();
            let start = Instant::now();
            while self.alive() && start.elapsed() < LEAVE {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        let note = self.shared.note(self.role_());
        let cpu_s = note
            .as_deref()
            .and_then(|n| n.strip_prefix("stopped cpu_s="))
            .and_then(|v| v.parse().ok());
        let status = if self.alive() {
            format!("still connected from host {host} after Stop")
        } else if cpu_s.is_some() {
            format!("stopped on host {host}")
        } else {
            match note {
                Some(n) => format!("left from host {host}: {n}"),
                None => format!("left from host {host}"),
            }
        };
        ExitReport { status, cpu_s }
    }
}
