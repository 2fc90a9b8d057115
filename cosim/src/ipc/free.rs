//! Free running over iceoryx2 (docs/architecture.md, "Execution modes"): the participant
//! steps on its own timer and the orchestrator relays without waiting.
//!
//! Participant side ([`serve_free`]): step `j` is due at `start + j·period`. The participant
//! sleeps until then (a late step is not waited for: it starts at once, so a participant
//! that fell behind catches up step by step and never skips one), drains every request that
//! has arrived and keeps the newest (or the one it read last, if none came), steps the model
//! with it as step `j·ticks`, and publishes the output at once. The reply's header carries the
//! read instant (`recv_ns`), the compute time including any study busy wait (`compute_ns`),
//! the publish instant (`sent_ns`) and, in `relay`, the relay number of the input read (the
//! starting request's is 0, every later request carries its own).
//! A `Stop` request, or an orchestrator that has gone, ends it; a request flagged as a
//! scheduled crash aborts the process.

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::endpoint::LinkError;
use crate::msg::{now_ns, Kind, Message, FLAG_CRASH};
use crate::participant::{Participant, Role, Served};
use crate::wait::sleep_until_ns;

use super::IpcError;

/// Orchestrator side: appends every reply waiting in `subscriber`, in arrival order.
pub(crate) fn take_arrived<O: Message>(
    role: Role,
    subscriber: &Subscriber<ipc::Service, O, ()>,
    out: &mut Vec<O>,
) -> Result<(), LinkError> {
    loop {
        match subscriber.receive() {
            Ok(Some(s)) => out.push(*s),
            Ok(None) => return Ok(()),
            Err(e) => {
                return Err(LinkError::Transport {
                    role,
                    what: format!("receive: {e:?}"),
                })
            }
        }
    }
}

/// How a participant runs free, from the request that starts it.
#[derive(Debug, Clone, Copy)]
struct Clock {
    start_ns: u64,
    period_ns: u64,
    ticks: u64,
    busy_ns: u64,
}

/// Runs `served` free from the starting request `first` until a `Stop` arrives or the
/// orchestrator (process `parent`) has gone.
pub(crate) fn serve_free<P: Participant>(
    served: &mut Served<P>,
    subscriber: &Subscriber<ipc::Service, P::Input, ()>,
    publisher: &Publisher<ipc::Service, P::Output, ()>,
    first: P::Input,
    parent: libc::pid_t,
) -> Result<(), IpcError> {
    let c = first.header().clock;
    let clock = Clock {
        start_ns: c.start_ns,
        period_ns: c.period_ns.max(1),
        ticks: u64::from(c.period_ticks).max(1),
        busy_ns: u64::from(c.busy_us) * 1000,
    };
    let mut input = first;
    let mut relay = 0u64;
    for j in 0u64.. {
        let due = clock.start_ns + j * clock.period_ns;
        if now_ns() < due {
            sleep_until_ns(due);
            // An interrupted sleep ends early: the step is not started before it is due.
            while now_ns() < due {
                sleep_until_ns(due);
            }
        }
        while let Some(s) = subscriber.receive().map_err(super::iox("receive"))? {
            let got: P::Input = *s;
            match Kind::from_raw(got.header().kind) {
                Some(Kind::Stop) => return Ok(()),
                Some(Kind::Step) => {
                    if got.header().flags & FLAG_CRASH != 0 {
                        // A scheduled `crash` fault: die as a crashing process does.
                        std::process::abort();
                    }
                    input = got;
                    relay = got.header().relay;
                }
                _ => {}
            }
        }
        // SAFETY: getppid has no preconditions.
        if unsafe { libc::getppid() } != parent {
            return Err(IpcError::Iceoryx(format!(
                "{}: orchestrator is gone",
                P::ROLE
            )));
        }
        let reply = served.answer_free(&input, j * clock.ticks, relay, clock.busy_ns);
        if let Some(why) = served.model.failure() {
            return Err(IpcError::Model(why));
        }
        super::publish(publisher, reply).map_err(IpcError::Iceoryx)?;
    }
    Ok(())
}
