//! The handshake by which a participant joins a run.
//!
//! 1. The participant queries the run's **offer** (`tiltsim/run/*/offer`, or the one run it
//!    was told): the run's key, a nonce drawn for this run, the protocol version and the
//!    roles still awaited.
//! 2. It queries the orchestrator's **clock** a few times and keeps the exchange with the
//!    shortest round trip: the offset between the two hosts' monotonic clocks is the
//!    orchestrator's reading minus the middle of that round trip, known to within half of it.
//! 3. It sends its **hello** as the payload of a query on `join/<role>`: role, protocol
//!    version, host, pid, a nonce of its own, the clock offset, and the **proof**, a SHA-256
//!    of the run's secret with the run's key, the role and both nonces. The secret itself
//!    never crosses the network, and a proof is good for one run and one role only.
//! 4. The orchestrator answers with a **welcome** carrying the participant's settings and its
//!    own proof of the secret over them ([`welcome_proof`]), or a refusal that says why:
//!    wrong credentials, another protocol version, a role the run does not await, a role
//!    already joined. [`judge`] decides. The participant serves only after a welcome whose
//!    proof holds.
//!
//! All of this travels inside the TLS session, which both ends opened with certificates of
//! the run's authority ([`crate::credentials`]); the proofs bind the handshake to the run's
//! key and nonces on top of that.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use cosim::msg::PROTOCOL_VERSION;
use cosim::Role;

/// The run's offer.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Offer {
    /// The run's key (`<run>` of its key expressions).
    pub run: String,
    /// A nonce drawn for this run.
    pub nonce: String,
    /// The orchestrator's protocol version.
    pub protocol_version: u32,
    /// Roles the run awaits that have not joined yet.
    pub awaited: Vec<Role>,
}

/// A participant's request to join.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Hello {
    /// The role it serves.
    pub role: Role,
    /// Its protocol version.
    pub protocol_version: u32,
    /// Its host's name.
    pub host: String,
    /// Its process id on that host.
    pub pid: u32,
    /// A nonce of its own.
    pub nonce: String,
    /// [`proof`] of the secret.
    pub proof: String,
    /// The orchestrator's clock minus the participant's (ns), measured at joining.
    pub clock_offset_ns: i64,
    /// The round trip of the clock exchange that measured it (ns): the offset is known to
    /// within half of it.
    pub clock_rtt_ns: u64,
}

/// The orchestrator's answer to a [`Hello`].
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Welcome {
    /// Whether the participant joined.
    pub accepted: bool,
    /// Why not, when it did not.
    pub reason: String,
    /// Its settings as JSON (what `--params` carries on one host); empty when refused.
    pub params: String,
    /// [`welcome_proof`] of the secret over the settings: the orchestrator holds the secret
    /// too, and the settings are the ones it sent. Empty when refused.
    pub proof: String,
}

/// The proof that the sender of a hello holds `secret`, bound to one run, role and pair of
/// nonces.
pub fn proof(secret: &str, run: &str, role: Role, offer_nonce: &str, hello_nonce: &str) -> String {
    digest(&[
        "tiltsim-join-v1",
        secret,
        run,
        role.name(),
        offer_nonce,
        hello_nonce,
    ])
}

/// The orchestrator's proof that it holds `secret`, bound to the hello it answers (run, role,
/// both nonces) and to the settings it sends.
pub fn welcome_proof(
    secret: &str,
    run: &str,
    role: Role,
    nonces: (&str, &str),
    params: &str,
) -> String {
    digest(&[
        "tiltsim-welcome-v1",
        secret,
        run,
        role.name(),
        nonces.0,
        nonces.1,
        params,
    ])
}

/// SHA-256 of the parts, each prefixed by its length, as hex.
fn digest(parts: &[&str]) -> String {
    let mut h = Sha256::new();
    for part in parts {
        h.update((part.len() as u64).to_le_bytes());
        h.update(part.as_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Whether `welcome` accepts `role` and proves the secret over its settings.
pub fn welcome_is_genuine(
    secret: &str,
    run: &str,
    role: Role,
    nonces: (&str, &str),
    welcome: &Welcome,
) -> bool {
    let want = welcome_proof(secret, run, role, nonces, &welcome.params);
    welcome.accepted && same(&want, &welcome.proof)
}

/// Compares two strings in time independent of where they differ.
pub(crate) fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

/// What the orchestrator knows when a hello arrives.
pub struct Judge<'a> {
    /// The run's secret.
    pub secret: &'a str,
    /// The run's key.
    pub run: &'a str,
    /// The offer's nonce.
    pub offer_nonce: &'a str,
    /// Whether the run has `role` on another host.
    pub remote: &'a dyn Fn(Role) -> bool,
    /// Who holds `role` already (host and pid), if anyone.
    pub holder: &'a dyn Fn(Role) -> Option<(String, u32)>,
}

/// Accepts `hello` arriving on the join key of `role`, or says why not.
pub fn judge(j: &Judge<'_>, role: Role, hello: &Hello) -> Result<(), String> {
    if hello.protocol_version != PROTOCOL_VERSION {
        return Err(format!(
            "protocol version {} (this run speaks {PROTOCOL_VERSION})",
            hello.protocol_version
        ));
    }
    if hello.role != role {
        return Err(format!(
            "a hello for {} sent to the join key of {role}",
            hello.role
        ));
    }
    let want = proof(j.secret, j.run, role, j.offer_nonce, &hello.nonce);
    if !same(&want, &hello.proof) {
        return Err("wrong credentials (the run's secret does not match)".into());
    }
    if !(j.remote)(role) {
        return Err(format!("this run has no {role} on another host"));
    }
    if let Some((host, pid)) = (j.holder)(role) {
        return Err(format!(
            "{role} has already joined (from host {host}, pid {pid})"
        ));
    }
    Ok(())
}

/// A clock exchange: the participant's reading before (`t0`) and after (`t3`) the query, the
/// orchestrator's reading in between (`t`), all ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockSample {
    /// Participant's clock when the query left.
    pub t0: u64,
    /// Orchestrator's clock when it answered.
    pub t: u64,
    /// Participant's clock when the answer came.
    pub t3: u64,
}

/// The offset (orchestrator − participant, ns) and round trip of the exchange with the
/// shortest round trip, the one least disturbed by queueing.
pub fn clock_offset(samples: &[ClockSample]) -> Option<(i64, u64)> {
    samples
        .iter()
        .filter(|s| s.t3 >= s.t0)
        .min_by_key(|s| s.t3 - s.t0)
        .map(|s| {
            let mid = s.t0 as i128 + (s.t3 - s.t0) as i128 / 2;
            ((s.t as i128 - mid) as i64, s.t3 - s.t0)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hello(secret: &str, role: Role) -> Hello {
        Hello {
            role,
            protocol_version: PROTOCOL_VERSION,
            host: "ctrl".into(),
            pid: 7,
            nonce: "n2".into(),
            proof: proof(secret, "r1", role, "n1", "n2"),
            clock_offset_ns: 0,
            clock_rtt_ns: 0,
        }
    }

    fn judge_with(h: &Hello, role: Role, holder: Option<(String, u32)>) -> Result<(), String> {
        let remote = |r: Role| r != Role::Plant;
        let held = move |_: Role| holder.clone();
        judge(
            &Judge {
                secret: "s3cret",
                run: "r1",
                offer_nonce: "n1",
                remote: &remote,
                holder: &held,
            },
            role,
            h,
        )
    }

    #[test]
    fn the_right_secret_joins_and_everything_else_is_refused_by_name() {
        let c = Role::Controller;
        assert_eq!(judge_with(&hello("s3cret", c), c, None), Ok(()));
        let e = judge_with(&hello("guess", c), c, None).unwrap_err();
        assert!(e.contains("wrong credentials"), "{e}");
        let mut old = hello("s3cret", c);
        old.protocol_version = PROTOCOL_VERSION - 1;
        let e = judge_with(&old, c, None).unwrap_err();
        assert!(
            e.contains(&format!("protocol version {}", PROTOCOL_VERSION - 1)),
            "{e}"
        );
        let e = judge_with(&hello("s3cret", c), c, Some(("a".into(), 9))).unwrap_err();
        assert_eq!(e, "controller has already joined (from host a, pid 9)");
        let e = judge_with(&hello("s3cret", Role::Plant), Role::Plant, None).unwrap_err();
        assert_eq!(e, "this run has no plant on another host");
        // A proof made for one role does not let its holder in as another.
        let mut swapped = hello("s3cret", Role::Actuator);
        swapped.role = c;
        let e = judge_with(&swapped, c, None).unwrap_err();
        assert!(e.contains("wrong credentials"), "{e}");
    }

    #[test]
    fn a_proof_is_bound_to_its_run_role_and_nonces() {
        let p = proof("s", "r", Role::Plant, "a", "b");
        assert_eq!(p.len(), 64);
        assert_ne!(p, proof("s", "r2", Role::Plant, "a", "b"));
        assert_ne!(p, proof("s", "r", Role::Actuator, "a", "b"));
        assert_ne!(p, proof("s", "r", Role::Plant, "a2", "b"));
        assert_ne!(p, proof("s", "r", Role::Plant, "a", "b2"));
        // Length-prefixed parts: moving a character between parts changes the proof.
        assert_ne!(
            proof("sr", "", Role::Plant, "a", "b"),
            proof("s", "r", Role::Plant, "a", "b")
        );
    }

    #[test]
    fn a_welcome_proves_the_secret_over_its_settings() {
        let n = ("n1", "n2");
        let mut w = Welcome {
            accepted: true,
            reason: String::new(),
            params: "{\"a\":1}".into(),
            proof: welcome_proof("s3cret", "r1", Role::Controller, n, "{\"a\":1}"),
        };
        assert!(welcome_is_genuine("s3cret", "r1", Role::Controller, n, &w));
        assert!(!welcome_is_genuine("guess", "r1", Role::Controller, n, &w));
        assert!(!welcome_is_genuine("s3cret", "r1", Role::Plant, n, &w));
        assert!(!welcome_is_genuine(
            "s3cret",
            "r1",
            Role::Controller,
            ("n1", "n3"),
            &w
        ));
        // Settings changed on the way are not the ones proven.
        w.params = "{\"a\":2}".into();
        assert!(!welcome_is_genuine("s3cret", "r1", Role::Controller, n, &w));
        // The participant's own proof does not pass for the orchestrator's.
        w.params = "{\"a\":1}".into();
        w.proof = proof("s3cret", "r1", Role::Controller, "n1", "n2");
        assert!(!welcome_is_genuine("s3cret", "r1", Role::Controller, n, &w));
    }

    #[test]
    fn the_clock_offset_comes_from_the_shortest_round_trip() {
        // True offset +1000 ns; the first exchange queued 400 ns on the way back.
        let s = [
            ClockSample {
                t0: 100,
                t: 1150,
                t3: 600,
            },
            ClockSample {
                t0: 700,
                t: 1750,
                t3: 800,
            },
        ];
        assert_eq!(clock_offset(&s), Some((1000, 100)));
        assert_eq!(clock_offset(&[]), None);
    }
}
