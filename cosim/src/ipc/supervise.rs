//! Supervision of participant processes: reaping them and reporting how they ended.

use crate::endpoint::ExitReport;

/// Reaps child `pid` if it has ended (or waits for it when `block`), reporting its status and
/// the CPU time it used (from `wait4`'s resource usage).
pub(crate) fn try_reap(pid: u32, block: bool) -> Option<ExitReport> {
    let mut status: libc::c_int = 0;
    // SAFETY: an all-zero rusage is a valid value for the kernel to overwrite.
    let mut usage: libc::rusage = unsafe { core::mem::zeroed() };
    let flags = if block { 0 } else { libc::WNOHANG };
    // SAFETY: `pid` is our own child; wait4 writes into the two locals only.
    let r = unsafe { libc::wait4(pid as libc::pid_t, &mut status, flags, &mut usage) };
    if r != pid as libc::pid_t {
        return None;
    }
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let status = if libc::WIFEXITED(status) {
        format!("exit code {}", libc::WEXITSTATUS(status))
    } else if libc::WIFSIGNALED(status) {
        format!("killed by signal {}", libc::WTERMSIG(status))
    } else {
        format!("wait status {status}")
    };
    Some(ExitReport {
        status,
        cpu_s: Some(tv(usage.ru_utime) + tv(usage.ru_stime)),
    })
}
