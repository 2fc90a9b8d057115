//! Supervision of participant processes: reaping them and reporting how they ended.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::endpoint::ExitReport;
use crate::participant::Role;

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

/// What a participant tells its orchestrator about its side of the exchange, in a few words
/// of shared memory (`/dev/shm/<prefix>status_<role>`, removed with the run's files): the
/// request it last took, the reply it last published, and how many times it polled and found
/// nothing. Written by the participant only (plain stores, no waiting), read by the
/// orchestrator only when an exchange has gone silent, so it costs nothing on the normal path
/// (the cue's words, [`CueWords`], are also written by the orchestrator and by the other
/// participants).
/// With it a silent exchange is told apart: the reply was sent but not seen (lost reply), the
/// participant polls but never took the request (lost request), it took the request and
/// computes, or it does nothing at all (stalled).
#[repr(C, align(64))]
#[derive(Default)]
pub(crate) struct StatusWords {
    /// 1 + [`crate::msg::exchange_key`] of the request last taken (0: none yet).
    pub taken: AtomicU64,
    /// 1 + the key of the reply last published.
    pub answered: AtomicU64,
    /// Polls that found no request.
    pub empty_polls: AtomicU64,
    /// Repeated requests answered from the last reply.
    pub repeats: AtomicU64,
    /// Replies whose sending reached no subscriber and were sent again.
    pub undelivered: AtomicU64,
    /// The cue ([`CueWords`]), on a cache line of its own.
    pub cue: CueWords,
}

/// The cue among participants that share a CPU and yield it while they wait: the orchestrator
/// names, with each step request, the participant of that CPU it will ask next and for which
/// step; once this one has answered it cues that one, which then polls for its request without
/// yielding (for a bounded number of polls) instead of handing the CPU on. Whatever order the
/// kernel cycles the waiting processes in, the request then finds its participant polling.
/// Changes which process runs, never what any computes.
#[repr(C, align(64))]
#[derive(Default)]
pub(crate) struct CueWords {
    /// Written by the orchestrator: who is asked after this participant's current request,
    /// [`encode_next`]; 0 for nobody.
    pub next: AtomicU64,
    /// Written by the participant asked before this one: 1 + the step it will be asked for.
    pub cue: AtomicU64,
    /// Written by this participant: the cues it gave.
    pub given: AtomicU64,
    /// Written by this participant: the waits in which it was cued and polled without
    /// yielding.
    pub cued_waits: AtomicU64,
    /// Written by this participant: the times it stepped aside for a cued one.
    pub steps_aside: AtomicU64,
}

/// The `next` word naming participant `role` (its index in [`Role::ALL`]) asked for `step`.
pub(crate) fn encode_next(next: Option<(Role, u64)>) -> u64 {
    next.and_then(|(r, step)| {
        let i = Role::ALL.iter().position(|&x| x == r)? as u64;
        (step < 1 << 56).then_some(((i + 1) << 56) | step)
    })
    .unwrap_or(0)
}

/// The participant and step a `next` word names.
pub(crate) fn decode_next(word: u64) -> Option<(Role, u64)> {
    let i = (word >> 56).checked_sub(1)? as usize;
    Some((*Role::ALL.get(i)?, word & ((1 << 56) - 1)))
}

/// A participant's status words, mapped from shared memory (or private when the orchestrator
/// made none, e.g. a participant started by hand).
pub(crate) struct Status {
    words: *const StatusWords,
    /// Name to unlink on drop (the orchestrator's side owns the file).
    owned: Option<std::ffi::CString>,
    /// Private words when there is no shared memory.
    _private: Option<Box<StatusWords>>,
}

// SAFETY: the mapping lives as long as the value; the words are atomics.
unsafe impl Send for Status {}

const STATUS_BYTES: usize = 4096;

fn status_name(prefix: &str, role: Role) -> Option<std::ffi::CString> {
    std::ffi::CString::new(format!("/{prefix}status_{}", role.name())).ok()
}

impl Status {
    /// The orchestrator's side: creates the participant's status (zeroed).
    pub(crate) fn create(prefix: &str, role: Role) -> std::io::Result<Status> {
        let name = status_name(prefix, role).ok_or(std::io::ErrorKind::InvalidInput)?;
        // SAFETY: a NUL-terminated name; flags and mode are plain integers.
        let fd = unsafe {
            libc::shm_open(
                name.as_ptr(),
                libc::O_CREAT | libc::O_RDWR | libc::O_TRUNC,
                0o600,
            )
        };
        if fd < 0 {
            return Err(std::io::Error::last_os_error());
        }
        let status = Self::map(fd, Some(name.clone()));
        if status.is_err() {
            // SAFETY: as above.
            unsafe { libc::shm_unlink(name.as_ptr()) };
        }
        status
    }

    /// The participant's side: opens the status its orchestrator created, or private words.
    pub(crate) fn open(prefix: &str, role: Role) -> Status {
        if let Some(s) = Self::open_shared(prefix, role) {
            return s;
        }
        let private = Box::<StatusWords>::default();
        Status {
            words: &*private,
            owned: None,
            _private: Some(private),
        }
    }

    /// The status the orchestrator created for `role`, if there is one.
    pub(crate) fn open_shared(prefix: &str, role: Role) -> Option<Status> {
        let fd = status_name(prefix, role)
            // SAFETY: a NUL-terminated name.
            .map(|n| unsafe { libc::shm_open(n.as_ptr(), libc::O_RDWR, 0) })
            .unwrap_or(-1);
        if fd < 0 {
            return None;
        }
        // Mapped only once its orchestrator has sized it, or touching it would fault.
        // SAFETY: `fd` is open; `st` is written by fstat.
        let sized = unsafe {
            let mut st: libc::stat = std::mem::zeroed();
            libc::fstat(fd, &mut st) == 0 && st.st_size as usize >= STATUS_BYTES
        };
        if !sized {
            // SAFETY: `fd` is open and closed once.
            unsafe { libc::close(fd) };
            return None;
        }
        Self::map(fd, None).ok()
    }

    fn map(fd: libc::c_int, owned: Option<std::ffi::CString>) -> std::io::Result<Status> {
        // SAFETY: `fd` is an open shared-memory object; the mapping is checked before use and
        // the descriptor is closed once mapped (the mapping keeps the object).
        unsafe {
            if owned.is_some() && libc::ftruncate(fd, STATUS_BYTES as libc::off_t) != 0 {
                let e = std::io::Error::last_os_error();
                libc::close(fd);
                return Err(e);
            }
            let p = libc::mmap(
                core::ptr::null_mut(),
                STATUS_BYTES,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                fd,
                0,
            );
            let e = std::io::Error::last_os_error();
            libc::close(fd);
            if p == libc::MAP_FAILED {
                return Err(e);
            }
            Ok(Status {
                words: p as *const StatusWords,
                owned,
                _private: None,
            })
        }
    }

    /// The words.
    pub(crate) fn words(&self) -> &StatusWords {
        // SAFETY: `words` points at a live mapping (or the private box) for `self`'s lifetime.
        unsafe { &*self.words }
    }
}

impl Drop for Status {
    fn drop(&mut self) {
        if self.owned.is_some() {
            // The participant is gone or replaced: it names nobody to the others, whose
            // mappings outlive this one, and nobody steps aside for it.
            self.words().cue.next.store(0, Ordering::Release);
        }
        if self._private.is_none() {
            // SAFETY: the mapping made in `map`, of STATUS_BYTES, unmapped once.
            unsafe { libc::munmap(self.words as *mut libc::c_void, STATUS_BYTES) };
        }
        if let Some(name) = &self.owned {
            // SAFETY: a NUL-terminated name.
            unsafe { libc::shm_unlink(name.as_ptr()) };
        }
    }
}

/// Scheduler state and CPU time (ns, from `/proc/<pid>/schedstat`, else from the clock ticks
/// of `/proc/<pid>/stat`) of process `pid`; `None` once it is gone.
pub(crate) fn proc_state(pid: u32) -> Option<(char, u64)> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = s.get(s.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let state = f.first()?.chars().next()?;
    let ticks = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    let ns = std::fs::read_to_string(format!("/proc/{pid}/schedstat"))
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .unwrap_or(ticks.saturating_mul(10_000_000));
    Some((state, ns))
}
