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

/// Unlocks the process's memory locked by [`enter`], for a process that goes on after a
/// real-time run (`tiltsim bench --realtime`).
pub fn unlock_memory() {
    // SAFETY: a plain system call on this process.
    unsafe {
        libc::munlockall();
    }
}

/// Whether the kernel caps the CPU time of real-time threads (`kernel.sched_rt_runtime_us` of
/// every `kernel.sched_rt_period_us`, 0.95 s of each second by default), so that processes that
/// poll under `SCHED_FIFO` still leave a share of each CPU to everything else; the error says
/// what the kernel has and why that is refused.
pub fn throttled() -> Result<(), String> {
    let read = |f: &str| {
        let path = format!("/proc/sys/kernel/{f}");
        std::fs::read_to_string(&path)
            .map_err(|e| format!("{path}: {e}"))
            .and_then(|t| t.trim().parse::<i64>().map_err(|e| format!("{path}: {e}")))
    };
    throttling(read("sched_rt_runtime_us")?, read("sched_rt_period_us")?)
}

/// The verdict on a kernel whose real-time threads may run `runtime` µs of every `period` µs
/// (`runtime` −1: without limit).
fn throttling(runtime: i64, period: i64) -> Result<(), String> {
    if runtime < 0 || runtime >= period {
        return Err(format!(
            "the kernel does not throttle real-time threads (kernel.sched_rt_runtime_us = {runtime} of kernel.sched_rt_period_us = {period}), so the run's polling processes could hold their CPUs from everything else; set it below the period (`sysctl kernel.sched_rt_runtime_us=950000`) or pace the run (--pace)"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    /// Linux's default (0.95 s of each second) throttles; no limit (−1) or a limit of the
    /// whole period does not, and the refusal says what to set.
    #[test]
    fn only_a_kernel_that_caps_real_time_threads_is_accepted_unpaced() {
        assert!(super::throttling(950_000, 1_000_000).is_ok());
        assert!(super::throttling(0, 1_000_000).is_ok());
        for (runtime, period) in [(-1, 1_000_000), (1_000_000, 1_000_000)] {
            let e = super::throttling(runtime, period).unwrap_err();
            assert!(
                e.contains("sysctl kernel.sched_rt_runtime_us=950000"),
                "{e}"
            );
            assert!(e.contains(&format!("= {runtime} of")), "{e}");
        }
        // This machine's kernel answers one way or the other, never with an unreadable file.
        let e = super::throttled().err().unwrap_or_default();
        assert!(!e.contains("/proc/sys"), "{e}");
    }
}
