//! The electric anti-roll-bar actuator of the paper (eqs 1-8, Tables 1-2, Fig. 4): a
//! trapezoidal-back-EMF brushless DC motor fed by a three-phase inverter on a DC link, with a
//! hysteresis current controller, the speed PI of Table 1, our position loop, a harmonic
//! gearbox and the anti-roll bar.
//!
//! Units: SI throughout; angles in rad, speeds in rad/s (motor shaft), torques in N·m,
//! currents in A, voltages in V.
//!
//! Constants (docs/model.md D19-D23):
//! * k_t = 7.15 N·m/A is the torque per ampere with two phases conducting (model-notes). The
//!   per-phase back-EMF amplitude is then λ_p = k_t/2 (V·s/rad, eq 6-8 with f = ±1), so that
//!   Σ e_x i_x = T_e ω holds exactly (energy consistency). Table 2's Λ_e = 442.8 V/krpm read as
//!   an RMS line-to-line value of a sinusoidal equivalent gives √3·Λ_e = 7.32 N·m/A, 2.4 %
//!   from k_t: the two constants agree under that reading, and k_t is the one we keep.
//! * The gear chain: θ_m = n_r·φ (harmonic gearbox, n_r = 200), δ_a = 2(L2/L1)·φ (eq 1), so
//!   θ_m = G δ_a with G = n_r L1/(2 L2) ≈ 285.7.
//! * Load: the bar stores ½k_vr(δ_a − ψ)², so by virtual work the motor sees
//!   T_l = k_vr (δ_a − ψ)/G. Eq 2 (T = k_vr L2 δ_a/L1) is half of the virtual-work moment
//!   2(L2/L1)·k_vr δ_a; we take the energy-consistent one (D21).

use crate::dc_link::{DcLink, DcLinkParams};
use crate::shaping::{CommandShaping, Shaper};

mod commutation;
mod control;
mod event;
mod inverter;
mod params;

use commutation::shapes_and_sector_reduced;
pub use commutation::{commutation_table, sector, shapes, shapes_and_sector, trapezoid, SHIFT};
pub use event::{EventStats, MAX_SEGMENT_S};
pub use params::{BldcParams, GearLoss, SwitchedIntegration, GEAR_EFFICIENCY};

/// Bits of [`Telemetry::limits`] (recorded in `timeseries.csv` → `actuator_limits`).
pub mod limit {
    /// The speed PI's torque demand hit ±`torque_limit_nm`.
    pub const TORQUE: u32 = 1;
    /// A measured phase current reached `current_limit_a`.
    pub const CURRENT: u32 = 2;
    /// The position loop's speed demand hit the DC-link speed limit.
    pub const SPEED: u32 = 4;
    /// The bar command was outside the stroke and was clamped.
    pub const STROKE_COMMAND: u32 = 8;
    /// The bar reached its mechanical end stop.
    pub const END_STOP: u32 = 16;
    /// Over-current protection acted: a measured phase current exceeded `current_limit_a`
    /// plus half the hysteresis band and the gates were blocked until the next control update.
    pub const OVERCURRENT_TRIP: u32 = 32;
    /// The braking chopper was on (DC-link voltage reached `dc_link.chopper_on_v`).
    pub const CHOPPER: u32 = 64;
    /// The DC link exceeded `dc_link.overvoltage_trip_v`; the gates were blocked.
    pub const OVERVOLTAGE: u32 = 128;
}

/// State of one inverter leg.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Gate {
    /// Upper switch on: terminal at the link voltage.
    Upper,
    /// Lower switch on: terminal at 0 V.
    Lower,
    /// Both off: the terminal follows the diodes (by current sign) or floats.
    Off,
}

/// Which electrical model runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Electrics {
    /// Inverter switches, hysteresis current control, three phase currents (reference).
    Switched,
    /// DC-equivalent averaged model: the conducting pair as one R-L-EMF branch (2R, 2L,
    /// k_t ω) fed with the voltage the current controller asks for, within ±V_dc.
    Averaged,
}

/// Energy bookkeeping over a run (J).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Energy {
    /// Drawn from the DC link, ∫ Σ v_x i_x dt.
    pub electrical_in: f64,
    /// Copper loss ∫ R Σ i_x² dt.
    pub copper: f64,
    /// Friction ∫ B ω² dt.
    pub friction: f64,
    /// Work done on the bar ∫ T_b ω dt (T_b the bar's torque at the motor shaft).
    pub load: f64,
    /// Loss in the gearbox ∫ (T_l − T_b) ω dt (never negative).
    pub gear: f64,
}

/// Telemetry of one exchange interval.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Telemetry {
    /// Achieved bar angle δ_a = θ_m/G (rad), at the end of the interval.
    pub delta_a: f64,
    /// Mean electromagnetic torque over the interval (N·m).
    pub torque: f64,
    /// Rotor speed at the end of the interval (rad/s).
    pub speed: f64,
    /// Mean torque-producing current T_e/k_t over the interval (A): the current in the two
    /// conducting phases between commutations.
    pub current: f64,
    /// Mean power drawn from the DC link over the interval (W); negative when regenerating.
    pub dc_power: f64,
    /// Bits of [`limit`] that were active during the interval.
    pub limits: u32,
    /// Largest |phase current| in any electrical step of the interval (A).
    pub phase_current_peak: f64,
    /// DC-link voltage at the end of the interval (V).
    pub v_dc: f64,
    /// Largest DC-link voltage in any electrical step of the interval (V).
    pub v_dc_max: f64,
    /// Mean power dumped in the braking chopper over the interval (W).
    pub chopper_power: f64,
    /// The shaped bar set-point at the end of the interval (rad).
    pub delta_a_ref: f64,
}

/// The actuator: motor, inverter, current/speed/position control, gearbox and bar.
#[derive(Debug, Clone)]
pub struct Bldc {
    p: BldcParams,
    kind: Electrics,
    /// Bar stiffness k_vr (N·m/rad), from the vehicle (one source of truth).
    k_vr: f64,
    gear: f64,
    /// The gearbox's loss.
    gear_loss: GearLoss,
    lambda: f64,
    dt: f64,
    sub_per_control: u32,
    /// Electrical steps per control period (the hook that disables the loops keeps this).
    steps_per_period: u32,
    sub_count: u32,
    omega_max: f64,
    stroke: f64,
    table: [(usize, usize); 6],
    /// Event-driven or fixed-step integration of the switched electrics.
    integration: SwitchedIntegration,
    /// Counters of the event-driven integration.
    stats: EventStats,
    /// Constants of the event-driven integration.
    consts: event::Consts,
    /// Phase currents (A); the averaged model uses `i[0]` as the pair current.
    pub i: [f64; 3],
    /// Rotor speed γ (rad/s).
    pub omega: f64,
    /// Rotor angle (mechanical, rad), zero at neutral bar.
    pub theta_m: f64,
    /// Electrical angle reduced to [0, 2π), advanced with θ_m (saves a remainder per step).
    theta_e: f64,
    /// Current reference of the last control update (A).
    i_ref: f64,
    /// Torque reference from the speed PI (N·m).
    pub torque_ref: f64,
    integral: f64,
    /// Inverter legs (switched model).
    gates: [Gate; 3],
    /// Gates blocked by a protection for the rest of the control period.
    blocked: bool,
    /// Electrical steps left until a protection's block is released.
    blocked_steps: u32,
    /// Phase current above which the over-current protection blocks the gates (A).
    trip_a: f64,
    /// The DC link.
    pub link: DcLink,
    shaper: Shaper,
    /// Electrical steps taken in the current interval (for the set-point ramp).
    sub_in_interval: u64,
    /// Energy accounting since the start.
    pub energy: Energy,
    limits: u32,
    peak: f64,
    v_max: f64,
}

impl Bldc {
    /// A motor at rest with the bar at neutral, its DC link charged to the supply voltage,
    /// holding new set-points (see [`Bldc::with_shaping`]).
    pub fn new(p: &BldcParams, link: &DcLinkParams, kind: Electrics, k_vr: f64) -> Self {
        let dt = match kind {
            Electrics::Switched => p.dt_switched_s,
            Electrics::Averaged => p.dt_averaged_s,
        };
        let sub_per_control = ((p.control_period_s / dt).round() as u32).max(1);
        Bldc {
            kind,
            k_vr,
            gear: p.gear(),
            gear_loss: GearLoss::new(p.gear_efficiency, p.gear_loss_speed_rad_s),
            lambda: p.k_t / 2.0,
            dt,
            sub_per_control,
            steps_per_period: sub_per_control,
            sub_count: 0,
            omega_max: p.speed_limit_fraction * p.v_dc / p.k_t,
            stroke: p.stroke_deg.to_radians(),
            table: commutation_table(),
            integration: p.switched_integration,
            stats: EventStats::default(),
            consts: event::Consts::new(p, link, k_vr),
            i: [0.0; 3],
            omega: 0.0,
            theta_m: 0.0,
            theta_e: 0.0,
            i_ref: 0.0,
            torque_ref: 0.0,
            integral: 0.0,
            gates: [Gate::Off; 3],
            blocked: false,
            blocked_steps: 0,
            trip_a: p.current_limit_a + 0.5 * p.hysteresis_a,
            link: DcLink::new(link, p.v_dc),
            shaper: Shaper::new(CommandShaping::Hold, 0.0, dt),
            sub_in_interval: 0,
            energy: Energy::default(),
            limits: 0,
            peak: 0.0,
            v_max: 0.0,
            p: p.clone(),
        }
    }

    /// Applies new set-points with `shaping` over the controller period `period_s`.
    pub fn with_shaping(mut self, shaping: CommandShaping, period_s: f64) -> Self {
        self.shaper = Shaper::new(shaping, period_s, self.dt);
        self
    }

    /// Electrical integration step (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Counters of the event-driven integration (all zero for the other models).
    pub fn event_stats(&self) -> EventStats {
        self.stats
    }

    /// DC-link voltage (V).
    pub fn v_dc(&self) -> f64 {
        self.link.v
    }

    /// Bar angle δ_a (rad).
    pub fn delta_a(&self) -> f64 {
        self.theta_m / self.gear
    }

    /// Magnetic energy ½ L Σ i² (J) (the averaged pair: ½ (2L) i²).
    pub fn magnetic_energy(&self) -> f64 {
        match self.kind {
            Electrics::Switched => 0.5 * self.p.l_s * self.i.iter().map(|x| x * x).sum::<f64>(),
            Electrics::Averaged => self.p.l_s * self.i[0] * self.i[0],
        }
    }

    /// Kinetic energy ½ J ω² (J).
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.p.j_rot * self.omega * self.omega
    }

    fn electrical_angle(&self) -> f64 {
        0.5 * self.p.poles as f64 * self.theta_m
    }

    /// The bar's torque at the motor shaft, T_b = k_vr (δ_a − ψ)/G (N·m), the load of an
    /// ideal gear (the motor sees [`GearLoss::load`] of it).
    pub fn load_torque(&self, psi: f64) -> f64 {
        self.k_vr * (self.delta_a() - psi) / self.gear
    }

    /// One electrical step: returns (electromagnetic torque, power drawn by the inverter,
    /// power dumped in the chopper).
    fn substep(&mut self, psi: f64) -> (f64, f64, f64) {
        if self.sub_count == 0 {
            self.control_update();
        }
        self.count_down_block();
        self.sub_count = (self.sub_count + 1) % self.sub_per_control;
        self.sub_in_interval += 1;
        self.fixed_step(psi, self.dt)
    }

    /// One forward-Euler step of `dt` of the electrics, the link and the rotor with the
    /// references held.
    #[inline]
    fn fixed_step(&mut self, psi: f64, dt: f64) -> (f64, f64, f64) {
        let i_ref = self.i_ref;
        let (te, p_in, cu) = match self.kind {
            Electrics::Averaged => self.averaged(i_ref, dt),
            Electrics::Switched => self.switched(i_ref, dt),
        };
        let p_chop = self.link.step(dt, p_in);
        // Rotor mechanics (eq 4), the gearbox and the bar.
        let w = self.omega;
        let tb = self.load_torque(psi);
        let tl = self.gear_loss.load(tb, w);
        self.omega += dt * (te - self.p.b_f * w - tl) / self.p.j_rot;
        self.theta_m += dt * w;
        let tau = std::f64::consts::TAU;
        self.theta_e += dt * w * 0.5 * self.p.poles as f64;
        if !(0.0..tau).contains(&self.theta_e) {
            self.theta_e = self.theta_e.rem_euclid(tau);
        }
        let stop = self.gear * self.stroke;
        if self.theta_m.abs() >= stop {
            // Inelastic end stop: the bar cannot go further; its speed outwards is lost.
            self.theta_m = self.theta_m.clamp(-stop, stop);
            self.theta_e = self.electrical_angle().rem_euclid(tau);
            if self.omega * self.theta_m > 0.0 {
                self.omega = 0.0;
            }
            self.limits |= limit::END_STOP;
        }
        self.energy.electrical_in += dt * p_in;
        self.energy.copper += dt * cu;
        self.energy.friction += dt * self.p.b_f * w * w;
        self.energy.load += dt * tb * w;
        self.energy.gear += dt * (tl - tb) * w;
        (te, p_in, p_chop)
    }

    /// Advances over `interval` seconds with bar command `delta_cmd` and twist `psi` held
    /// (both rad); returns the interval's telemetry.
    pub fn advance(&mut self, delta_cmd: f64, psi: f64, interval: f64) -> Telemetry {
        self.limits = 0;
        let mut cmd = delta_cmd;
        if cmd.abs() > self.stroke {
            cmd = cmd.clamp(-self.stroke, self.stroke);
            self.limits |= limit::STROKE_COMMAND;
        }
        self.shaper.receive(cmd);
        self.run_interval(psi, interval)
    }

    /// Sub-steps over `interval` and averages torque and power over them.
    fn run_interval(&mut self, psi: f64, interval: f64) -> Telemetry {
        let n = ((interval / self.dt).round() as u64).max(1);
        let (mut te_sum, mut p_sum, mut ch_sum) = (0.0, 0.0, 0.0);
        self.peak = 0.0;
        self.v_max = self.link.v;
        self.sub_in_interval = 0;
        if self.kind == Electrics::Switched && self.integration == SwitchedIntegration::Event {
            (te_sum, p_sum, ch_sum) = self.run_events(psi, n);
        } else {
            for _ in 0..n {
                let (te, p, ch) = self.substep(psi);
                te_sum += te;
                p_sum += p;
                ch_sum += ch;
            }
        }
        self.shaper.advance(n);
        self.sub_in_interval = 0;
        if self.link.chopper_on || ch_sum > 0.0 {
            self.limits |= limit::CHOPPER;
        }
        let nf = n as f64;
        let peak = self
            .peak
            .max(self.i[0].abs().max(self.i[1].abs()).max(self.i[2].abs()));
        Telemetry {
            delta_a: self.delta_a(),
            torque: te_sum / nf,
            speed: self.omega,
            current: te_sum / nf / self.p.k_t,
            dc_power: p_sum / nf,
            limits: self.limits,
            phase_current_peak: peak,
            v_dc: self.link.v,
            v_dc_max: self.v_max.max(self.link.v),
            chopper_power: ch_sum / nf,
            delta_a_ref: self.shaper.value_after(0),
        }
    }

    /// Open-loop test hook: drive a constant torque reference, bypassing position and speed
    /// loops (used for the no-load and stall checks).
    pub fn hold_torque_reference(&mut self, t: f64, psi: f64, interval: f64) -> Telemetry {
        // Disable the loops: a control period longer than the interval.
        let saved = self.sub_per_control;
        self.sub_per_control = u32::MAX;
        self.sub_count = 1;
        self.torque_ref = t;
        self.i_ref = self.current_ref();
        self.limits = 0;
        let tel = self.run_interval(psi, interval);
        self.sub_per_control = saved;
        self.sub_count = 0;
        tel
    }
}

#[cfg(test)]
mod tests;
