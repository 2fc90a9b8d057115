//! The key expressions of one run. Every key starts with `tiltsim/run/<run>/`, where `<run>`
//! is 128 random bits drawn when the run starts, so two runs on one network never share a key.

use cosim::Role;

/// The run's offer, which a joining participant finds with a query (`tiltsim/run/*/offer`).
pub fn offer(run: &str) -> String {
    format!("tiltsim/run/{run}/offer")
}

/// Every offer on the network.
pub const ANY_OFFER: &str = "tiltsim/run/*/offer";

/// The orchestrator's clock, queried to measure the offset between the hosts' clocks.
pub fn clock(run: &str) -> String {
    format!("tiltsim/run/{run}/clock")
}

/// Where `role` asks to join, its hello as the query's payload.
pub fn join(run: &str, role: Role) -> String {
    format!("tiltsim/run/{run}/join/{}", role.name())
}

/// Every role's join key (the orchestrator's queryable).
pub fn join_any(run: &str) -> String {
    format!("tiltsim/run/{run}/join/*")
}

/// Requests to `role`.
pub fn request(run: &str, role: Role) -> String {
    format!("tiltsim/run/{run}/{}/request", role.name())
}

/// Replies of `role`.
pub fn reply(run: &str, role: Role) -> String {
    format!("tiltsim/run/{run}/{}/reply", role.name())
}

/// Process faults sent to `role` (`kill`, `stall NS`).
pub fn control(run: &str, role: Role) -> String {
    format!("tiltsim/run/{run}/{}/control", role.name())
}

/// What `role` says about itself outside the exchange: why it ends, its CPU time at a stop.
pub fn note(run: &str, role: Role) -> String {
    format!("tiltsim/run/{run}/{}/note", role.name())
}

/// Every role's notes.
pub fn note_any(run: &str) -> String {
    format!("tiltsim/run/{run}/*/note")
}

/// The liveliness token of a joined `role`: it disappears when the participant's session
/// closes or its link's lease runs out.
pub fn alive(run: &str, role: Role) -> String {
    format!("tiltsim/run/{run}/{}/alive", role.name())
}

/// Every participant's liveliness token.
pub fn alive_any(run: &str) -> String {
    format!("tiltsim/run/{run}/*/alive")
}

/// The orchestrator's liveliness token: participants end when it disappears.
pub fn orchestrator_alive(run: &str) -> String {
    format!("tiltsim/run/{run}/orchestrator/alive")
}

/// The role a key of the run names in its fourth chunk (`tiltsim/run/<run>/<role>/...`).
pub fn role_of(key: &str) -> Option<Role> {
    key.split('/').nth(3).and_then(Role::parse)
}

/// The run a key of the run names (`tiltsim/run/<run>/...`).
pub fn run_of(key: &str) -> Option<&str> {
    key.split('/').nth(2)
}
