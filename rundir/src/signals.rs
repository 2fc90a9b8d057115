//! Interrupting signals (SIGINT from Ctrl-C, SIGTERM, SIGHUP): each sets the run's interrupt
//! flag, and the signal is remembered so that reports name what it was.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};

static SIGNAL: AtomicI32 = AtomicI32::new(0);
static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();

extern "C" fn on_signal(sig: libc::c_int) {
    // Only atomic stores: async-signal-safe.
    SIGNAL.store(sig, Ordering::Relaxed);
    if let Some(f) = FLAG.get() {
        f.store(true, Ordering::Relaxed);
    }
}

/// For a command that only prints (no child processes, no shared memory): a closed pipe on
/// stdout (`tiltsim inspect X.fmu | head`) ends the process quietly, as it does any Unix
/// filter, instead of failing the next write.
pub fn end_quietly_on_closed_pipe() {
    // SAFETY: restoring the default disposition of SIGPIPE has no preconditions.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Installs the handlers for SIGINT, SIGTERM and SIGHUP once; returns the flag they set.
pub fn install() -> Arc<AtomicBool> {
    let flag = FLAG
        .get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone();
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: the handler only stores into atomics; sigaction with a zeroed, then filled,
        // struct is the documented way to install it.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_signal as *const () as usize;
            libc::sigemptyset(&mut sa.sa_mask);
            sa.sa_flags = libc::SA_RESTART;
            libc::sigaction(sig, &sa, std::ptr::null_mut());
        }
    }
    flag
}

/// Whether an interrupting signal has arrived since the handlers were installed.
pub fn received() -> bool {
    SIGNAL.load(Ordering::Relaxed) != 0
}

/// What interrupted the run, for messages: "Ctrl-C (SIGINT)", "SIGTERM", "SIGHUP", or
/// "an interrupt" when no signal was received (the flag was set by the program).
pub fn describe() -> &'static str {
    match SIGNAL.load(Ordering::Relaxed) {
        libc::SIGINT => "Ctrl-C (SIGINT)",
        libc::SIGTERM => "SIGTERM",
        libc::SIGHUP => "SIGHUP",
        _ => "an interrupt",
    }
}
