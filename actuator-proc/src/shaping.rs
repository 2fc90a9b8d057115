//! Command shaping between slow controller updates (`actuator.command_shaping`), as a servo
//! drive does with a set-point that arrives every controller period T_c:
//! * `hold`: the new set-point is applied at once and held (zero-order hold);
//! * `ramp`: the set-point moves linearly from where it is to the new value over T_c, reaching
//!   it exactly at the end of the period, never beyond it.

use serde::{Deserialize, Serialize};

/// How the actuator applies a new bar set-point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum CommandShaping {
    /// Apply at once (zero-order hold).
    #[default]
    Hold,
    /// Reach the new set-point linearly over the controller period.
    Ramp,
}

/// The scenario file's spelling (`actuator.command_shaping = "ramp"`).
impl std::fmt::Display for CommandShaping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CommandShaping::Hold => "hold",
            CommandShaping::Ramp => "ramp",
        })
    }
}

/// The shaped set-point. Time is counted in integer electrical steps so that the end of the
/// ramp is exact.
#[derive(Debug, Clone)]
pub struct Shaper {
    /// Length of a ramp in steps (0 = hold).
    steps: u64,
    /// Where the current ramp started (rad).
    start: f64,
    /// Where it goes (rad).
    target: f64,
    /// Steps since the current target arrived.
    elapsed: u64,
    /// The last raw command received (rad); a different value starts a new ramp.
    last_raw: f64,
}

impl Shaper {
    /// A shaper with `shaping` over `period_s`, for a drive stepping at `dt` (s).
    pub fn new(shaping: CommandShaping, period_s: f64, dt: f64) -> Self {
        let steps = match shaping {
            CommandShaping::Hold => 0,
            CommandShaping::Ramp => (period_s / dt).round().max(0.0) as u64,
        };
        Shaper {
            steps,
            start: 0.0,
            target: 0.0,
            elapsed: 0,
            last_raw: 0.0,
        }
    }

    /// The set-point `k` steps after the current target arrived (rad).
    #[inline]
    pub fn value_after(&self, k: u64) -> f64 {
        let n = self.elapsed + k;
        if n >= self.steps {
            self.target
        } else {
            self.start + (self.target - self.start) * (n as f64 / self.steps as f64)
        }
    }

    /// Takes the command received for the coming interval (already clamped to the stroke).
    pub fn receive(&mut self, cmd: f64) {
        if cmd != self.last_raw {
            self.start = self.value_after(0);
            self.target = cmd;
            self.elapsed = 0;
            self.last_raw = cmd;
        }
    }

    /// Advances by `n` steps.
    pub fn advance(&mut self, n: u64) {
        self.elapsed = self.elapsed.saturating_add(n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hold_applies_at_once_and_ramp_arrives_at_the_end_of_the_period() {
        let mut h = Shaper::new(CommandShaping::Hold, 0.05, 1e-6);
        h.receive(0.01);
        assert_eq!(h.value_after(0), 0.01);
        let mut r = Shaper::new(CommandShaping::Ramp, 0.05, 1e-6);
        r.receive(0.01);
        assert_eq!(r.value_after(0), 0.0);
        assert!((r.value_after(25_000) - 0.005).abs() < 1e-15);
        r.advance(49_000);
        assert!(r.value_after(0) < 0.01);
        r.advance(1000);
        assert_eq!(r.value_after(0), 0.01);
        r.advance(10_000);
        assert_eq!(r.value_after(0), 0.01);
        // A new set-point mid-ramp starts from where the ramp is.
        let mut r = Shaper::new(CommandShaping::Ramp, 0.05, 1e-6);
        r.receive(0.01);
        r.advance(25_000);
        r.receive(-0.01);
        assert!((r.value_after(0) - 0.005).abs() < 1e-15);
        r.advance(50_000);
        assert_eq!(r.value_after(0), -0.01);
    }
}
