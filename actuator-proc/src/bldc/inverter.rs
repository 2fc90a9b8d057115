//! The electrics of one fixed step: the averaged R-L-EMF branch, and the switched inverter
//! (eq 3 per phase) with its hysteresis comparators, diodes and floating phase.

use super::{shapes_and_sector, Bldc, Gate};

impl Bldc {
    /// Averaged electrics: the conducting pair as one R-L-EMF branch (2R, 2L, k_t ω) fed with
    /// the voltage the current controller asks for within ± the link voltage. With the gates
    /// blocked the branch sees the diodes: −sign(i)·v_dc while current flows, and no current
    /// unless the back-EMF exceeds the link. Returns (torque, inverter power, copper loss).
    #[inline]
    pub(super) fn averaged(&mut self, i_ref: f64, dt: f64) -> (f64, f64, f64) {
        let (r, l) = (self.p.r_s, self.p.l_s);
        let vdc = self.link.v;
        self.protect(self.i[0].abs());
        let e = self.p.k_t * self.omega;
        let i = self.i[0];
        let v = if self.blocked {
            if i > 0.0 {
                -vdc
            } else if i < 0.0 {
                vdc
            } else {
                e.clamp(-vdc, vdc)
            }
        } else {
            // Current controller as an ideal voltage source within the DC link: it asks for
            // the voltage that removes the error in τ_c = 5 steps, plus R i + e.
            let tau = 5.0 * dt;
            (2.0 * l * (i_ref - i) / tau + 2.0 * r * i + e).clamp(-vdc, vdc)
        };
        let mut next = i + dt * (v - 2.0 * r * i - e) / (2.0 * l);
        if self.blocked && i != 0.0 && next.signum() != i.signum() {
            next = 0.0; // the diodes block
        }
        self.i[0] = next;
        // Power and torque on the step's mean current (see `switched`).
        let ia = 0.5 * (i + next);
        (self.p.k_t * ia, v * ia, 2.0 * r * ia * ia)
    }

    /// The hysteresis comparators: each of the two commutated legs on its own measured phase
    /// current (the + phase to +I_ref, the − phase to −I_ref), the third leg off; all off while
    /// a protection blocks the gates.
    #[inline]
    pub(super) fn compare(&mut self, pp: usize, mm: usize, i_ref: f64) {
        if self.blocked {
            self.gates = [Gate::Off; 3];
            return;
        }
        let i = self.i;
        let band = 0.5 * self.p.hysteresis_a;
        self.gates[3 - pp - mm] = Gate::Off;
        for (x, target) in [(pp, i_ref), (mm, -i_ref)] {
            if i[x] < target - band {
                self.gates[x] = Gate::Upper;
            } else if i[x] > target + band {
                self.gates[x] = Gate::Lower;
            } else if self.gates[x] == Gate::Off {
                self.gates[x] = if i[x] < target {
                    Gate::Upper
                } else {
                    Gate::Lower
                };
            }
        }
    }

    /// Switched electrics: six-step commutation, each of the two commutated legs regulated by
    /// its own hysteresis comparator on its own measured phase current (the + phase to +I_ref,
    /// the − phase to −I_ref), the third leg off. A leg that is off conducts through its diodes
    /// while its phase carries current, and a floating phase starts conducting if its terminal
    /// would leave [0, v_dc]. Returns (torque, inverter power, copper loss).
    #[inline]
    pub(super) fn switched(&mut self, i_ref: f64, dt: f64) -> (f64, f64, f64) {
        let i = self.i;
        self.protect(i[0].abs().max(i[1].abs()).max(i[2].abs()));
        let (f, sec) = shapes_and_sector(self.theta_e);
        let (pp, mm) = self.table[sec];
        self.compare(pp, mm, i_ref);
        let mut ph = self.phases(f, pp, mm);
        let inv_l = 1.0 / self.p.l_s;
        if !self.blocked && !ph.cond[ph.off] {
            if let Some(out) = self.pair_step(&ph, inv_l, dt) {
                return out;
            }
        }
        let next = self.phases_step(&mut ph, inv_l, dt);
        self.i = next;
        // Torque, power and loss on the step's mean current: with L di/dt explicit,
        // Σ v·ī − Σ e·ī − R Σ ī² equals the change of ½LΣi² exactly, so the energy account
        // closes at switching di/dt (the start-of-step current would leave ½LΣΔi² per step,
        // about 1 % of the energy drawn).
        let (v, r) = (ph.v, self.p.r_s);
        let ia: [f64; 3] = std::array::from_fn(|x| 0.5 * (i[x] + next[x]));
        let te = self.lambda * (f[0] * ia[0] + f[1] * ia[1] + f[2] * ia[2]);
        let p_in = v[0] * ia[0] + v[1] * ia[1] + v[2] * ia[2];
        let cu = r * (ia[0] * ia[0] + ia[1] * ia[1] + ia[2] * ia[2]);
        (te, p_in, cu)
    }

    /// The back-EMFs and the terminals of the legs that define one: a gated leg, or an open
    /// one whose phase still carries current through a diode.
    #[inline]
    fn phases(&self, f: [f64; 3], pp: usize, mm: usize) -> Phases {
        let vdc = self.link.v;
        let lam_w = self.lambda * self.omega;
        let e: [f64; 3] = std::array::from_fn(|x| lam_w * f[x]);
        let mut v = [0.0; 3];
        let mut cond = [false; 3];
        for x in 0..3 {
            match self.gates[x] {
                Gate::Upper => {
                    v[x] = vdc;
                    cond[x] = true;
                }
                Gate::Lower => cond[x] = true,
                Gate::Off => {
                    if self.i[x] > 0.0 {
                        cond[x] = true; // lower diode: terminal at 0 V
                    } else if self.i[x] < 0.0 {
                        v[x] = vdc; // upper diode
                        cond[x] = true;
                    }
                }
            }
        }
        Phases {
            f,
            e,
            v,
            cond,
            pp,
            mm,
            off: 3 - pp - mm,
            vdc,
        }
    }

    /// The usual case: the commutated pair conducts (i_+ = −i_−) and the third phase floats
    /// with its terminal inside [0, v_dc]. `None` when that terminal would leave the link.
    #[inline]
    fn pair_step(&mut self, ph: &Phases, inv_l: f64, dt: f64) -> Option<(f64, f64, f64)> {
        let (pp, mm, v, e, f) = (ph.pp, ph.mm, &ph.v, &ph.e, &ph.f);
        let (r, i) = (self.p.r_s, self.i);
        let vn = 0.5 * (v[pp] + v[mm] - e[pp] - e[mm]);
        let u = vn + e[ph.off];
        if !(0.0..=ph.vdc).contains(&u) {
            return None;
        }
        let mut next = i;
        let di = (v[pp] - vn - r * i[pp] - e[pp]) * inv_l;
        next[pp] += dt * di;
        next[mm] = -next[pp];
        self.i = next;
        let ia_p = 0.5 * (i[pp] + next[pp]);
        let te = self.lambda * (f[pp] - f[mm]) * ia_p;
        let p_in = (v[pp] - v[mm]) * ia_p;
        Some((te, p_in, 2.0 * r * ia_p * ia_p))
    }

    /// Every other case: a floating phase whose terminal would leave the link clamps through
    /// a diode, each conducting phase follows eq 3 from the star point, and a phase on its
    /// diodes stops at zero current. Returns the phase currents at the end of the step.
    #[inline]
    fn phases_step(&self, ph: &mut Phases, inv_l: f64, dt: f64) -> [f64; 3] {
        let (r, i) = (self.p.r_s, self.i);
        let mut vn = ph.star_point();
        if ph.clamp_floating(vn) {
            vn = ph.star_point();
        }
        let mut next = i;
        let mut conducting = 0;
        for x in 0..3 {
            if ph.cond[x] {
                next[x] += dt * (ph.v[x] - vn - r * i[x] - ph.e[x]) * inv_l;
                conducting += 1;
            }
        }
        conducting -= self.diodes_block(&mut next);
        if conducting <= 2 {
            // Two conducting phases carry opposite currents (removes rounding drift).
            let (pp, mm, off) = (ph.pp, ph.mm, ph.off);
            if next[off] == 0.0 {
                next[mm] = -next[pp];
            } else if next[mm] == 0.0 {
                next[pp] = -next[off];
            } else if next[pp] == 0.0 {
                next[mm] = -next[off];
            }
        }
        next
    }

    /// A phase on its diodes stops when its current reaches zero; what the step overshot goes
    /// back to the others (Σi = 0). Returns how many phases stopped.
    #[inline]
    fn diodes_block(&self, next: &mut [f64; 3]) -> u32 {
        let i = self.i;
        let mut stopped = 0;
        for x in 0..3 {
            if self.gates[x] == Gate::Off
                && i[x] != 0.0
                && (next[x] == 0.0 || next[x].signum() != i[x].signum())
            {
                let spill = next[x];
                next[x] = 0.0;
                let (y, z) = ((x + 1) % 3, (x + 2) % 3);
                match (next[y] != 0.0, next[z] != 0.0) {
                    (true, true) => {
                        next[y] += 0.5 * spill;
                        next[z] += 0.5 * spill;
                    }
                    (true, false) => next[y] += spill,
                    (false, true) => next[z] += spill,
                    (false, false) => {}
                }
                stopped += 1;
            }
        }
        stopped
    }
}

/// One switched step's view of the phases: the commutated pair, the back-EMFs and the
/// terminals that a leg or a diode defines.
struct Phases {
    /// Back-EMF shapes f_x (eqs 6-8).
    f: [f64; 3],
    /// Back-EMFs e_x = λ ω f_x (V).
    e: [f64; 3],
    /// Terminal voltages of the conducting legs (V).
    v: [f64; 3],
    /// Which phases conduct.
    cond: [bool; 3],
    /// The phase driven positive, the one driven negative, and the one off.
    pp: usize,
    mm: usize,
    off: usize,
    /// The link voltage (V).
    vdc: f64,
}

impl Phases {
    /// The star point from Σi = 0 over the conducting phases (non-conducting ones carry
    /// none); with none conducting, midway between the link and the back-EMFs' extremes.
    #[inline]
    fn star_point(&self) -> f64 {
        let (e, v, cond) = (&self.e, &self.v, &self.cond);
        let (mut s, mut n) = (0.0, 0u32);
        for x in 0..3 {
            if cond[x] {
                s += v[x] - e[x];
                n += 1;
            }
        }
        match n {
            0 => {
                let (hi, lo) = (e[0].max(e[1]).max(e[2]), e[0].min(e[1]).min(e[2]));
                0.5 * (self.vdc - hi - lo)
            }
            _ => s / n as f64,
        }
    }

    /// A floating phase whose terminal (star point `vn` plus its back-EMF) would leave
    /// [0, v_dc] starts conducting through the diode at that rail. Returns whether one did.
    #[inline]
    fn clamp_floating(&mut self, vn: f64) -> bool {
        let mut clamped = false;
        for x in 0..3 {
            if !self.cond[x] {
                let u = vn + self.e[x];
                if u > self.vdc {
                    self.v[x] = self.vdc;
                    self.cond[x] = true;
                    clamped = true;
                } else if u < 0.0 {
                    self.cond[x] = true;
                    clamped = true;
                }
            }
        }
        clamped
    }
}
