//! Where a segment's events come from: the gear's loss law, the chopper and the rectifier,
//! the commutation sector's boundaries and the link's levels, each offered to [`First`].

use std::f64::consts::{FRAC_PI_3, FRAC_PI_6, TAU};

use super::roots::{leaving, reach, Poly, ORDER};
use super::{Bldc, Event, First, Rotor, GEAR_NUDGE};

impl Bldc {
    /// The gear's linear load law over a segment from now ([`Rotor`]), `te0` the motor's
    /// torque (to tell which way a rotor at rest leaves), and the longest segment it allows
    /// (its damping d/J times the segment at most 0.25, as accurate as the link's pole).
    pub(super) fn rotor(&self, psi: f64, te0: f64) -> (Rotor, f64) {
        let k = &self.consts;
        let gl = self.gear_loss;
        if gl.lossless() {
            let r = Rotor {
                kappa_j: k.kappa_j,
                bf_j: k.bf_j,
                c: 1.0,
                d: 0.0,
            };
            return (r, f64::INFINITY);
        }
        let tb = self.load_torque(psi);
        let w = self.omega;
        let dir = if w != 0.0 {
            w.signum()
        } else {
            (te0 - tb).signum()
        };
        let mu = gl.mu(tb, dir);
        let (c, d) = if w.abs() * gl.inv_w_eps >= 1.0 {
            (1.0 + mu, 0.0)
        } else {
            (1.0, mu * tb * dir * gl.inv_w_eps)
        };
        let r = Rotor {
            kappa_j: c * k.kappa_j,
            bf_j: k.bf_j + d * k.inv_j,
            c,
            d,
        };
        let h_max = if d > 0.0 {
            0.25 / (d * k.inv_j)
        } else {
            f64::INFINITY
        };
        (r, h_max)
    }

    /// Offers `first` the edges of the gear's loss law that the speed series `cw` and the
    /// angle series `cth` reach within `h`: ±ω_ε and zero bar torque.
    pub(super) fn gear_events(&self, psi: f64, cw: &Poly, cth: &Poly, h: f64, first: &mut First) {
        let gl = self.gear_loss;
        if gl.lossless() {
            return;
        }
        // How far each series can move within h: edges further away are not looked for.
        let (mut w_reach, mut th_reach) = (0.0, 0.0);
        for k in (1..=ORDER).rev() {
            w_reach = (w_reach + cw[k].abs()) * h;
            th_reach = (th_reach + cth[k].abs()) * h;
        }
        let w0 = cw[0];
        let w_eps = 1.0 / gl.inv_w_eps;
        if (w0.abs() - w_eps).abs() > w_reach {
            // Neither +ω_ε nor −ω_ε within reach.
        } else if w0.abs() * gl.inv_w_eps >= 1.0 {
            let dir = w0.signum();
            first.offer(
                reach(cw, dir * w_eps, -dir, h),
                Event::GearSpeed(dir * w_eps * (1.0 - GEAR_NUDGE)),
            );
        } else {
            // Zero speed is not an edge: within ±ω_ε the loss is d ω, d from the direction at
            // the segment's start, which stays dissipative (d ω² ≥ 0) through a reversal.
            let out = w_eps * (1.0 + GEAR_NUDGE);
            first.offer(reach(cw, w_eps, 1.0, h), Event::GearSpeed(out));
            first.offer(reach(cw, -w_eps, -1.0, h), Event::GearSpeed(-out));
        }
        // The bar's torque is zero where θ_m = G ψ.
        let target = self.gear * psi - self.theta_m;
        if target != 0.0 && target.abs() <= th_reach {
            let dir = target.signum();
            first.offer(
                reach(cth, target, dir, h),
                Event::GearTorque(target + dir * GEAR_NUDGE * (1.0 + self.theta_m.abs())),
            );
        }
    }

    /// The chopper's state for a segment, by its hysteresis rule as its fixed step decides
    /// it; its conductance.
    pub(super) fn chopper(&mut self) -> f64 {
        let (v0, lp) = (self.link.v, &self.link.p);
        if v0 >= lp.chopper_on_v {
            self.link.chopper_on = true;
        } else if v0 <= lp.chopper_off_v {
            self.link.chopper_on = false;
        }
        if self.link.chopper_on {
            self.consts.g_ch
        } else {
            0.0
        }
    }

    /// Whether the rectifier conducts over a segment: below the supply voltage, and at it when
    /// the link would otherwise fall (`dv`: its slope without the rectifier; when 0, the
    /// series `without` without the rectifier decides).
    pub(super) fn rectifier(&self, dv: f64, without: impl FnOnce() -> Poly) -> bool {
        let (v0, v_s) = (self.link.v, self.link.v_supply);
        if v0 != v_s {
            v0 < v_s
        } else if dv != 0.0 {
            dv < 0.0
        } else {
            leaving(&without()) < 0.0
        }
    }

    /// The electrical angle θ_e unwrapped into sector `sec` (rad) and the sector's start (rad).
    pub(super) fn sector_angle(&self, sec: usize) -> (f64, f64) {
        let th = if self.theta_e < FRAC_PI_6 {
            self.theta_e + TAU
        } else {
            self.theta_e
        };
        (th, FRAC_PI_6 + FRAC_PI_3 * sec as f64)
    }

    /// Offers `first` the sector's boundaries (commutations) reached by Δθ_m (`cth`) within
    /// `h`; returns the electrical angle unwrapped into the sector and the sector's start.
    pub(super) fn sector_events(
        &self,
        sec: usize,
        cth: &Poly,
        h: f64,
        first: &mut First,
    ) -> (f64, f64) {
        let half_pp = 0.5 * self.p.poles as f64;
        let (th, start) = self.sector_angle(sec);
        let d_hi = (start + FRAC_PI_3 - th) / half_pp;
        let d_lo = (start - th) / half_pp;
        first.offer(reach(cth, d_hi, 1.0, h), Event::Commutation(d_hi, 1.0));
        first.offer(reach(cth, d_lo, -1.0, h), Event::Commutation(d_lo, -1.0));
        (th, start)
    }

    /// Offers `first` the link's levels the voltage series `cv` reaches within `h`: the
    /// chopper's threshold, the over-voltage trip and the supply voltage (the rectifier).
    pub(super) fn link_events(&self, cv: &Poly, rect: bool, h: f64, first: &mut First) {
        let (v0, v_s, lp) = (cv[0], self.link.v_supply, &self.link.p);
        let (on, off, trip) = (lp.chopper_on_v, lp.chopper_off_v, lp.overvoltage_trip_v);
        let mut v_reach = 0.0;
        for k in (1..=ORDER).rev() {
            v_reach = (v_reach + cv[k].abs()) * h;
        }
        let near = |level: f64| (level - v0).abs() <= v_reach;
        if self.link.chopper_on {
            if near(off) {
                first.offer(reach(cv, off, -1.0, h), Event::Link(off));
            }
        } else if near(on) {
            first.offer(reach(cv, on, 1.0, h), Event::Link(on));
        }
        if near(trip) {
            first.offer(reach(cv, trip, 1.0, h), Event::Link(trip.next_up()));
        }
        if near(v_s) {
            let dir = if rect { 1.0 } else { -1.0 };
            first.offer(reach(cv, v_s, dir, h), Event::Link(v_s));
        }
    }
}
