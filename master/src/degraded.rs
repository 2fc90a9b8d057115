//! Stand-ins for a participant lost during a run (`faults.on_failure = "degrade"`): what a
//! tilting train does when its tilt actuator or tilt controller fails. Plain models with an
//! explicit step, served in-process by the orchestrator once the real process is gone.

use cosim::msg::{FromActuator, FromController, ToActuator, ToController};
use cosim::{Participant, Role};

/// Failsafe of a lost actuator: the bar returns from where it was to neutral (δ_a = 0) at a
/// constant rate, reaching it `ramp_s` after the loss; the motor is de-energised.
pub struct NeutralBar {
    start: f64,
    delta_a: f64,
    /// Steps to neutral.
    steps: f64,
    n: u64,
}

impl NeutralBar {
    /// Starts from `delta_a` (rad); base tick `dt` (s).
    pub fn new(delta_a: f64, ramp_s: f64, dt: f64) -> Self {
        NeutralBar {
            start: delta_a,
            delta_a,
            steps: (ramp_s / dt).round().max(1.0),
            n: 0,
        }
    }
    fn out(&self) -> FromActuator {
        FromActuator {
            delta_a: self.delta_a,
            ..Default::default()
        }
    }
}

impl Participant for NeutralBar {
    type Input = ToActuator;
    type Output = FromActuator;
    const ROLE: Role = Role::Actuator;
    fn initial_output(&mut self) -> FromActuator {
        self.out()
    }
    fn step(&mut self, _: &ToActuator) -> FromActuator {
        // From the step count, so the bar is exactly neutral after `ramp_s`.
        self.n += 1;
        self.delta_a = self.start * (1.0 - self.n as f64 / self.steps).max(0.0);
        self.out()
    }
}

/// Fallback of a lost controller: hold the last command, or ramp it to neutral in `ramp_s`.
pub struct FallbackController {
    start: f64,
    cmd: f64,
    /// Calls to neutral (None: hold).
    steps: Option<f64>,
    n: u64,
}

impl FallbackController {
    /// Starts from command `cmd` (rad); `ramp_s` = None holds it. Called every `period` s.
    pub fn new(cmd: f64, ramp_s: Option<f64>, period: f64) -> Self {
        FallbackController {
            start: cmd,
            cmd,
            steps: ramp_s.map(|r| (r / period).round().max(1.0)),
            n: 0,
        }
    }
}

impl Participant for FallbackController {
    type Input = ToController;
    type Output = FromController;
    const ROLE: Role = Role::Controller;
    fn initial_output(&mut self) -> FromController {
        FromController {
            delta_a_cmd: self.cmd,
            ..Default::default()
        }
    }
    fn step(&mut self, i: &ToController) -> FromController {
        self.n += 1;
        if let Some(steps) = self.steps {
            self.cmd = self.start * (1.0 - self.n as f64 / steps).max(0.0);
        }
        FromController {
            delta_a_cmd: self.cmd,
            theta_ref: 0.0,
            theta_v_hat: i.theta_v_meas,
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bar_reaches_neutral_in_the_ramp_time_and_stays_there() {
        let mut b = NeutralBar::new(-0.04, 2.0, 1e-3);
        let mut last = -0.04f64;
        for k in 1..=2500 {
            let d = b.step(&ToActuator::default()).delta_a;
            assert!(d.abs() <= last.abs() + 1e-15);
            if k == 1000 {
                assert!((d + 0.02).abs() < 1e-12, "halfway at 1 s: {d}");
            }
            if k >= 2000 {
                assert_eq!(d, 0.0, "at tick {k}");
            }
            last = d;
        }
        let mut c = FallbackController::new(0.04, None, 0.05);
        assert_eq!(c.step(&ToController::default()).delta_a_cmd, 0.04);
    }
}
