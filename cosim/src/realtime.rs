//! Real-time scheduling for paced runs (hardware in the loop): the `SCHED_FIFO` policy, so that
//! no ordinary process delays a tick, and memory locked, so that no page fault does.

/// The `SCHED_FIFO` priority tiltsim uses (of 1-99): above ordinary work, below the kernel's
/// own real-time threads (which run at 99 or at 50 for interrupt threads on PREEMPT_RT).
pub const PRIORITY: i32 = 40;

/// Puts the calling thread under `SCHED_FIFO` at `priority` and locks the process's memory
/// (current and future pages). The error says what refused and what would allow it.
pub fn enter(priority: i32) -> Result<(), String> {
    // SAFETY: plain system calls on this thread and process with a valid sched_param.
    unsafe {
        let p = libc::sched_param {
            sched_priority: priority,
        };
        if libc::sched_setscheduler(0, libc::SCHED_FIFO, &p) != 0 {
            return Err(format!(
                "SCHED_FIFO at priority {priority}: {} (allowed for root, with CAP_SYS_NICE, or with `ulimit -r` of at least {priority})",
                std::io::Error::last_os_error()
            ));
        }
        if libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) != 0 {
            let e = std::io::Error::last_os_error();
            // Back to the ordinary policy: half a real-time set-up is not offered.
            let p = libc::sched_param { sched_priority: 0 };
            libc::sched_setscheduler(0, libc::SCHED_OTHER, &p);
            return Err(format!(
                "locking memory (mlockall): {e} (allowed for root, with CAP_IPC_LOCK, or with a large enough `ulimit -l`)"
            ));
        }
    }
    Ok(())
}

/// Returns the calling thread to the ordinary policy (memory stays locked): for the work after
/// a paced loop, which must not hold a core at real-time priority.
pub fn leave() {
    // SAFETY: a plain system call on this thread with a valid sched_param.
    unsafe {
        let p = libc::sched_param { sched_priority: 0 };
        libc::sched_setscheduler(0, libc::SCHED_OTHER, &p);
    }
}
