//! The usual state's segment: the commutated pair conducting (i_+ = −i_−) on its flat
//! tops, the third phase floating; from its series to its first event and its end.

use std::f64::consts::{FRAC_PI_3, FRAC_PI_6};

use super::roots::{eval, reach, Poly};
use super::{Consts, Event, First, Integrals, Rotor, FALLBACK_STEP, GL_W, GL_X, MAX_SEGMENT_S};
use super::{Q_AUX, Q_CHOPPER, Q_COPPER, Q_FRICTION, Q_GEAR, Q_INVERTER, Q_LOAD, Q_RECTIFIER};
use crate::bldc::{shapes, shapes_and_sector_reduced, Bldc, Gate};

/// A segment of the usual state from now: the pair at s·v, the longest segment `h`, the
/// gear's load law, the link's conductances (rectifier `g_r` when `rect`, chopper `g_ch`) and
/// supply `v_s`, the link at the start `v0`, and the Taylor series of (I, ω, Δθ_m, v).
struct Usual {
    s: f64,
    h: f64,
    gear: Rotor,
    rect: bool,
    g_r: f64,
    g_ch: f64,
    v_s: f64,
    v0: f64,
    ci: Poly,
    cw: Poly,
    cth: Poly,
    cv: Poly,
}

impl Usual {
    /// [`Integrals`] over [0, `tau`] with the rotor at `theta_m`, the bar twisted by `psi`
    /// and the pair's current `i_pair` at the start.
    fn integrals(&self, k: &Consts, theta_m: f64, psi: f64, tau: f64, i_pair: f64) -> Integrals {
        let (ci, cw, cth, cv, gear) = (&self.ci, &self.cw, &self.cth, &self.cv, self.gear);
        let mut q_i = 0.0;
        let mut q = [0.0; 8];
        let (mut peak, mut v_hi) = (i_pair.abs(), self.v0);
        let half = 0.5 * tau;
        for (xg, wg) in GL_X.iter().zip(GL_W) {
            let t = half * (1.0 + xg);
            let w = wg * half;
            let (it, wt, tht, vt) = (eval(ci, t), eval(cw, t), eval(cth, t), eval(cv, t));
            let tb = k.k_vr_g * ((theta_m + tht) * k.inv_g - psi);
            q_i += w * it;
            q[Q_INVERTER] += w * self.s * vt * it;
            q[Q_COPPER] += w * k.two_r * it * it;
            q[Q_FRICTION] += w * k.b_f * wt * wt;
            q[Q_LOAD] += w * tb * wt;
            q[Q_GEAR] += w * ((gear.c - 1.0) * tb + gear.d * wt) * wt;
            q[Q_RECTIFIER] += w * vt * self.g_r * (self.v_s - vt);
            q[Q_CHOPPER] += w * self.g_ch * vt * vt;
            q[Q_AUX] += w * k.g_aux * vt * vt;
            peak = peak.max(it.abs());
            v_hi = v_hi.max(vt);
        }
        Integrals {
            q0: q_i,
            q,
            peak,
            v_hi,
        }
    }
}

impl Bldc {
    /// One segment of the usual state from now, at most `left` long: returns its length and
    /// the integrals of torque, inverter power and chopper power over it, or, when the drive
    /// is not in the usual state, nothing advanced and the fixed step to take instead as a
    /// fraction of `dt_switched_s`.
    pub(super) fn segment(&mut self, psi: f64, left: f64) -> Result<(f64, f64, f64, f64), f64> {
        if self.blocked || self.blocked_steps > 0 {
            return Err(FALLBACK_STEP);
        }
        let i = self.i;
        self.protect(i[0].abs().max(i[1].abs()).max(i[2].abs()));
        if self.blocked {
            return Err(FALLBACK_STEP);
        }
        let (f, sec) = shapes_and_sector_reduced(self.theta_e);
        let (pp, mm) = self.table[sec];
        let off = 3 - pp - mm;
        self.compare(pp, mm, self.i_ref);
        if i[off] != 0.0 {
            return self.transient(psi, left.min(MAX_SEGMENT_S), [pp, mm, off], sec);
        }
        let (s, vn_per_v) = self.pair_voltage(pp, mm, f[off])?;
        let u = self.usual_series(psi, left, s, i[pp])?;
        let (first, th) = self.usual_events(&u, psi, sec, off, f[off], vn_per_v)?;
        let tau = first.tau;
        let q = u.integrals(&self.consts, self.theta_m, psi, tau, i[pp]);
        let (q_te, q_inverter, q_chopper) =
            (self.consts.k_t * q.q0, q.q[Q_INVERTER], q.q[Q_CHOPPER]);
        self.usual_end(&u, first, [pp, mm], th, q);
        Ok((tau, q_te, q_inverter, q_chopper))
    }

    /// The pair's voltage in units of the link's, s, and the star point's, v_n/v, as the
    /// commutated legs set them; `Err` (a fixed step) unless both legs are gated and the
    /// floating terminal lies inside the link.
    fn pair_voltage(&self, pp: usize, mm: usize, f_off: f64) -> Result<(f64, f64), f64> {
        let v0 = self.link.v;
        let (s, vn_per_v) = match (self.gates[pp], self.gates[mm]) {
            (Gate::Upper, Gate::Lower) => (1.0, 0.5),
            (Gate::Lower, Gate::Upper) => (-1.0, 0.5),
            (Gate::Upper, Gate::Upper) => (0.0, 1.0),
            (Gate::Lower, Gate::Lower) => (0.0, 0.0),
            _ => return Err(FALLBACK_STEP),
        };
        let e_off = self.lambda * self.omega * f_off;
        let u = vn_per_v * v0 + e_off;
        if !(0.0..=v0).contains(&u) {
            return Err(FALLBACK_STEP);
        }
        Ok((s, vn_per_v))
    }

    /// The usual state's segment from now with the pair at s·v and current `i_pair`: the
    /// gear's law, the chopper's and the rectifier's states, the longest segment and the
    /// series. `Err` (a fixed step) at high speed, where the floating phase may conduct, or
    /// near the bar's end stop.
    fn usual_series(&mut self, psi: f64, left: f64, s: f64, i_pair: f64) -> Result<Usual, f64> {
        let v0 = self.link.v;
        let k = self.consts;
        let (gear, h_gear) = self.rotor(psi, k.k_t * i_pair);
        let h = left.min(MAX_SEGMENT_S).min(h_gear);

        let g_ch = self.chopper();
        let v_s = self.link.v_supply;
        let rect = self.rectifier(-(g_ch + k.g_aux) * v0 - s * i_pair, || {
            k.series(
                s,
                0.0,
                g_ch,
                [i_pair, self.omega, v0],
                self.theta_m,
                psi,
                v_s,
                gear,
            )[3]
        });
        let g_r = if rect { k.g_r } else { 0.0 };
        let [ci, cw, cth, cv] = k.series(
            s,
            g_r,
            g_ch,
            [i_pair, self.omega, v0],
            self.theta_m,
            psi,
            v_s,
            gear,
        );

        // Speeds at which the floating terminal could leave [0, v] with the pair at ±v/2.
        let w_max = cw[0].abs() + (cw[1].abs() + (cw[2].abs() + cw[3].abs() * h) * h) * h;
        let dv_max = (cv[1].abs() + (cv[2].abs() + cv[3].abs() * h) * h) * h;
        if s != 0.0 && self.lambda * w_max >= 0.5 * (v0 - dv_max) {
            // High speed: the floating phase may conduct through its diodes all along;
            // the fixed-step model at its own step takes it.
            return Err(1.0);
        }
        // The bar's end stop is the fixed-step model's to handle.
        if self.theta_m.abs() + w_max * h >= self.gear * self.stroke {
            return Err(FALLBACK_STEP);
        }
        Ok(Usual {
            s,
            h,
            gear,
            rect,
            g_r,
            g_ch,
            v_s,
            v0,
            ci,
            cw,
            cth,
            cv,
        })
    }

    /// The first event of a usual segment: a comparator, a commutation, the floating
    /// terminal's sign condition (pair legs both at one rail), a link level or an edge of the
    /// gear's law; with the electrical angle unwrapped into sector `sec`. `Err` (a fixed step)
    /// on a zero of the floating phase's back-EMF that it leaves the wrong way.
    fn usual_events(
        &self,
        u: &Usual,
        psi: f64,
        sec: usize,
        off: usize,
        f_off: f64,
        vn_per_v: f64,
    ) -> Result<(First, f64), f64> {
        let (s, h, ci, cw, cth) = (u.s, u.h, &u.ci, &u.cw, &u.cth);
        let mut first = First::within(h);
        let band = 0.5 * self.p.hysteresis_a;
        let (hi, lo) = (self.i_ref + band, self.i_ref - band);
        if s >= 0.0 {
            first.offer(reach(ci, hi, 1.0, h), Event::Upper);
        }
        if s <= 0.0 {
            first.offer(reach(ci, lo, -1.0, h), Event::Lower);
        }
        let (th, start) = self.sector_events(sec, cth, h, &mut first);
        let half_pp = 0.5 * self.p.poles as f64;
        if s == 0.0 {
            // The floating terminal stays inside the link while λ ω f_off keeps the sign that
            // puts it there: up to a zero of ω or of f_off (mid-sector).
            let keep = if vn_per_v == 0.0 { 1.0 } else { -1.0 };
            let d_mid = (start + FRAC_PI_6 - th) / half_pp;
            if self.omega * f_off == 0.0 {
                // On a zero of the product: go on only if it leaves the zero the right way.
                // f_off falls (or rises) linearly across the sector, through 0 at mid-sector.
                let f0 = shapes(start + 1e-6)[off].signum();
                let t = h.min(1e-7);
                let f_t = f0 * (1.0 - 2.0 * (th + half_pp * eval(cth, t) - start) / FRAC_PI_3);
                if keep * eval(cw, t) * f_t < 0.0 {
                    return Err(FALLBACK_STEP);
                }
            }
            if cw[0] != 0.0 {
                first.offer(reach(cw, 0.0, -cw[0].signum(), h), Event::Floating);
            }
            if d_mid != 0.0 {
                first.offer(reach(cth, d_mid, d_mid.signum(), h), Event::Floating);
            }
        }
        self.link_events(&u.cv, u.rect, h, &mut first);
        self.gear_events(psi, cw, cth, h, &mut first);
        Ok((first, th))
    }

    /// Puts the state at the end of a usual segment exactly on the threshold that ended it (a
    /// comparator's switches the pair's legs) and closes the segment.
    fn usual_end(&mut self, u: &Usual, first: First, [pp, mm]: [usize; 2], th: f64, q: Integrals) {
        let First { tau, what } = first;
        let band = 0.5 * self.p.hysteresis_a;
        let (hi, lo) = (self.i_ref + band, self.i_ref - band);
        let mut i_end = eval(&u.ci, tau);
        let mut d_th = eval(&u.cth, tau);
        let mut v_end = eval(&u.cv, tau);
        let mut w_end = eval(&u.cw, tau);
        match what {
            Event::Upper => {
                i_end = hi;
                self.gates[pp] = Gate::Lower;
                self.gates[mm] = Gate::Upper;
            }
            Event::Lower => {
                i_end = lo;
                self.gates[pp] = Gate::Upper;
                self.gates[mm] = Gate::Lower;
            }
            Event::Commutation(d, _) => d_th = d,
            Event::Link(level) => v_end = level,
            Event::GearSpeed(w) => w_end = w,
            Event::GearTorque(d) => d_th = d,
            Event::End | Event::Floating | Event::Leg(..) | Event::DiodeOff | Event::Trip => {}
        }
        self.i[pp] = i_end;
        self.i[mm] = -i_end;
        let half_pp = 0.5 * self.p.poles as f64;
        self.close(
            what,
            th + half_pp * d_th,
            d_th,
            w_end,
            v_end,
            q.peak.max(i_end.abs()),
            q.v_hi,
            q.q,
        );
    }
}
