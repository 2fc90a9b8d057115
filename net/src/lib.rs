//! `tiltsim-net`: participants on other hosts, over Eclipse Zenoh.
//!
//! The orchestrator opens a Zenoh session that listens on the run's address
//! ([`NetSettings::listen`]) and waits for each remote role to join ([`NetHub`]). On the other
//! host the user starts the same program, `tiltsim participant ROLE --connect ADDRESS`, with
//! the run's secret; it finds the run, proves it holds the secret, is given its settings and
//! serves requests ([`serve::participant_main`]). From then on the orchestrator drives it
//! through a [`NetEndpoint`], the same `cosim::Endpoint` the in-process and iceoryx2
//! transports implement, so the master algorithms, link effects, faults and recording do not
//! know which participant is remote.
//!
//! Files: [`keys`] (the run's key expressions), [`join`] (the handshake: offer, hello,
//! welcome, the proof of the secret, the clock offset), [`session`] (Zenoh configuration),
//! [`hub`] (the orchestrator's side), [`endpoint`] (one remote participant), [`serve`] (the
//! participant's side).
//!
//! Samples travel as [`tiltsim_protocol::wire`] bytes over a reliable, ordered TCP link
//! (express: never batched), so a lock-step run gives the same bytes as on one host.

pub mod endpoint;
pub mod hub;
pub mod join;
pub mod keys;
pub mod pingpong;
pub mod serve;
pub mod session;

pub use endpoint::NetEndpoint;
pub use hub::{Joined, NetHub, Refusal};

use std::time::Duration;

use cosim::Role;

/// What a run's network side needs.
#[derive(Debug, Clone)]
pub struct NetSettings {
    /// Where the orchestrator listens, as a Zenoh endpoint (`tcp/10.0.0.1:7447`).
    pub listen: String,
    /// The run's secret: a participant must prove it holds it to join.
    pub secret: String,
    /// How long a remote participant may take to answer one exchange.
    pub deadline: Duration,
    /// How long the orchestrator waits for a remote role to join.
    pub join_timeout: Duration,
    /// Zenoh's link lease: a link silent this long (a cut cable, a host gone) is closed and
    /// the participant on it counted as gone.
    pub lease: Duration,
}

/// Errors of the network transport.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// Zenoh refused something.
    #[error("network ({what}): {why}")]
    Zenoh {
        /// What was being done.
        what: String,
        /// Zenoh's message.
        why: String,
    },
    /// A remote role did not join in time.
    #[error("participant {role} never joined the run at {listen} within {waited_s:.0} s{refused}")]
    NeverJoined {
        /// The role.
        role: Role,
        /// The run's address.
        listen: String,
        /// How long the orchestrator waited.
        waited_s: f64,
        /// The participants refused meanwhile, as text (empty if none).
        refused: String,
    },
    /// The run was interrupted while it waited for a remote role.
    #[error("interrupted while waiting for participant {role} to join")]
    Interrupted {
        /// The role.
        role: Role,
    },
    /// The participant's side could not join or serve.
    #[error("{0}")]
    Participant(String),
}

pub(crate) fn zenoh_error<E: std::fmt::Display>(what: &str) -> impl FnOnce(E) -> NetError + '_ {
    move |e| NetError::Zenoh {
        what: what.to_string(),
        why: e.to_string(),
    }
}

/// A new secret for a run: 128 random bits as hex, from the kernel's random source.
pub fn new_secret() -> std::io::Result<String> {
    use std::io::Read;
    let mut b = [0u8; 16];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut b)?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

/// This host's name (`uname -n`), for naming a participant in messages.
pub fn host_name() -> String {
    // SAFETY: an all-zero utsname is valid; uname only writes into it.
    let mut u: libc::utsname = unsafe { core::mem::zeroed() };
    // SAFETY: a valid pointer to a utsname.
    if unsafe { libc::uname(&mut u) } != 0 {
        return "?".into();
    }
    let bytes: Vec<u8> = u
        .nodename
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}
