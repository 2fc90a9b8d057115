//! `[network]`: participants on other hosts (docs/network.md).
//!
//! ```toml
//! [network]
//! remote = ["controller"]          # roles that join from other hosts
//! listen = "10.0.0.1:7447"         # where the orchestrator listens for them
//! join_timeout_s = 60              # how long it waits for each to join
//! lease_ms = 1000                  # a link silent this long is closed
//! ```
//!
//! The run's secret is never in the scenario (the scenario is copied into every run's
//! outputs): the orchestrator takes it from `TILTSIM_SECRET` or `--secret-file`, or draws one
//! and prints the command that joins with it.

use serde::{Deserialize, Serialize};
use tiltsim_protocol::address::{Address, ADDRESS_FORM};
use tiltsim_protocol::settings::Checker;
use tiltsim_protocol::Role;

/// The default address: this host only, so that trying a remote participant on one machine
/// needs no setting; a participant on another host needs an address it can reach.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:7447";

/// `[network]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Network {
    /// Roles served from other hosts (`tiltsim participant ROLE --connect ...` there).
    pub remote: Vec<Role>,
    /// Where the orchestrator listens: `HOST:PORT` (a leading `tls/` or `tcp/` is allowed; the
    /// link is TLS over TCP either way).
    pub listen: String,
    /// How long the orchestrator waits for each remote role to join (s).
    pub join_timeout_s: f64,
    /// Zenoh's link lease (ms): a link silent this long is closed, and a participant on it
    /// counts as gone.
    pub lease_ms: u64,
}

impl Default for Network {
    fn default() -> Self {
        Network {
            remote: Vec::new(),
            listen: DEFAULT_LISTEN.into(),
            join_timeout_s: 60.0,
            lease_ms: 1000,
        }
    }
}

impl Network {
    /// Whether every participant runs on this host (nothing of `[network]` is used).
    pub fn is_local(&self) -> bool {
        self.remote.is_empty()
    }

    /// Whether `role` joins from another host.
    pub fn is_remote(&self, role: Role) -> bool {
        self.remote.contains(&role)
    }

    /// Checks the section; errors are named under `prefix`.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        let mut seen = Vec::new();
        for r in &self.remote {
            c.require(
                !seen.contains(r),
                "remote",
                format!("{r} twice"),
                "each role at most once",
            );
            seen.push(*r);
        }
        if let Err(why) = Address::parse(&self.listen) {
            c.require(
                false,
                "listen",
                format!("{:?} ({why})", self.listen),
                ADDRESS_FORM,
            );
        }
        c.range("join_timeout_s", self.join_timeout_s, 0.1, 86_400.0, "s");
        c.require(
            (100..=600_000).contains(&self.lease_ms),
            "lease_ms",
            self.lease_ms,
            "an integer in [100, 600000] ms",
        );
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_field_and_what_is_allowed() {
        let n = Network {
            remote: vec![Role::Controller, Role::Controller],
            listen: "10.0.0.1".into(),
            join_timeout_s: 0.0,
            lease_ms: 5,
        };
        let fields: Vec<String> = n
            .validate("network")
            .errors
            .iter()
            .map(|e| e.field.clone())
            .collect();
        assert_eq!(
            fields,
            [
                "network.remote",
                "network.listen",
                "network.join_timeout_s",
                "network.lease_ms"
            ]
        );
        assert!(Network::default().validate("network").errors.is_empty());
    }
}
