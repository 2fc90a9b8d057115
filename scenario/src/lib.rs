//! `tiltsim-scenario`: the scenario file. It maps a TOML file onto typed settings (unknown
//! fields are errors), validates them once with messages that name the field and what is
//! allowed, and holds the settings of the links and of the process faults a scenario declares.
//! What the engine does with them (the links' effects on the values in flight, the scheduled
//! faults, the stand-ins for a lost participant) is `tiltsim-master`'s.
//!
//! Modules: [`scenario`] (the file, its loading and validation), [`links`] (link-effect
//! settings and the link names), [`faults`] (process-fault settings), [`network`]
//! (participants on other hosts), [`roles`] (a value per role).

pub mod faults;
pub mod links;
pub mod network;
pub mod roles;
pub mod scenario;

pub use scenario::{Master, Scenario, Transport};
