//! The stall check's rule: whether a participant that has not answered by its deadline is
//! hung, idle with the request pending, or running but starved (waited for).

use std::time::Duration;

use crate::ipc::supervise::proc_state;

/// Interval between two looks at a participant that has not answered by its deadline.
pub(super) const LOOK_EVERY: Duration = Duration::from_millis(100);

/// One look at a participant process: for the next look to compare with.
#[derive(Debug, Clone, Copy)]
pub(super) struct Look {
    pub(super) cpu_ns: u64,
    pub(super) empty_polls: u64,
}

/// What the looks at a participant past its deadline remember: the previous look and the
/// first (for the ceiling), and how many looks in a row found it idle.
#[derive(Debug, Default)]
pub(super) struct Looks {
    pub(super) previous: Option<Look>,
    pub(super) first: Option<Look>,
    pub(super) idle: u32,
}

/// How many ceilings of wall time a running participant is waited for at most, whatever CPU
/// time it got: the bound on one that never gets going (in an uninterruptible wait for ever).
pub(super) const WALL_CEILINGS: u32 = 10;

/// Whether a participant judged running has gone past the ceiling: it used more CPU time than
/// the ceiling since the first look (it computes for ever), or [`WALL_CEILINGS`] ceilings of
/// wall time have passed. CPU time, not wall time, is what the ceiling counts: a participant
/// starved by other load gets little of it, so load alone never makes it fail.
pub(super) fn past_ceiling(
    ceiling: Duration,
    elapsed: Duration,
    first: Option<Look>,
    now: Option<Look>,
) -> bool {
    let cpu_ns = match (first, now) {
        (Some(f), Some(n)) => n.cpu_ns.saturating_sub(f.cpu_ns),
        _ => 0,
    };
    Duration::from_nanos(cpu_ns) > ceiling || elapsed > ceiling * WALL_CEILINGS
}

/// Whether a participant that has not answered by the deadline is hung or only slow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Liveness {
    /// Stopped, or sleeping without using CPU: it will not answer.
    Hung,
    /// Runnable or using CPU: starved by other load (or busy); wait on.
    Running,
    /// Polls but has not taken the pending request: it is re-sent, and a second such look
    /// declares the participant hung.
    Idle,
}

/// The verdict on a participant that has not answered by its deadline, from its process state,
/// its CPU time and its status, compared with the previous look (`None` at the first).
///
/// * Gone, or stopped (`T`): hung.
/// * Runnable (`R`) or in an uninterruptible wait (`D`): running, starved by other load.
/// * Took the request and computes: running while its CPU time grows, else hung (asleep with
///   the request in hand).
/// * Has not taken the request: hung if it keeps polling without taking it over two looks
///   (the request is re-sent at each), or if it neither polls nor uses CPU; else running.
pub(super) fn judge(
    pid: u32,
    computing: bool,
    empty_polls: u64,
    previous: Option<Look>,
    idle_looks: &mut u32,
) -> (Liveness, Option<Look>) {
    let Some((state, cpu_ns)) = proc_state(pid) else {
        return (Liveness::Hung, None);
    };
    let look = Look {
        cpu_ns,
        empty_polls,
    };
    let verdict = match (state, previous) {
        ('T' | 't', _) => Liveness::Hung,
        ('R' | 'D', _) => Liveness::Running,
        // First look: a short second look decides.
        (_, None) => Liveness::Running,
        (_, Some(p)) if computing => {
            if cpu_ns > p.cpu_ns {
                Liveness::Running
            } else {
                Liveness::Hung
            }
        }
        (_, Some(p)) if empty_polls > p.empty_polls => {
            *idle_looks += 1;
            if *idle_looks >= 2 {
                Liveness::Hung
            } else {
                Liveness::Idle
            }
        }
        (_, Some(p)) if cpu_ns > p.cpu_ns => Liveness::Running,
        (_, Some(_)) => Liveness::Hung,
    };
    if verdict != Liveness::Idle {
        *idle_looks = 0;
    }
    (verdict, Some(look))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ceiling_counts_cpu_time_so_a_starved_participant_is_waited_for() {
        let c = Duration::from_secs(60);
        let look = |cpu_s: f64| {
            Some(Look {
                cpu_ns: (cpu_s * 1e9) as u64,
                empty_polls: 0,
            })
        };
        // Starved: five minutes of wall time, one second of CPU.
        assert!(!past_ceiling(
            c,
            Duration::from_secs(300),
            look(2.0),
            look(3.0)
        ));
        // Computing for ever: more CPU than the ceiling since the first look.
        assert!(past_ceiling(
            c,
            Duration::from_secs(70),
            look(2.0),
            look(62.5)
        ));
        assert!(!past_ceiling(
            c,
            Duration::from_secs(70),
            look(2.0),
            look(61.5)
        ));
        // Never getting going: ten ceilings of wall time, whatever the CPU.
        assert!(past_ceiling(
            c,
            Duration::from_secs(601),
            look(2.0),
            look(2.0)
        ));
        assert!(!past_ceiling(c, Duration::from_secs(599), None, None));
    }
}
