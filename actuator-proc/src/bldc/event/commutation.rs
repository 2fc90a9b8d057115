//! A commutation's segment: the outgoing phase on its diode while the new pair is
//! regulated, all three phases conducting into the star point.

use std::f64::consts::FRAC_PI_3;

use super::roots::{eval, reach, Poly, ORDER};
use super::{Consts, Event, First, Integrals, Rotor, FALLBACK_STEP, GL_W, GL_X};
use super::{Q_AUX, Q_CHOPPER, Q_COPPER, Q_FRICTION, Q_GEAR, Q_INVERTER, Q_LOAD, Q_RECTIFIER};
use crate::bldc::{limit, shapes, Bldc, Gate};

/// A segment of a commutation from now: as [`Usual`], with the legs of the commutated pair
/// and of the outgoing phase's diode (1 at the link, 0 at 0 V), the pair's gates, the
/// outgoing phase's back-EMF shape (f_o0, k_o), the electrical angle unwrapped into the
/// sector, and the series of (i_+, i_o, i_− = −i_+ − i_o, ω, Δθ_m, v).
struct Commutation {
    h: f64,
    gear: Rotor,
    legs: [f64; 3],
    gates: (Gate, Gate),
    shape: (f64, f64),
    rect: bool,
    g_r: f64,
    g_ch: f64,
    v_s: f64,
    v0: f64,
    th: f64,
    cp: Poly,
    co: Poly,
    cm: Poly,
    cw: Poly,
    cth: Poly,
    cv: Poly,
}

impl Commutation {
    /// [`Integrals`] over [0, `tau`] with the rotor at `theta_m`, the bar twisted by `psi`
    /// and the phase currents `i` at the start.
    fn integrals(&self, k: &Consts, theta_m: f64, psi: f64, tau: f64, i: [f64; 3]) -> Integrals {
        let (cp, co, cw, cth, cv, gear) =
            (&self.cp, &self.co, &self.cw, &self.cth, &self.cv, self.gear);
        let (f_o0, k_o) = self.shape;
        let legs = self.legs;
        let ds = [legs[0] - legs[1], legs[2] - legs[1]];
        let mut q = [0.0; 8];
        let mut q_te = 0.0;
        let (mut peak, mut v_hi) = (i[0].abs().max(i[1].abs()).max(i[2].abs()), self.v0);
        let half = 0.5 * tau;
        for (xg, wg) in GL_X.iter().zip(GL_W) {
            let t = half * (1.0 + xg);
            let w = wg * half;
            let (ip, io, wt, tht, vt) = (
                eval(cp, t),
                eval(co, t),
                eval(cw, t),
                eval(cth, t),
                eval(cv, t),
            );
            let im = -ip - io;
            let tb = k.k_vr_g * ((theta_m + tht) * k.inv_g - psi);
            q_te += w * k.lam * (2.0 * ip + (1.0 + f_o0 + k_o * tht) * io);
            q[Q_INVERTER] += w * vt * (ds[0] * ip + ds[1] * io);
            q[Q_COPPER] += w * 0.5 * k.two_r * (ip * ip + io * io + im * im);
            q[Q_FRICTION] += w * k.b_f * wt * wt;
            q[Q_LOAD] += w * tb * wt;
            q[Q_GEAR] += w * ((gear.c - 1.0) * tb + gear.d * wt) * wt;
            q[Q_RECTIFIER] += w * vt * self.g_r * (self.v_s - vt);
            q[Q_CHOPPER] += w * self.g_ch * vt * vt;
            q[Q_AUX] += w * k.g_aux * vt * vt;
            peak = peak.max(ip.abs()).max(io.abs()).max(im.abs());
            v_hi = v_hi.max(vt);
        }
        Integrals {
            q0: q_te,
            q,
            peak,
            v_hi,
        }
    }
}

impl Bldc {
    /// One segment of a commutation: the outgoing phase `off` still carries current through
    /// its diode while the commutated pair `pp`, `mm` is regulated by its comparators, all
    /// three conducting ([`Consts::transient_series`]), at most `h` long. Ends at the first of:
    /// the outgoing current reaching zero, a comparator switching, a sector boundary, a link
    /// level. Returns what [`Bldc::segment`] returns.
    pub(super) fn transient(
        &mut self,
        psi: f64,
        h: f64,
        phases: [usize; 3],
        sec: usize,
    ) -> Result<(f64, f64, f64, f64), f64> {
        let c = self.commutation_series(psi, h, phases, sec)?;
        let first = self.commutation_events(&c, psi, phases, sec);
        let tau = first.tau;
        let q = c.integrals(&self.consts, self.theta_m, psi, tau, self.i);
        let (q_te, q_inverter, q_chopper) = (q.q0, q.q[Q_INVERTER], q.q[Q_CHOPPER]);
        self.commutation_end(&c, first, phases, q);
        Ok((tau, q_te, q_inverter, q_chopper))
    }

    /// A commutation's segment from now, at most `h` long: the legs, the outgoing phase's
    /// back-EMF shape across the sector, the link's conductances and the series. `Err` (a
    /// fixed step) while a commutated leg is not gated, or near the bar's end stop.
    fn commutation_series(
        &mut self,
        psi: f64,
        h: f64,
        [pp, mm, off]: [usize; 3],
        sec: usize,
    ) -> Result<Commutation, f64> {
        let i = self.i;
        let (gear, h_gear) = self.rotor(psi, self.consts.k_t * i[pp]);
        let h = h.min(h_gear);
        let (gp, gm) = (self.gates[pp], self.gates[mm]);
        if gp == Gate::Off || gm == Gate::Off {
            return Err(FALLBACK_STEP);
        }
        let at_link = |g: Gate| if g == Gate::Upper { 1.0 } else { 0.0 };
        // The outgoing phase's diode: the lower one (0 V) for a positive current, else the upper.
        let legs = [
            at_link(gp),
            at_link(gm),
            if i[off] < 0.0 { 1.0 } else { 0.0 },
        ];
        let k = self.consts;
        let v0 = self.link.v;
        let g_ch = self.chopper();
        let v_s = self.link.v_supply;
        // f_o across the sector: from its value at the start (±1) linearly to the opposite.
        let half_pp = 0.5 * self.p.poles as f64;
        let (th, start) = self.sector_angle(sec);
        let f_start = shapes(start + 1e-6)[off].signum();
        let per_rad_e = -2.0 * f_start / FRAC_PI_3;
        let shape = (f_start + per_rad_e * (th - start), per_rad_e * half_pp);
        let x = [i[pp], i[off], self.omega, v0];
        let i_inv0 = (legs[0] - legs[1]) * i[pp] + (legs[2] - legs[1]) * i[off];
        let rect = self.rectifier(-(g_ch + k.g_aux) * v0 - i_inv0, || {
            k.transient_series(legs, shape, (0.0, g_ch), x, self.theta_m, psi, v_s, gear)[4]
        });
        let g_r = if rect { k.g_r } else { 0.0 };
        let [cp, co, cw, cth, cv] =
            k.transient_series(legs, shape, (g_r, g_ch), x, self.theta_m, psi, v_s, gear);
        let mut w_max = 0.0;
        for n in (1..=ORDER).rev() {
            w_max = (w_max + cw[n].abs()) * h;
        }
        if self.theta_m.abs() + (cw[0].abs() + w_max) * h >= self.gear * self.stroke {
            return Err(FALLBACK_STEP);
        }
        let cm: Poly = std::array::from_fn(|n| -cp[n] - co[n]);
        Ok(Commutation {
            h,
            gear,
            legs,
            gates: (gp, gm),
            shape,
            rect,
            g_r,
            g_ch,
            v_s,
            v0,
            th,
            cp,
            co,
            cm,
            cw,
            cth,
            cv,
        })
    }

    /// The first event of a commutation's segment: the outgoing current reaching zero, a
    /// comparator switching its leg, the over-current trip, a sector boundary, a link level or
    /// an edge of the gear's law.
    fn commutation_events(
        &self,
        c: &Commutation,
        psi: f64,
        [pp, mm, off]: [usize; 3],
        sec: usize,
    ) -> First {
        let h = c.h;
        let (gp, gm) = c.gates;
        let mut first = First::within(h);
        first.offer(reach(&c.co, 0.0, -self.i[off].signum(), h), Event::DiodeOff);
        // Each comparator switches its leg when its phase current leaves the band on the side
        // its leg drives it to (the + phase to +I_ref, the − phase to −I_ref).
        let band = 0.5 * self.p.hysteresis_a;
        for (leg, cx, target, g) in [(pp, &c.cp, self.i_ref, gp), (mm, &c.cm, -self.i_ref, gm)] {
            if g == Gate::Upper {
                first.offer(
                    reach(cx, target + band, 1.0, h),
                    Event::Leg(leg, Gate::Lower),
                );
            } else {
                first.offer(
                    reach(cx, target - band, -1.0, h),
                    Event::Leg(leg, Gate::Upper),
                );
            }
        }
        // The comparators do not bound the three currents here: the over-current protection's
        // level is an event too.
        for cx in [&c.cp, &c.co, &c.cm] {
            first.offer(reach(cx, self.trip_a, 1.0, h), Event::Trip);
            first.offer(reach(cx, -self.trip_a, -1.0, h), Event::Trip);
        }
        self.sector_events(sec, &c.cth, h, &mut first);
        self.link_events(&c.cv, c.rect, h, &mut first);
        self.gear_events(psi, &c.cw, &c.cth, h, &mut first);
        first
    }

    /// Puts the state at the end of a commutation's segment on the threshold that ended it
    /// (the outgoing diode blocking, a leg switching, the trip blocking the gates) and closes
    /// the segment.
    fn commutation_end(
        &mut self,
        c: &Commutation,
        first: First,
        [pp, mm, off]: [usize; 3],
        q: Integrals,
    ) {
        let First { tau, what } = first;
        let (ip, mut io) = (eval(&c.cp, tau), eval(&c.co, tau));
        let mut d_th = eval(&c.cth, tau);
        let mut v_end = eval(&c.cv, tau);
        let mut w_end = eval(&c.cw, tau);
        match what {
            Event::DiodeOff => io = 0.0,
            Event::Leg(leg, g) => self.gates[leg] = g,
            Event::Trip => {
                // As the protection acts on a measured current above the level.
                self.block();
                self.limits |= limit::CURRENT | limit::OVERCURRENT_TRIP;
            }
            Event::Commutation(d, _) => d_th = d,
            Event::Link(level) => v_end = level,
            Event::GearSpeed(w) => w_end = w,
            Event::GearTorque(d) => d_th = d,
            Event::End | Event::Upper | Event::Lower | Event::Floating => {}
        }
        self.i[pp] = ip;
        self.i[off] = io;
        self.i[mm] = -ip - io;
        let i_peak = ip.abs().max(io.abs()).max((ip + io).abs());
        let half_pp = 0.5 * self.p.poles as f64;
        self.close(
            what,
            c.th + half_pp * d_th,
            d_th,
            w_end,
            v_end,
            q.peak.max(i_peak),
            q.v_hi,
            q.q,
        );
    }
}
