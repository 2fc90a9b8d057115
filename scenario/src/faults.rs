//! Process faults (section `[faults]`): what happens to the participants' processes, and what
//! the run does when one fails or sends bad data.

use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;
use tiltsim_protocol::Role;

/// What the run does when a participant fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OnFailure {
    /// End the run, name the participant, keep the rows.
    #[default]
    Abort,
    /// Continue as a tilting train would: a lost actuator's bar returns to neutral over
    /// `neutral_ramp_s`; a lost controller is replaced by `controller_fallback`. A lost plant
    /// always aborts.
    Degrade,
}

/// What a participant does with a NaN or infinite input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OnBadData {
    /// Reject it: the run ends naming participant, field and step.
    #[default]
    Abort,
    /// Use the last good input instead and log it.
    Hold,
}

/// The controller's replacement in degraded mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Fallback {
    /// Ramp the bar command to neutral over `neutral_ramp_s`.
    #[default]
    Neutral,
    /// Hold the last command.
    Hold,
}

/// A scheduled process fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultAction {
    /// SIGKILL.
    Kill,
    /// SIGSTOP for `stall_s` of wall time, then SIGCONT.
    Stall,
    /// The process aborts itself on its next request.
    Crash,
}

/// The scenario file's spelling (`action = "kill"`).
impl std::fmt::Display for FaultAction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FaultAction::Kill => "kill",
            FaultAction::Stall => "stall",
            FaultAction::Crash => "crash",
        })
    }
}

/// One scheduled fault (`[[faults.schedule]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScheduledFault {
    /// Which participant.
    pub participant: Role,
    /// What happens.
    pub action: FaultAction,
    /// Simulated time (s); applied before the first tick at or after it.
    pub at_s: f64,
    /// Wall-clock length of a stall (s).
    #[serde(default)]
    pub stall_s: f64,
}

/// Section `[faults]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faults {
    /// What follows a participant failure.
    pub on_failure: OnFailure,
    /// What follows a NaN or infinite input.
    pub on_bad_data: OnBadData,
    /// Degraded mode: time for the bar to return to neutral (s).
    pub neutral_ramp_s: f64,
    /// Degraded mode: what replaces a lost controller.
    pub controller_fallback: Fallback,
    /// Scheduled faults.
    pub schedule: Vec<ScheduledFault>,
}

impl Default for Faults {
    fn default() -> Self {
        Faults {
            on_failure: OnFailure::Abort,
            on_bad_data: OnBadData::Abort,
            neutral_ramp_s: 2.0,
            controller_fallback: Fallback::Neutral,
            schedule: Vec::new(),
        }
    }
}

impl Faults {
    /// Checks the section.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        c.range("neutral_ramp_s", self.neutral_ramp_s, 1e-3, 60.0, "s");
        for (i, f) in self.schedule.iter().enumerate() {
            c.range(&format!("schedule[{i}].at_s"), f.at_s, 0.0, 1e6, "s");
            if f.action == FaultAction::Stall {
                c.range(
                    &format!("schedule[{i}].stall_s"),
                    f.stall_s,
                    1e-3,
                    600.0,
                    "s",
                );
            }
        }
        c
    }
}
