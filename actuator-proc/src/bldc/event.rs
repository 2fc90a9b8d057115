//! Event-driven integration of the switched electrics (`bldc.switched_integration = "event"`).
//!
//! Between two events (a hysteresis comparator switching, a commutation, a DC-link threshold,
//! a control update) the drive in its usual state is a linear time-invariant system: two
//! phases of the commutated pair conduct (i_+ = −i_− = I) through legs that each sit at the
//! link or at 0 V, the third phase floats with no current, the back-EMF shapes of the pair are
//! on their flat tops (f_+ = 1, f_− = −1 over the whole sector), and the rectifier, the chopper
//! and ψ are constant. With s ∈ {+1, 0, −1} the pair voltage in units of the link voltage v:
//!
//! ```text
//! 2 L_s dI/dt = s v − 2 R_s I − k_t ω                        (eq 3 for the pair, e_+ − e_− = k_t ω)
//! J dω/dt     = k_t I − B_f ω − k_vr (θ_m/G − ψ)/G           (eq 4, T_e = λ(f_+ − f_−) I = k_t I)
//! dθ_m/dt     = ω
//! C dv/dt     = g_r (V_app − v) − s I − g_ch v               (the DC link, dc_link.rs)
//! ```
//!
//! x' = A x + b is integrated from event to event by its Taylor series to fifth order,
//! x(τ) = Σ c_k τ^k with c_1 = A x_0 + b and c_{k+1} = A c_k/(k+1), over segments of at most
//! [`MAX_SEGMENT_S`] = 50 µs: the fastest pole left (the link's R_s C = 220 µs) makes the
//! truncation error (50/220)⁶/720 ≈ 2e-7 of a deviation. Each event is the first root of the
//! series in τ: Newton kept in a bracket on the whole polynomial where its slope cannot change
//! sign within the segment (the usual case), else on the monotone pieces of its cubic part and
//! polished on the whole; the state is put exactly on the threshold there. Torque, power,
//! losses and the link's energy are integrated over the segment by 2-point Gauss-Legendre
//! quadrature (exact to degree 3; with the nearly linear currents and voltages of a segment
//! the link's energy account closes to about 1e-7 over a run).
//!
//! A commutation leaves the outgoing phase carrying current through one of its diodes for up to
//! a millisecond (at the current limit) while the new pair is regulated: all three phases
//! conduct into the star point, and the outgoing phase's back-EMF shape moves along its slope,
//! f_o = f_o0 + k_o Δθ_m. Those segments ([`Consts::transient_series`], [`Bldc::transient`])
//! carry the products ω·Δθ_m and i_o·Δθ_m as Cauchy products in the same Taylor recursion, and
//! end when the outgoing current reaches zero (its diode blocks), a comparator switches, a
//! phase current reaches the over-current trip, or at the events above.
//!
//! What is left (the gates blocked by a protection, a floating terminal about to leave [0, v],
//! a leg not yet gated, the bar near its end stop, speeds where the floating phase's back-EMF
//! reaches half the link) is taken by the fixed-step model, at [`FALLBACK_STEP`] ×
//! `dt_switched_s` (at `dt_switched_s` at high speed), until a segment can start again: the
//! same equations, so the two paths agree where they meet.

use std::f64::consts::TAU;

use super::{limit, Bldc, Gate};

mod commutation;
mod roots;
mod series;
mod sources;
mod usual;

/// Longest segment between two evaluations of the Taylor series (s).
pub const MAX_SEGMENT_S: f64 = 50e-6;

/// The fixed step taken outside the usual state, as a fraction of `dt_switched_s`: those
/// stretches (commutations, protections) are short, so a finer step costs little and keeps
/// them as accurate as the segments around them.
pub const FALLBACK_STEP: f64 = 0.1;

/// Indices of a segment's energy integrals (J): drawn by the inverter, copper, friction, bar
/// work, gear loss, delivered by the rectifier, dumped in the chopper, drawn by the
/// auxiliary load.
const Q_INVERTER: usize = 0;
const Q_COPPER: usize = 1;
const Q_FRICTION: usize = 2;
const Q_LOAD: usize = 3;
const Q_GEAR: usize = 4;
const Q_RECTIFIER: usize = 5;
const Q_CHOPPER: usize = 6;
const Q_AUX: usize = 7;

/// Gauss-Legendre nodes on [−1, 1] and weights (2 points, exact to degree 3).
const GL_X: [f64; 2] = [-0.577_350_269_189_625_8, 0.577_350_269_189_625_8];
const GL_W: [f64; 2] = [1.0, 1.0];

/// Counters of the event-driven integration since the drive was made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EventStats {
    /// Segments integrated in closed form.
    pub segments: u64,
    /// Hysteresis comparator events.
    pub switchings: u64,
    /// Commutations located.
    pub commutations: u64,
    /// DC-link events (rectifier conducting or blocking, chopper on or off, over-voltage).
    pub link_events: u64,
    /// Fixed steps taken outside the usual state.
    pub fixed_steps: u64,
    /// Edges of the gear's loss law crossed (speed ±ω_ε, bar torque 0).
    pub gear_events: u64,
}

/// The drive's constants as the segment equations use them (no division per segment).
#[derive(Debug, Clone, Copy)]
pub(in crate::bldc) struct Consts {
    /// 1/(2 L_s), R_s/L_s, k_t/(2 L_s).
    inv_2l: f64,
    r_l: f64,
    kt_2l: f64,
    /// k_t/J, B_f/J, k_vr/(G² J).
    kt_j: f64,
    bf_j: f64,
    kappa_j: f64,
    /// 1/C, the rectifier's, the chopper's and the auxiliary load's conductances.
    inv_c: f64,
    g_r: f64,
    g_ch: f64,
    g_aux: f64,
    /// G, 1/G, k_vr/G, k_t, 2 R_s, B_f.
    g: f64,
    inv_g: f64,
    k_vr_g: f64,
    k_t: f64,
    two_r: f64,
    b_f: f64,
    /// λ_p = k_t/2 (V·s/rad per phase), 1/L_s, λ_p/J, 1/J.
    lam: f64,
    inv_l: f64,
    lam_j: f64,
    inv_j: f64,
}

/// What ended a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Event {
    /// The segment's length ran out.
    End,
    /// I reached the upper comparator threshold.
    Upper,
    /// I reached the lower comparator threshold.
    Lower,
    /// θ_e reached the sector boundary Δθ_m (commutation); +1 forwards, −1 backwards.
    Commutation(f64, f64),
    /// The floating terminal's sign condition (s = 0) is about to fail.
    Floating,
    /// The link reached a level; the exact value to put it at.
    Link(f64),
    /// During a commutation: a comparator switches leg `.0` to `.1`.
    Leg(usize, Gate),
    /// During a commutation: the outgoing phase's current reached zero; its diode blocks.
    DiodeOff,
    /// During a commutation: a phase current reached the over-current trip level.
    Trip,
    /// The rotor's speed reached an edge of the gear's loss law (±ω_ε); the speed to put it
    /// at, a hair past the edge.
    GearSpeed(f64),
    /// The bar's torque reached zero (the gear's power flow reverses); the Δθ_m to put the
    /// rotor at, a hair past it.
    GearTorque(f64),
}

/// The gearbox's load on the rotor over one segment in the linear form T_l = c T_b + d ω
/// ([`super::GearLoss`], docs/model.md D45): away from zero speed c = 1/η (driving) or η
/// (back-driven) and d = 0; within ±ω_ε, c = 1 and d = |μ T_b|/ω_ε with T_b and the branch of
/// μ (driving or back-driven) taken at the segment's start (T_b moves by less than 1e-5 of
/// itself over a segment at such speeds; a reversal within a segment keeps the branch it
/// started with: the loss d ω² stays dissipative, only its coefficient is the other
/// direction's until the segment ends, at most 50 µs).
/// Carried into the rotor equation as k_vr c/(G² J) and (B_f + d)/J.
#[derive(Debug, Clone, Copy)]
pub(super) struct Rotor {
    kappa_j: f64,
    bf_j: f64,
    c: f64,
    d: f64,
}

/// Relative distance past an edge of the gear's loss law at which a gear event leaves the
/// rotor, so that the next segment starts on the far side.
const GEAR_NUDGE: f64 = 1e-12;

/// The earliest event offered so far within a segment of length `tau`: the segment ends there.
struct First {
    /// Where the segment ends (s from its start).
    tau: f64,
    /// What ends it.
    what: Event,
}

impl First {
    /// A segment of at most `h` with no event yet.
    fn within(h: f64) -> Self {
        First {
            tau: h,
            what: Event::End,
        }
    }

    /// Keeps event `e` at `t` if it comes before every event offered so far.
    fn offer(&mut self, t: Option<f64>, e: Event) {
        if let Some(t) = t.filter(|&t| t < self.tau) {
            self.tau = t;
            self.what = e;
        }
    }
}

/// A segment's integrals over [0, τ] by 2-point Gauss-Legendre: `q0` is ∫ I dt in the usual
/// state and ∫ T_e dt in a commutation, `q` the energies (indexed by `Q_*`), with the peaks
/// of the phase currents and of the link voltage at the nodes.
struct Integrals {
    q0: f64,
    q: [f64; 8],
    peak: f64,
    v_hi: f64,
}

impl Bldc {
    /// Advances the switched drive event by event over `n` electrical steps, running the
    /// control loops at their instants as the fixed-step model does; returns the sums of
    /// torque, inverter power and chopper power in units of one step (integral / dt), so that
    /// the interval's means are formed as in the fixed-step model.
    pub(super) fn run_events(&mut self, psi: f64, n: u64) -> (f64, f64, f64) {
        let (mut te, mut p, mut ch) = (0.0, 0.0, 0.0);
        let inv_dt = 1.0 / self.dt;
        let mut k = 0u64;
        while k < n {
            if self.sub_count == 0 {
                self.control_update();
            }
            let m = (u64::from(self.sub_per_control - self.sub_count)).min(n - k);
            let span = m as f64 * self.dt;
            let mut t = 0.0;
            let mut stalled = 0;
            while span - t > 1e-15 {
                let left = span - t;
                // Events at the same instant change the state each time (gates, mode, sector);
                // should they ever stop making progress, a fixed step moves time on.
                let segment = if stalled < 8 {
                    self.segment(psi, left)
                } else {
                    Err(FALLBACK_STEP)
                };
                let (h, a, b, c) = match segment {
                    Ok(r) => {
                        stalled = if r.0 < 1e-12 { stalled + 1 } else { 0 };
                        r
                    }
                    Err(fraction) => {
                        stalled = 0;
                        let h = (self.dt * fraction).min(left);
                        self.count_down_block();
                        self.stats.fixed_steps += 1;
                        let (a, b, c) = self.fixed_step(psi, h);
                        (h, a * h, b * h, c * h)
                    }
                };
                t += h;
                te += a * inv_dt;
                p += b * inv_dt;
                ch += c * inv_dt;
            }
            self.sub_count =
                ((u64::from(self.sub_count) + m) % u64::from(self.sub_per_control)) as u32;
            self.sub_in_interval += m;
            k += m;
        }
        (te, p, ch)
    }

    /// Ends a segment that ended with `what`: the rotor at ω `w_end`, advanced by `d_th`
    /// (θ_e at `te`, unwrapped), the link at `v_end`; the peaks and the energy integrals
    /// `q` (indexed by `Q_*`) booked.
    #[allow(clippy::too_many_arguments)]
    fn close(
        &mut self,
        what: Event,
        te: f64,
        d_th: f64,
        w_end: f64,
        v_end: f64,
        peak: f64,
        v_hi: f64,
        q: [f64; 8],
    ) {
        match what {
            Event::Upper | Event::Lower | Event::Leg(..) => self.stats.switchings += 1,
            Event::Commutation(..) => self.stats.commutations += 1,
            Event::Link(_) => self.stats.link_events += 1,
            Event::GearSpeed(_) | Event::GearTorque(_) => self.stats.gear_events += 1,
            Event::End | Event::Floating | Event::DiodeOff | Event::Trip => {}
        }
        self.omega = w_end;
        self.theta_m += d_th;
        let mut te = te;
        if let Event::Commutation(_, dir) = what {
            // Past the boundary by a hair, so that the new sector is the one computed next.
            te += dir * 1e-12;
        }
        // te lies within a sector of [0, 2π] (or a hair beyond): one wrap at most.
        self.theta_e = if te >= TAU {
            te - TAU
        } else if te < 0.0 {
            te + TAU
        } else {
            te
        };
        self.link.v = v_end;
        self.peak = self.peak.max(peak);
        self.v_max = self.v_max.max(v_hi).max(v_end);
        if peak >= self.p.current_limit_a {
            self.limits |= limit::CURRENT;
        }
        self.energy.electrical_in += q[Q_INVERTER];
        self.energy.copper += q[Q_COPPER];
        self.energy.friction += q[Q_FRICTION];
        self.energy.load += q[Q_LOAD];
        self.energy.gear += q[Q_GEAR];
        self.link.energy.rectifier += q[Q_RECTIFIER];
        self.link.energy.chopper += q[Q_CHOPPER];
        self.link.energy.inverter += q[Q_INVERTER];
        self.link.energy.aux += q[Q_AUX];
        self.stats.segments += 1;
    }
}
