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

use std::f64::consts::{FRAC_PI_3, FRAC_PI_6, TAU};

use super::{limit, shapes, shapes_and_sector_reduced, Bldc, Gate};

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

/// Order of the Taylor series.
const ORDER: usize = 5;

/// A polynomial Σ c_k τ^k of degree [`ORDER`] (degree 3 in the tests of [`reach`]).
type Poly = [f64; ORDER + 1];

#[inline]
fn eval(c: &Poly, t: f64) -> f64 {
    let mut x = c[ORDER];
    for k in (0..ORDER).rev() {
        x = c[k] + t * x;
    }
    x
}

#[inline]
fn slope(c: &Poly, t: f64) -> f64 {
    let mut x = ORDER as f64 * c[ORDER];
    for k in (1..ORDER).rev() {
        x = k as f64 * c[k] + t * x;
    }
    x
}

/// The cubic part c0 + c1 τ + c2 τ² + c3 τ³ of a polynomial.
#[inline]
fn cubic(c: &Poly, t: f64) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * c[3]))
}

#[inline]
fn cubic_slope(c: &Poly, t: f64) -> f64 {
    c[1] + t * (2.0 * c[2] + t * 3.0 * c[3])
}

/// The direction a polynomial leaves its starting value in: the sign of its first non-zero
/// coefficient after c0 (0 if it stays).
#[inline]
fn leaving(c: &Poly) -> f64 {
    c[1..]
        .iter()
        .find(|x| **x != 0.0)
        .map_or(0.0, |x| x.signum())
}

/// The first τ in [0, h] at which polynomial `c` reaches `level` travelling in direction
/// `dir` (+1 upwards, −1 downwards); `None` if it does not within h. One already beyond the
/// level, or on it and moving on, reaches it at once. The crossing is found on the cubic part
/// (monotone pieces, safeguarded Newton) and polished by Newton on the whole polynomial; the
/// higher terms are below 1e-6 of the cubic ones over a segment.
#[inline]
pub(crate) fn reach(c: &Poly, level: f64, dir: f64, h: f64) -> Option<f64> {
    let g0 = dir * (c[0] - level);
    let mut bound = 0.0;
    for k in (1..=ORDER).rev() {
        bound = (bound + c[k].abs()) * h;
    }
    if g0 + bound < 0.0 {
        return None;
    }
    // The usual case: the slope keeps the sign of c1 over [0, h] (its change is bounded by
    // Σ k |c_k| h^(k−1) < |c1|), so g is monotone: Newton on the whole polynomial from the
    // linear estimate, kept in the bracket.
    let mut dslope = 0.0;
    for k in (2..=ORDER).rev() {
        dslope = dslope * h + k as f64 * c[k].abs();
    }
    dslope *= h;
    if dslope < c[1].abs() {
        if g0 > 0.0 || (g0 == 0.0 && dir * c[1] > 0.0) {
            return Some(0.0);
        }
        if dir * c[1] <= 0.0 || dir * (eval(c, h) - level) <= 0.0 {
            return None;
        }
        // Newton converges quadratically here (|c2| τ ≪ |c1|): after a step of 1e-10 s the
        // error left is below 1e-16 s.
        let t0 = (-g0 / (dir * c[1])).min(h);
        return Some(root(
            |t| dir * (eval(c, t) - level),
            |t| dir * slope(c, t),
            (0.0, h),
            t0,
            1e-10,
        ));
    }
    let t = reach_cubic(c, level, dir, h)?;
    if t == 0.0 {
        return Some(0.0);
    }
    let mut t1 = t;
    for _ in 0..2 {
        let d = slope(c, t1);
        if d == 0.0 {
            break;
        }
        t1 -= (eval(c, t1) - level) / d;
    }
    Some(if t1 > 0.0 && t1 <= h && (t1 - t).abs() < 1e-9 {
        t1
    } else {
        t
    })
}

fn reach_cubic(c: &Poly, level: f64, dir: f64, h: f64) -> Option<f64> {
    let g = |t: f64| dir * (cubic(c, t) - level);
    let g0 = g(0.0);
    if g0 > 0.0 || (g0 == 0.0 && dir * leaving(c) > 0.0) {
        return Some(0.0);
    }
    // Monotone pieces: split at the turning points (roots of the slope) inside (0, h).
    let mut cuts = [h; 3];
    let mut n = 0;
    let (a, b, cc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut push = |t: f64| {
        if t > 0.0 && t < h {
            cuts[n] = t;
            n += 1;
        }
    };
    if a != 0.0 {
        let disc = b * b - 4.0 * a * cc;
        if disc >= 0.0 {
            let q = -0.5 * (b + b.signum() * disc.sqrt());
            if q != 0.0 {
                push(q / a);
                push(cc / q);
            } else {
                push(0.0);
            }
        }
    } else if b != 0.0 {
        push(-cc / b);
    }
    if n == 2 && cuts[0] > cuts[1] {
        cuts.swap(0, 1);
    }
    cuts[n] = h;
    let mut lo = 0.0;
    for &hi in &cuts[..=n] {
        // Strictly past the level: a cubic that only touches it (or stays on it) goes on.
        let (glo, ghi) = (g(lo), g(hi));
        if ghi > 0.0 {
            let t0 = lo + (hi - lo) * (-glo / (ghi - glo));
            let dg = |t: f64| dir * cubic_slope(c, t);
            return Some(root(g, dg, (lo, hi), t0, 1e-14));
        }
        lo = hi;
    }
    None
}

/// The root of monotone `g` (slope `dg`) in `[lo, hi]` with g(lo) ≤ 0 ≤ g(hi), by Newton
/// from `t` kept in the bracket, until a step is below `tol` (s).
fn root(
    g: impl Fn(f64) -> f64,
    dg: impl Fn(f64) -> f64,
    (mut lo, mut hi): (f64, f64),
    mut t: f64,
    tol: f64,
) -> f64 {
    for _ in 0..60 {
        let gt = g(t);
        if gt == 0.0 {
            return t;
        }
        if gt > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let step = gt / dg(t);
        let next = t - step;
        if next > lo && next < hi {
            if step.abs() <= tol {
                return next;
            }
            t = next;
        } else {
            if hi - lo <= 1e-14 {
                return hi;
            }
            t = 0.5 * (lo + hi);
        }
    }
    hi
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

/// The drive's constants as the segment equations use them (no division per segment).
#[derive(Debug, Clone, Copy)]
pub(super) struct Consts {
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

/// 1/n for the Taylor recursion.
const INV_N: [f64; ORDER + 1] = [1.0, 1.0, 0.5, 1.0 / 3.0, 0.25, 0.2];

impl Consts {
    pub(super) fn new(p: &super::BldcParams, link: &crate::DcLinkParams, k_vr: f64) -> Self {
        let g = p.gear();
        Consts {
            inv_2l: 1.0 / (2.0 * p.l_s),
            r_l: p.r_s / p.l_s,
            kt_2l: p.k_t / (2.0 * p.l_s),
            kt_j: p.k_t / p.j_rot,
            bf_j: p.b_f / p.j_rot,
            kappa_j: k_vr / (g * g * p.j_rot),
            inv_c: 1.0 / link.capacitance_f,
            g_r: 1.0 / link.supply_resistance_ohm,
            g_ch: 1.0 / link.chopper_resistance_ohm,
            g_aux: link.aux_conductance(p.v_dc),
            g,
            inv_g: 1.0 / g,
            k_vr_g: k_vr / g,
            lam: 0.5 * p.k_t,
            inv_l: 1.0 / p.l_s,
            lam_j: 0.5 * p.k_t / p.j_rot,
            inv_j: 1.0 / p.j_rot,
            k_t: p.k_t,
            two_r: 2.0 * p.r_s,
            b_f: p.b_f,
        }
    }

    /// Taylor coefficients of (I, ω, Δθ_m, v) from (I, ω, v) at the segment's start, with
    /// the pair at s·v, the rectifier's and chopper's conductances `g_r`, `g_ch`, the rotor
    /// at `theta_m` and the bar twisted by `psi` at the bogie, the supply at `v_s`, and the
    /// gearbox's load on the rotor as `gear` makes it over the segment.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn series(
        &self,
        s: f64,
        g_r: f64,
        g_ch: f64,
        x: [f64; 3],
        theta_m: f64,
        psi: f64,
        v_s: f64,
        gear: Rotor,
    ) -> [Poly; 4] {
        let g_v = (g_r + g_ch + self.g_aux) * self.inv_c;
        let s_c = s * self.inv_c;
        let s_2l = s * self.inv_2l;
        let (kappa_j, bf_j) = (gear.kappa_j, gear.bf_j);
        let a_x = |x: [f64; 4]| {
            [
                s_2l * x[3] - self.r_l * x[0] - self.kt_2l * x[1],
                self.kt_j * x[0] - bf_j * x[1] - kappa_j * x[2],
                x[1],
                -g_v * x[3] - s_c * x[0],
            ]
        };
        // θ_m is carried as Δθ_m from the segment's start (its coefficients stay small).
        let x0 = [x[0], x[1], 0.0, x[2]];
        let mut ck = a_x(x0);
        ck[1] -= kappa_j * (theta_m - self.g * psi);
        ck[3] += g_r * v_s * self.inv_c;
        let mut out = [[0.0; ORDER + 1]; 4];
        for k in 0..4 {
            out[k][0] = x0[k];
            out[k][1] = ck[k];
        }
        for (n, inv) in INV_N.iter().enumerate().skip(2) {
            ck = a_x(ck).map(|x| x * inv);
            for k in 0..4 {
                out[k][n] = ck[k];
            }
        }
        out
    }

    /// Taylor coefficients of (i_+, i_o, ω, Δθ_m, v) during a commutation: the two commutated
    /// phases on their legs (`s_p`, `s_m` = 1 at the link, 0 at 0 V) and the outgoing phase on
    /// its diode (`s_o`), all three conducting into the star point (v_n = Σ(v_x − e_x)/3,
    /// eq 3 per phase). Its back-EMF shape falls or rises linearly across the sector,
    /// f_o = f_o0 + k_o Δθ_m, so e_o = λ ω f_o and T_e = λ(2 i_+ + (1 + f_o) i_o) (eq 5) carry
    /// the products ω·Δθ_m and i_o·Δθ_m, taken into the recursion as Cauchy products.
    #[allow(clippy::too_many_arguments)]
    fn transient_series(
        &self,
        legs: [f64; 3],
        (f_o0, k_o): (f64, f64),
        (g_r, g_ch): (f64, f64),
        x: [f64; 4],
        theta_m: f64,
        psi: f64,
        v_s: f64,
        gear: Rotor,
    ) -> [Poly; 5] {
        let [s_p, s_m, s_o] = legs;
        let sum_s = s_p + s_m + s_o;
        let g_v = (g_r + g_ch + self.g_aux) * self.inv_c;
        let (kappa_j, bf_j) = (gear.kappa_j, gear.bf_j);
        // out[k][n]: state k = (i_+, i_o, ω, Δθ_m, v), coefficient n.
        let mut out = [[0.0; ORDER + 1]; 5];
        out[0][0] = x[0];
        out[1][0] = x[1];
        out[2][0] = x[2];
        out[4][0] = x[3];
        for n in 0..ORDER {
            let (mut wth, mut ith) = (0.0, 0.0);
            for j in 0..=n {
                wth += out[2][j] * out[3][n - j];
                ith += out[1][j] * out[3][n - j];
            }
            let [ip, io, w, th, v] = [out[0][n], out[1][n], out[2][n], out[3][n], out[4][n]];
            let e_o = self.lam * (f_o0 * w + k_o * wth);
            let vn = (sum_s * v - e_o) * (1.0 / 3.0);
            let mut d = [
                (s_p * v - vn - self.lam * w) * self.inv_l - self.r_l * ip,
                (s_o * v - vn - e_o) * self.inv_l - self.r_l * io,
                self.lam_j * (2.0 * ip + (1.0 + f_o0) * io + k_o * ith) - bf_j * w - kappa_j * th,
                w,
                -g_v * v - ((s_p - s_m) * ip + (s_o - s_m) * io) * self.inv_c,
            ];
            if n == 0 {
                d[2] -= kappa_j * (theta_m - self.g * psi);
                d[4] += g_r * v_s * self.inv_c;
            }
            for k in 0..5 {
                out[k][n + 1] = d[k] * INV_N[n + 1];
            }
        }
        out
    }
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

    /// One segment of the usual state from now, at most `left` long: returns its length and
    /// the integrals of torque, inverter power and chopper power over it, or, when the drive
    /// is not in the usual state, nothing advanced and the fixed step to take instead as a
    /// fraction of `dt_switched_s`.
    fn segment(&mut self, psi: f64, left: f64) -> Result<(f64, f64, f64, f64), f64> {
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
        let v0 = self.link.v;
        let (s, vn_per_v) = match (self.gates[pp], self.gates[mm]) {
            (Gate::Upper, Gate::Lower) => (1.0, 0.5),
            (Gate::Lower, Gate::Upper) => (-1.0, 0.5),
            (Gate::Upper, Gate::Upper) => (0.0, 1.0),
            (Gate::Lower, Gate::Lower) => (0.0, 0.0),
            _ => return Err(FALLBACK_STEP),
        };
        let e_off = self.lambda * self.omega * f[off];
        let u = vn_per_v * v0 + e_off;
        if !(0.0..=v0).contains(&u) {
            return Err(FALLBACK_STEP);
        }
        let k = self.consts;
        let i_pair = i[pp];
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

        // The first event.
        let mut first = First::within(h);
        let band = 0.5 * self.p.hysteresis_a;
        let (hi, lo) = (self.i_ref + band, self.i_ref - band);
        if s >= 0.0 {
            first.offer(reach(&ci, hi, 1.0, h), Event::Upper);
        }
        if s <= 0.0 {
            first.offer(reach(&ci, lo, -1.0, h), Event::Lower);
        }
        let (th, start) = self.sector_events(sec, &cth, h, &mut first);
        let half_pp = 0.5 * self.p.poles as f64;
        if s == 0.0 {
            // The floating terminal stays inside the link while λ ω f_off keeps the sign that
            // puts it there: up to a zero of ω or of f_off (mid-sector).
            let keep = if vn_per_v == 0.0 { 1.0 } else { -1.0 };
            let d_mid = (start + FRAC_PI_6 - th) / half_pp;
            if self.omega * f[off] == 0.0 {
                // On a zero of the product: go on only if it leaves the zero the right way.
                // f_off falls (or rises) linearly across the sector, through 0 at mid-sector.
                let f0 = shapes(start + 1e-6)[off].signum();
                let t = h.min(1e-7);
                let f_t = f0 * (1.0 - 2.0 * (th + half_pp * eval(&cth, t) - start) / FRAC_PI_3);
                if keep * eval(&cw, t) * f_t < 0.0 {
                    return Err(FALLBACK_STEP);
                }
            }
            if cw[0] != 0.0 {
                first.offer(reach(&cw, 0.0, -cw[0].signum(), h), Event::Floating);
            }
            if d_mid != 0.0 {
                first.offer(reach(&cth, d_mid, d_mid.signum(), h), Event::Floating);
            }
        }
        self.link_events(&cv, rect, h, &mut first);
        self.gear_events(psi, &cw, &cth, h, &mut first);

        // Integrals over [0, τ] by 2-point Gauss-Legendre.
        let mut q_i = 0.0;
        let mut q = [0.0; 8];
        let (mut peak, mut v_hi) = (i_pair.abs(), v0);
        let First { tau, what } = first;
        let half = 0.5 * tau;
        for (xg, wg) in GL_X.iter().zip(GL_W) {
            let t = half * (1.0 + xg);
            let w = wg * half;
            let (it, wt, tht, vt) = (eval(&ci, t), eval(&cw, t), eval(&cth, t), eval(&cv, t));
            let tb = k.k_vr_g * ((self.theta_m + tht) * k.inv_g - psi);
            q_i += w * it;
            q[Q_INVERTER] += w * s * vt * it;
            q[Q_COPPER] += w * k.two_r * it * it;
            q[Q_FRICTION] += w * k.b_f * wt * wt;
            q[Q_LOAD] += w * tb * wt;
            q[Q_GEAR] += w * ((gear.c - 1.0) * tb + gear.d * wt) * wt;
            q[Q_RECTIFIER] += w * vt * g_r * (v_s - vt);
            q[Q_CHOPPER] += w * g_ch * vt * vt;
            q[Q_AUX] += w * k.g_aux * vt * vt;
            peak = peak.max(it.abs());
            v_hi = v_hi.max(vt);
        }

        // The state at τ, put exactly on the threshold that ended the segment.
        let mut i_end = eval(&ci, tau);
        let mut d_th = eval(&cth, tau);
        let mut v_end = eval(&cv, tau);
        let mut w_end = eval(&cw, tau);
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
        self.close(
            what,
            th + half_pp * d_th,
            d_th,
            w_end,
            v_end,
            peak.max(i_end.abs()),
            v_hi,
            q,
        );
        Ok((tau, k.k_t * q_i, q[Q_INVERTER], q[Q_CHOPPER]))
    }

    /// One segment of a commutation: the outgoing phase `off` still carries current through
    /// its diode while the commutated pair `pp`, `mm` is regulated by its comparators, all
    /// three conducting ([`Consts::transient_series`]), at most `h` long. Ends at the first of:
    /// the outgoing current reaching zero, a comparator switching, a sector boundary, a link
    /// level. Returns what [`Bldc::segment`] returns.
    fn transient(
        &mut self,
        psi: f64,
        h: f64,
        [pp, mm, off]: [usize; 3],
        sec: usize,
    ) -> Result<(f64, f64, f64, f64), f64> {
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

        let mut first = First::within(h);
        first.offer(reach(&co, 0.0, -i[off].signum(), h), Event::DiodeOff);
        // Each comparator switches its leg when its phase current leaves the band on the side
        // its leg drives it to (the + phase to +I_ref, the − phase to −I_ref).
        let band = 0.5 * self.p.hysteresis_a;
        for (leg, c, target, g) in [(pp, &cp, self.i_ref, gp), (mm, &cm, -self.i_ref, gm)] {
            if g == Gate::Upper {
                first.offer(
                    reach(c, target + band, 1.0, h),
                    Event::Leg(leg, Gate::Lower),
                );
            } else {
                first.offer(
                    reach(c, target - band, -1.0, h),
                    Event::Leg(leg, Gate::Upper),
                );
            }
        }
        // The comparators do not bound the three currents here: the over-current protection's
        // level is an event too.
        for c in [&cp, &co, &cm] {
            first.offer(reach(c, self.trip_a, 1.0, h), Event::Trip);
            first.offer(reach(c, -self.trip_a, -1.0, h), Event::Trip);
        }
        self.sector_events(sec, &cth, h, &mut first);
        self.link_events(&cv, rect, h, &mut first);
        self.gear_events(psi, &cw, &cth, h, &mut first);

        // Integrals over [0, τ] by 2-point Gauss-Legendre.
        let (f_o0, k_o) = shape;
        let ds = [legs[0] - legs[1], legs[2] - legs[1]];
        let mut q = [0.0; 8];
        let mut q_te = 0.0;
        let (mut peak, mut v_hi) = (i[0].abs().max(i[1].abs()).max(i[2].abs()), v0);
        let First { tau, what } = first;
        let half = 0.5 * tau;
        for (xg, wg) in GL_X.iter().zip(GL_W) {
            let t = half * (1.0 + xg);
            let w = wg * half;
            let (ip, io, wt, tht, vt) = (
                eval(&cp, t),
                eval(&co, t),
                eval(&cw, t),
                eval(&cth, t),
                eval(&cv, t),
            );
            let im = -ip - io;
            let tb = k.k_vr_g * ((self.theta_m + tht) * k.inv_g - psi);
            q_te += w * k.lam * (2.0 * ip + (1.0 + f_o0 + k_o * tht) * io);
            q[Q_INVERTER] += w * vt * (ds[0] * ip + ds[1] * io);
            q[Q_COPPER] += w * 0.5 * k.two_r * (ip * ip + io * io + im * im);
            q[Q_FRICTION] += w * k.b_f * wt * wt;
            q[Q_LOAD] += w * tb * wt;
            q[Q_GEAR] += w * ((gear.c - 1.0) * tb + gear.d * wt) * wt;
            q[Q_RECTIFIER] += w * vt * g_r * (v_s - vt);
            q[Q_CHOPPER] += w * g_ch * vt * vt;
            q[Q_AUX] += w * k.g_aux * vt * vt;
            peak = peak.max(ip.abs()).max(io.abs()).max(im.abs());
            v_hi = v_hi.max(vt);
        }

        let (ip, mut io) = (eval(&cp, tau), eval(&co, tau));
        let mut d_th = eval(&cth, tau);
        let mut v_end = eval(&cv, tau);
        let mut w_end = eval(&cw, tau);
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
        self.close(
            what,
            th + half_pp * d_th,
            d_th,
            w_end,
            v_end,
            peak.max(i_peak),
            v_hi,
            q,
        );
        Ok((tau, q_te, q[Q_INVERTER], q[Q_CHOPPER]))
    }

    /// The gear's linear load law over a segment from now ([`Rotor`]), `te0` the motor's
    /// torque (to tell which way a rotor at rest leaves), and the longest segment it allows
    /// (its damping d/J times the segment at most 0.25, as accurate as the link's pole).
    fn rotor(&self, psi: f64, te0: f64) -> (Rotor, f64) {
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
    fn gear_events(&self, psi: f64, cw: &Poly, cth: &Poly, h: f64, first: &mut First) {
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
    fn chopper(&mut self) -> f64 {
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
    fn rectifier(&self, dv: f64, without: impl FnOnce() -> Poly) -> bool {
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
    fn sector_angle(&self, sec: usize) -> (f64, f64) {
        let th = if self.theta_e < FRAC_PI_6 {
            self.theta_e + TAU
        } else {
            self.theta_e
        };
        (th, FRAC_PI_6 + FRAC_PI_3 * sec as f64)
    }

    /// Offers `first` the sector's boundaries (commutations) reached by Δθ_m (`cth`) within
    /// `h`; returns the electrical angle unwrapped into the sector and the sector's start.
    fn sector_events(&self, sec: usize, cth: &Poly, h: f64, first: &mut First) -> (f64, f64) {
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
    fn link_events(&self, cv: &Poly, rect: bool, h: f64, first: &mut First) {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn p(c: [f64; 4]) -> Poly {
        let mut x = [0.0; ORDER + 1];
        x[..4].copy_from_slice(&c);
        x
    }

    #[test]
    fn reach_finds_the_first_crossing_of_a_cubic() {
        // Rising line: 2 + 3τ reaches 5 at τ = 1.
        let t = reach(&p([2.0, 3.0, 0.0, 0.0]), 5.0, 1.0, 2.0).unwrap();
        assert!((t - 1.0).abs() < 1e-13);
        assert_eq!(reach(&p([2.0, 3.0, 0.0, 0.0]), 5.0, 1.0, 0.5), None);
        // (τ − 1)(τ − 2)(τ − 3) = τ³ − 6τ² + 11τ − 6 reaches 0 upwards first at 1; its negative
        // reaches 0 downwards first at 1 and is beyond −1 downwards... never (it starts at 6).
        let c = p([-6.0, 11.0, -6.0, 1.0]);
        assert!((reach(&c, 0.0, 1.0, 4.0).unwrap() - 1.0).abs() < 1e-12);
        let neg = c.map(|x| -x);
        assert!((reach(&neg, 0.0, -1.0, 4.0).unwrap() - 1.0).abs() < 1e-12);
        // Beyond the level already: reached at once.
        assert_eq!(reach(&neg, 0.0, 1.0, 4.0), Some(0.0));
        let down = reach(&p([0.0, -1.0, 0.0, 0.0]), -0.5, -1.0, 1.0).unwrap();
        assert!((down - 0.5).abs() < 1e-13);
        // Starting on the level moving away: not reached; moving through: at once.
        assert_eq!(reach(&p([1.0, -1.0, 0.0, 0.0]), 1.0, 1.0, 1.0), None);
        assert_eq!(reach(&p([1.0, 1.0, 0.0, 0.0]), 1.0, 1.0, 1.0), Some(0.0));
        // A parabola that turns back before the level: never reached; one that touches later.
        assert_eq!(reach(&p([0.0, 2.0, -1.0, 0.0]), 1.5, 1.0, 3.0), None);
        let t = reach(&p([0.0, -1.0, 1.0, 0.0]), 2.0, 1.0, 5.0).unwrap();
        assert!((t - 2.0).abs() < 1e-12, "{t}");
        // Up to a local maximum below the level, down, then up through it: τ³ − 6τ² + 11τ − 6
        // has its maximum 0.385 at τ = 1.42 and reaches 1 again at τ = 3.32.
        let t = reach(&c, 1.0, 1.0, 4.0).unwrap();
        assert!((eval(&c, t) - 1.0).abs() < 1e-12 && t > 3.0, "{t}");
        assert_eq!(reach(&c, 0.5, 1.0, 3.0), None);
    }
}
