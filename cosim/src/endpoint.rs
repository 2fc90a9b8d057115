//! The orchestrator's view of one participant, the same for every transport.

use crate::msg::{Kind, Message, FLAG_CRASH, FLAG_REJECTED, PROTOCOL_VERSION};
use crate::participant::{Participant, Role, Served};

/// Why an exchange with a participant failed. Every variant names the participant and step.
#[derive(Debug, Clone, thiserror::Error)]
pub enum LinkError {
    /// No reply within the deadline.
    #[error("participant {role} (pid {pid}) did not answer step {step} within {deadline_ms} ms")]
    Timeout {
        role: Role,
        pid: u32,
        step: u64,
        deadline_ms: u64,
    },
    /// The participant's process ended.
    #[error("participant {role} (pid {pid}) exited ({status}) while step {step} was pending")]
    Exited {
        role: Role,
        pid: u32,
        step: u64,
        status: String,
    },
    /// A reply for an older step arrived (a stale or duplicated sample).
    #[error("participant {role}: stale sample for step {got} while waiting for step {expected}")]
    Stale { role: Role, expected: u64, got: u64 },
    /// A reply for a later step arrived (out of order).
    #[error(
        "participant {role}: sample for step {got} arrived out of order, expected step {expected}"
    )]
    OutOfOrder { role: Role, expected: u64, got: u64 },
    /// More than one reply for the same step.
    #[error("participant {role}: duplicated sample for step {step}")]
    Duplicate { role: Role, step: u64 },
    /// A reply of the wrong kind or protocol version.
    #[error("participant {role}: malformed sample for step {step}: {what}")]
    Malformed { role: Role, step: u64, what: String },
    /// A NaN or infinite value in a participant's reply.
    #[error("participant {role}: non-finite value in field `{field}` of {sample} at step {step}")]
    NonFinite {
        role: Role,
        step: u64,
        sample: &'static str,
        field: &'static str,
    },
    /// The participant rejected its request: a NaN or infinite input value.
    #[error(
        "participant {role} rejected step {step}: non-finite value in field `{field}` of {sample}"
    )]
    BadInput {
        role: Role,
        step: u64,
        sample: &'static str,
        field: &'static str,
    },
    /// The transport itself failed.
    #[error("transport to participant {role} failed: {what}")]
    Transport { role: Role, what: String },
    /// A participant on another host failed an exchange: it left the run (its connection
    /// closed, or its link went silent past the lease) or did not answer within the deadline.
    #[error("participant {role} on host {host} {what}, at step {step}")]
    Remote {
        role: Role,
        host: String,
        step: u64,
        /// One word for the event log, as [`LinkError::cause`] gives it.
        cause: &'static str,
        what: String,
    },
}

impl LinkError {
    /// The participant concerned.
    pub fn role(&self) -> Role {
        match self {
            LinkError::Timeout { role, .. }
            | LinkError::Exited { role, .. }
            | LinkError::Stale { role, .. }
            | LinkError::OutOfOrder { role, .. }
            | LinkError::Duplicate { role, .. }
            | LinkError::Malformed { role, .. }
            | LinkError::NonFinite { role, .. }
            | LinkError::BadInput { role, .. }
            | LinkError::Transport { role, .. }
            | LinkError::Remote { role, .. } => *role,
        }
    }
    /// One word for the cause, free of pids and wall-clock numbers (for the event log).
    pub fn cause(&self) -> &'static str {
        match self {
            LinkError::Timeout { .. } => "stalled",
            LinkError::Exited { .. } => "exited",
            LinkError::Stale { .. } => "stale-sample",
            LinkError::OutOfOrder { .. } => "out-of-order",
            LinkError::Duplicate { .. } => "duplicate",
            LinkError::Malformed { .. } => "malformed",
            LinkError::NonFinite { .. } => "non-finite-output",
            LinkError::BadInput { .. } => "non-finite-input",
            LinkError::Transport { .. } => "transport",
            LinkError::Remote { cause, .. } => cause,
        }
    }
}

/// Checks a reply (to a request of type `I`) against the request it answers.
pub fn check_reply<I: Message, O: Message>(
    role: Role,
    reply: &O,
    step: u64,
    kind: Kind,
) -> Result<(), LinkError> {
    let h = reply.header();
    if h.version != PROTOCOL_VERSION {
        return Err(LinkError::Malformed {
            role,
            step,
            what: format!(
                "protocol version {} (expected {PROTOCOL_VERSION})",
                h.version
            ),
        });
    }
    let size = core::mem::size_of::<O>() as u32;
    if h.size != size {
        return Err(LinkError::Malformed {
            role,
            step,
            what: format!("{} of {} bytes (expected {size})", O::NAME, h.size),
        });
    }
    if h.step < step {
        return Err(LinkError::Stale {
            role,
            expected: step,
            got: h.step,
        });
    }
    if h.step > step {
        return Err(LinkError::OutOfOrder {
            role,
            expected: step,
            got: h.step,
        });
    }
    if h.kind != kind as u32 {
        return Err(LinkError::Malformed {
            role,
            step,
            what: format!("kind {} (expected {kind:?})", h.kind),
        });
    }
    if h.flags & FLAG_REJECTED != 0 {
        return Err(LinkError::BadInput {
            role,
            step,
            sample: I::NAME,
            field: field_name::<I>(h.field),
        });
    }
    if let Some(i) = reply.first_non_finite() {
        return Err(LinkError::NonFinite {
            role,
            step,
            sample: O::NAME,
            field: O::FIELDS[i],
        });
    }
    Ok(())
}

/// Name of request field `1 + index` as carried in `Header::field`.
pub fn field_name<I: Message>(field: u32) -> &'static str {
    (field as usize)
        .checked_sub(1)
        .and_then(|i| I::FIELDS.get(i))
        .copied()
        .unwrap_or("?")
}

/// How a participant ended, as reported after the run.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ExitReport {
    /// Exit status in words ("exit code 0", "signal 9", "in-process").
    pub status: String,
    /// CPU time the process used, user + system (s); `None` in-process.
    pub cpu_s: Option<f64>,
}

/// What the exchanges with one participant cost beyond the normal path: waits for a starved
/// participant and the repair of lost samples. Wall-clock facts (they differ between repeats
/// of a run); they never change a value.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ExchangeCounts {
    /// Looks past the deadline at a participant that was running (starved of CPU by other
    /// load, or computing) and was waited for.
    pub starved_waits: u64,
    /// Requests re-sent and repeats discarded: what lost samples cost.
    pub lost_samples: LostSamples,
    /// How the participant handed its CPU over among those it shares it with.
    pub cue: CueCounts,
}

/// The cue among participants that share a CPU (docs/architecture.md, "The cue"), as one
/// participant counted it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CueCounts {
    /// Cues it gave the participant asked after it, once it had answered.
    pub given: u64,
    /// Waits in which it was cued and polled without yielding.
    pub cued_waits: u64,
    /// Times it found itself in front of a cued participant and stepped aside.
    pub steps_aside: u64,
}

impl CueCounts {
    /// No cue given, taken or stepped aside for: the participant was not cued.
    pub fn is_zero(&self) -> bool {
        *self == CueCounts::default()
    }
}

/// How lost samples were repaired for one participant (docs/architecture.md, "Lost samples").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LostSamples {
    /// Requests re-sent because their exchange went silent.
    pub resends: u64,
    /// Of those, requests found lost: the participant kept polling and never took it.
    pub lost_requests: u64,
    /// Of those, replies found lost: the participant had published it, it never came.
    pub lost_replies: u64,
    /// Repeated requests the participant answered from its last reply (the model not stepped).
    pub repeats_answered: u64,
    /// Answers to repeated requests that came besides the one taken, discarded.
    pub repeats_discarded: u64,
    /// Requests whose sending reached no subscriber and was sent again at once.
    pub undelivered_requests: u64,
    /// Replies whose sending reached no subscriber and was sent again at once.
    pub undelivered_replies: u64,
}

/// A process fault injected on purpose (scheduled in the scenario).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProcessFault {
    /// The process is killed (SIGKILL).
    Kill,
    /// The process is stopped for this long, then continues (SIGSTOP, SIGCONT).
    Stall(std::time::Duration),
}

/// The orchestrator's handle on one participant.
pub trait Endpoint<I: Message, O: Message> {
    /// Role of the participant.
    fn role(&self) -> Role;
    /// Process id (the orchestrator's own pid in-process).
    fn pid(&self) -> u32;
    /// Sends a request; its header says which step and kind (version, size and send time are
    /// stamped here).
    fn send(&mut self, req: &I) -> Result<(), LinkError>;
    /// Sends the participant's next step request while its current one is still to be answered,
    /// where the transport queues it behind that one: the participant takes it as soon as it
    /// has answered, without waiting for the orchestrator. `Ok(false)`: not sent (the default;
    /// in one process a request is answered as it is sent), to be sent with
    /// [`Endpoint::send`] once the current reply is in. Changes when a participant computes,
    /// never what.
    fn send_ahead(&mut self, _req: &I) -> Result<bool, LinkError> {
        Ok(false)
    }
    /// Waits for the reply to the request for `step` of `kind` and checks it.
    fn receive(&mut self, step: u64, kind: Kind) -> Result<O, LinkError>;
    /// Injects a process fault.
    fn inject(&mut self, fault: ProcessFault);
    /// Asks the participant to end, waits for it (bounded), reports how it ended.
    fn shutdown(&mut self) -> ExitReport;
    /// Free running: appends every reply that has arrived, in arrival order, without waiting
    /// and without the lock-step's step checks (the caller checks the order). A participant
    /// whose process has ended is an error. Only the IPC transport runs free; in-process
    /// participants have no clock of their own.
    fn take_arrived(&mut self, _out: &mut Vec<O>) -> Result<(), LinkError> {
        Err(LinkError::Transport {
            role: self.role(),
            what: "no free-running mode in one process".into(),
        })
    }
    /// Starved waits, re-sent requests and discarded repeats so far ([`ExchangeCounts`]).
    fn counts(&self) -> ExchangeCounts {
        ExchangeCounts::default()
    }
    /// Tells the endpoint whether its participant now runs on the orchestrator's CPU. A
    /// waiter that shares a CPU with the process it waits for yields at once, since spinning
    /// would only delay that process. Changes how the orchestrator waits, never what it gets.
    fn set_shares_cpu(&mut self, _shared: bool) {}
    /// Names, before the next request is sent, the participant asked after this one and for
    /// which step, for this one to cue once it has answered (`cosim::ipc::supervise::CueWords`);
    /// `None`: nobody. Changes which process runs, never what it computes.
    fn set_cue_next(&mut self, _next: Option<(Role, u64)>) {}
    /// Waits (yielding the CPU) until a reply is pending, the participant is gone, or the
    /// deadline or 2 ms have passed, without taking the reply. The orchestrator lets
    /// participants that share its CPU answer first while another computes elsewhere;
    /// [`Endpoint::receive`] then takes and checks the replies in the algorithm's order.
    fn await_pending(&mut self) {}
}

/// In-process transport: the model runs inside the orchestrator's process, on `send`.
///
/// Process faults are emulated so that a scenario gives the same rows on both transports: a
/// kill or crash makes the endpoint report the participant gone at the same step; a stall
/// sleeps in `send` and is a timeout when it lasts past the deadline.
pub struct InProcess<P: Participant> {
    served: Served<P>,
    pending: Option<P::Output>,
    gone: Option<String>,
    stall: Option<std::time::Duration>,
    deadline: std::time::Duration,
}

impl<P: Participant> InProcess<P> {
    /// Wraps a model (stall deadline 500 ms).
    pub fn new(model: P) -> Self {
        InProcess {
            served: Served::new(model),
            pending: None,
            gone: None,
            stall: None,
            deadline: std::time::Duration::from_millis(500),
        }
    }
    /// Sets the stall deadline.
    pub fn with_deadline(mut self, deadline: std::time::Duration) -> Self {
        self.deadline = deadline;
        self
    }
    /// Whether requests and replies carry wall-clock times ([`Served::set_timed`]).
    pub fn timed(mut self, timed: bool) -> Self {
        self.served.set_timed(timed);
        self
    }
}

impl<P: Participant> Endpoint<P::Input, P::Output> for InProcess<P> {
    fn role(&self) -> Role {
        P::ROLE
    }
    fn pid(&self) -> u32 {
        std::process::id()
    }
    fn send(&mut self, req: &P::Input) -> Result<(), LinkError> {
        if self.pending.is_some() {
            let step = req.header().step;
            return Err(LinkError::Duplicate {
                role: P::ROLE,
                step,
            });
        }
        if self.gone.is_some() {
            return Ok(());
        }
        if req.header().flags & FLAG_CRASH != 0 {
            self.gone = Some("crashed (in-process emulation of an abort)".into());
            return Ok(());
        }
        let mut req = *req;
        req.stamp_at(self.served.clock());
        if let Some(d) = self.stall {
            std::thread::sleep(d.min(self.deadline + std::time::Duration::from_millis(1)));
        }
        let reply = self.served.answer(&req);
        match self.served.model.failure() {
            Some(why) => self.gone = Some(format!("failed: {why}")),
            None => self.pending = Some(reply),
        }
        Ok(())
    }
    fn receive(&mut self, step: u64, kind: Kind) -> Result<P::Output, LinkError> {
        if let Some(status) = &self.gone {
            return Err(LinkError::Exited {
                role: P::ROLE,
                pid: std::process::id(),
                step,
                status: status.clone(),
            });
        }
        if let Some(d) = self.stall.take() {
            if d > self.deadline {
                self.pending = None;
                self.gone = Some("stalled (in-process emulation)".into());
                return Err(LinkError::Timeout {
                    role: P::ROLE,
                    pid: std::process::id(),
                    step,
                    deadline_ms: self.deadline.as_millis() as u64,
                });
            }
        }
        let Some(reply) = self.pending.take() else {
            return Err(LinkError::Transport {
                role: P::ROLE,
                what: format!("no request pending for step {step}"),
            });
        };
        check_reply::<P::Input, P::Output>(P::ROLE, &reply, step, kind)?;
        Ok(reply)
    }
    fn inject(&mut self, fault: ProcessFault) {
        match fault {
            ProcessFault::Kill => self.gone = Some("killed (in-process emulation)".into()),
            ProcessFault::Stall(d) => self.stall = Some(d),
        }
    }
    fn shutdown(&mut self) -> ExitReport {
        ExitReport {
            status: self.gone.clone().unwrap_or_else(|| "in-process".into()),
            cpu_s: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{FromController, Header, ToController};

    /// A participant that echoes the measurement, to exercise the checks.
    struct Echo;
    impl Participant for Echo {
        type Input = ToController;
        type Output = FromController;
        const ROLE: Role = Role::Controller;
        fn initial_output(&mut self) -> FromController {
            FromController::default()
        }
        fn step(&mut self, i: &ToController) -> FromController {
            FromController {
                theta_v_hat: i.theta_v_meas,
                ..Default::default()
            }
        }
    }

    fn reply(step: u64, kind: Kind) -> FromController {
        let mut r = FromController {
            header: Header::new(step, kind),
            ..Default::default()
        };
        r.stamp();
        r
    }

    #[test]
    fn replies_for_other_steps_kinds_or_versions_are_errors() {
        let r = Role::Controller;
        assert!(check_reply::<ToController, FromController>(
            r,
            &reply(7, Kind::Step),
            7,
            Kind::Step
        )
        .is_ok());
        assert!(matches!(
            check_reply::<ToController, FromController>(r, &reply(6, Kind::Step), 7, Kind::Step),
            Err(LinkError::Stale {
                expected: 7,
                got: 6,
                ..
            })
        ));
        assert!(matches!(
            check_reply::<ToController, FromController>(r, &reply(8, Kind::Step), 7, Kind::Step),
            Err(LinkError::OutOfOrder {
                expected: 7,
                got: 8,
                ..
            })
        ));
        assert!(matches!(
            check_reply::<ToController, FromController>(r, &reply(7, Kind::Init), 7, Kind::Step),
            Err(LinkError::Malformed { .. })
        ));
        let mut old = reply(7, Kind::Step);
        old.header.version = 0;
        let e = check_reply::<ToController, FromController>(r, &old, 7, Kind::Step).unwrap_err();
        assert!(e.to_string().contains("protocol version 0"), "{e}");
        let mut nan = reply(7, Kind::Step);
        nan.delta_a_cmd = f64::NAN;
        let e = check_reply::<ToController, FromController>(r, &nan, 7, Kind::Step).unwrap_err();
        assert_eq!(e.to_string(), "participant controller: non-finite value in field `delta_a_cmd` of from_controller at step 7");
    }

    #[test]
    fn in_process_endpoint_checks_like_ipc_and_rejects_a_second_request() {
        let mut ep = InProcess::new(Echo);
        let req = ToController {
            header: Header::new(3, Kind::Step),
            theta_v_meas: 0.25,
            ..Default::default()
        };
        ep.send(&req).unwrap();
        assert!(matches!(
            ep.send(&req),
            Err(LinkError::Duplicate { step: 3, .. })
        ));
        assert!(matches!(
            ep.receive(4, Kind::Step),
            Err(LinkError::Stale {
                expected: 4,
                got: 3,
                ..
            })
        ));
        ep.send(&req).unwrap();
        assert_eq!(ep.receive(3, Kind::Step).unwrap().theta_v_hat, 0.25);
        assert!(
            matches!(ep.receive(3, Kind::Step), Err(LinkError::Transport { .. })),
            "no reply without a request"
        );
    }

    #[test]
    fn an_untimed_endpoint_answers_alike_and_stamps_no_time() {
        let req = ToController {
            header: Header::new(5, Kind::Step),
            theta_v_meas: -0.125,
            ..Default::default()
        };
        let mut timed = InProcess::new(Echo);
        let mut untimed = InProcess::new(Echo).timed(false);
        timed.send(&req).unwrap();
        untimed.send(&req).unwrap();
        let (a, b) = (
            timed.receive(5, Kind::Step).unwrap(),
            untimed.receive(5, Kind::Step).unwrap(),
        );
        assert_eq!(a.theta_v_hat, b.theta_v_hat);
        let (ha, hb) = (a.header, b.header);
        assert!(ha.recv_ns > 0 && ha.sent_ns >= ha.recv_ns, "timed: {ha:?}");
        assert_eq!((hb.recv_ns, hb.compute_ns, hb.sent_ns), (0, 0, 0));
        assert_eq!((hb.step, hb.kind, hb.flags), (ha.step, ha.kind, ha.flags));
    }
}
