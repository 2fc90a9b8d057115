//! CPU placement of a run's processes (`sched_setaffinity`).

/// The CPUs this process may run on (from `sched_getaffinity`).
pub fn allowed_cpus() -> Vec<usize> {
    // SAFETY: cpu_set_t is plain data; sched_getaffinity writes into it.
    unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        if libc::sched_getaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

/// Pins the calling process to `cpu`. Returns false if the kernel refused.
pub fn pin_to_cpu(cpu: usize) -> bool {
    set_cpus(&[cpu])
}

/// Restricts the calling process to `cpus` (used to undo [`pin_to_cpu`]).
pub fn set_cpus(cpus: &[usize]) -> bool {
    // SAFETY: as above; sched_setaffinity reads the set.
    unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        for &c in cpus {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    }
}

/// Restricts process `pid` (a participant of this run) to `cpus`. Returns false if the
/// kernel refused.
pub fn set_cpus_of(pid: u32, cpus: &[usize]) -> bool {
    // SAFETY: as above, for another process of the same user.
    unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        for &c in cpus {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(
            pid as libc::pid_t,
            core::mem::size_of::<libc::cpu_set_t>(),
            &set,
        ) == 0
    }
}
