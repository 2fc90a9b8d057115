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
//! Files: [`keys`] (the run's key expressions), [`credentials`] (the run's TLS authority,
//! derived from its secret, and each end's certificate), [`acl`] (Zenoh's access control:
//! each role its own keys, deny by default), [`join`] (the handshake: offer, hello, welcome,
//! the proofs of the secret, the clock offset), [`session`] (Zenoh configuration), [`hub`]
//! (the orchestrator's side), [`endpoint`] (one remote participant), [`serve`] (the
//! participant's side), [`watch`] (attempts by others, named in the run's outputs).
//!
//! Samples travel as [`tiltsim_protocol::wire`] bytes over a reliable, ordered link, TLS 1.3
//! over TCP with certificates at both ends (express: never batched), so a lock-step run gives
//! the same bytes as on one host and nobody without the run's credentials reads or sends any
//! of them (docs/network.md, "Who can touch a run").

pub mod acl;
pub mod credentials;
pub mod endpoint;
pub mod hub;
pub mod join;
pub mod keys;
pub mod pingpong;
pub mod serve;
pub mod session;
pub mod watch;

pub use endpoint::NetEndpoint;
pub use hub::{Joined, NetHub, Refusal};
pub use watch::{Attempt, AttemptKind};

use std::time::Duration;

use cosim::Role;
use tiltsim_protocol::address::Address;

/// What a run's network side needs.
#[derive(Debug, Clone)]
pub struct NetSettings {
    /// Where the orchestrator listens.
    pub listen: Address,
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
    /// The caller's stop flag was set during a measurement (`pingpong`).
    #[error("stopped at the caller's request")]
    Stopped,
}

pub(crate) fn zenoh_error<E: std::fmt::Display>(what: &str) -> impl FnOnce(E) -> NetError + '_ {
    move |e| NetError::Zenoh {
        what: what.to_string(),
        why: clean(&e.to_string()),
    }
}

/// Zenoh's error text without the source locations it appends (` at /path/file.rs:123.`),
/// which say nothing to a user.
pub fn clean(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(" at /") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 4..];
        // The location ends after `.rs:LINE` (and a full stop, if any).
        match after.find(".rs:") {
            Some(j) => {
                let tail = &after[j + 4..];
                let digits = tail.chars().take_while(char::is_ascii_digit).count();
                let mut skip = j + 4 + digits;
                if after[skip..].starts_with('.') {
                    skip += 1;
                }
                rest = &after[skip..];
            }
            None => {
                // Not a location: keep the text (`after` still starts with the slash).
                out.push_str(" at ");
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out.trim_end().to_string()
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

#[cfg(test)]
mod tests {
    #[test]
    fn zenoh_errors_lose_their_source_locations() {
        let raw = "Can not create a new TLS listener bound to 10.0.0.1:7447: Address already in use (os error 98) at /root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/zenoh-link-tls-1.10.2/src/unicast.rs:320.";
        assert_eq!(
            super::clean(raw),
            "Can not create a new TLS listener bound to 10.0.0.1:7447: Address already in use (os error 98)"
        );
        assert_eq!(super::clean("meet at /x"), "meet at /x");
    }
}
