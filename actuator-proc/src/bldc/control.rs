//! The drive's cascade, run every `control_period_s`: the position loop, the speed PI of
//! Table 1 with conditional integration, the current reference, and the cycle-by-cycle
//! protections on the measured phase currents and link voltage.

use super::{limit, Bldc};

impl Bldc {
    /// Position and speed loops (run every `control_period_s`).
    fn control(&mut self, delta_cmd: f64) {
        let theta_ref = self.gear * delta_cmd;
        let mut w_ref = self.p.position_gain * (theta_ref - self.theta_m);
        if w_ref.abs() > self.omega_max {
            w_ref = w_ref.clamp(-self.omega_max, self.omega_max);
            self.limits |= limit::SPEED;
        }
        let e = w_ref - self.omega;
        let tc = self.p.control_period_s;
        let trial = self.p.speed_kp * e + self.p.speed_ki * (self.integral + e * tc);
        let lim = self.p.torque_limit_nm;
        // Conditional integration: hold the integrator while saturated further out.
        if trial.abs() <= lim || trial.signum() != e.signum() {
            self.integral += e * tc;
        }
        let t = self.p.speed_kp * e + self.p.speed_ki * self.integral;
        if t.abs() > lim {
            self.limits |= limit::TORQUE;
        }
        self.torque_ref = t.clamp(-lim, lim);
    }

    /// The current reference T/k_t, clamped at the current limit less half the hysteresis
    /// band so that the regulated phase currents stay within `current_limit_a`.
    pub(super) fn current_ref(&mut self) -> f64 {
        let i = self.torque_ref / self.p.k_t;
        let lim = (self.p.current_limit_a - 0.5 * self.p.hysteresis_a).max(0.0);
        i.clamp(-lim, lim)
    }

    /// Protection on measured quantities, every electrical step: records the peak phase current
    /// and link voltage, and blocks the gates on over-current or over-voltage.
    #[inline]
    pub(super) fn protect(&mut self, peak: f64) {
        if peak > self.peak {
            self.peak = peak;
        }
        if self.link.v > self.v_max {
            self.v_max = self.link.v;
        }
        if peak >= self.p.current_limit_a {
            self.limits |= limit::CURRENT;
            if peak > self.trip_a {
                self.block();
                self.limits |= limit::OVERCURRENT_TRIP;
            }
        }
        if self.link.overvoltage() {
            self.block();
            self.limits |= limit::OVERVOLTAGE;
        }
    }

    /// Blocks the gates for one control period.
    #[inline]
    pub(super) fn block(&mut self) {
        self.blocked = true;
        self.blocked_steps = self.steps_per_period;
    }

    /// Position, speed and current references at a control instant.
    pub(super) fn control_update(&mut self) {
        let cmd = self.shaper.value_after(self.sub_in_interval);
        self.control(cmd);
        self.i_ref = self.current_ref();
    }

    /// Cycle-by-cycle protection: a block lasts one control period (counted in electrical
    /// steps), then the gates are released and blocked again at once if the fault persists.
    #[inline]
    pub(super) fn count_down_block(&mut self) {
        if self.blocked_steps > 0 {
            self.blocked_steps -= 1;
            self.blocked = self.blocked_steps > 0;
        }
    }
}
