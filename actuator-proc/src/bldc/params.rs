//! The drive's settings (scenario `[actuator.bldc]`, Tables 1-2 and eq 1) and the harmonic
//! gearbox's loss law (docs/model.md D45).

use serde::{Deserialize, Serialize};

use tiltsim_protocol::settings::Checker;

/// Motor, drive and bar parameters (scenario `[actuator.bldc]`), Tables 1-2 and eq 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BldcParams {
    /// Supply voltage V_app (V), Table 2: the rectifier's no-load DC-link voltage.
    pub v_dc: f64,
    /// Stator phase resistance R_s (Ω).
    pub r_s: f64,
    /// Stator phase inductance L_s (H).
    pub l_s: f64,
    /// Viscous friction B_f (N·m·s/rad).
    pub b_f: f64,
    /// Rotor inertia J_rot (kg·m²).
    pub j_rot: f64,
    /// Torque constant k_t with two phases conducting (N·m/A).
    pub k_t: f64,
    /// Number of poles N_p.
    pub poles: u32,
    /// Harmonic gearbox ratio n_r.
    pub n_r: f64,
    /// Bar lever L1 (m), eq 1.
    pub l1: f64,
    /// Bar lever L2 (m), eq 1.
    pub l2: f64,
    /// Speed PI proportional gain (N·m·s/rad on the motor shaft), Table 1.
    pub speed_kp: f64,
    /// Speed PI integral gain (N·m/rad), Table 1 (parallel form, T = K_p e + K_i ∫e dt).
    pub speed_ki: f64,
    /// Torque limit of the speed PI (N·m), Table 1.
    pub torque_limit_nm: f64,
    /// Phase current limit (A).
    pub current_limit_a: f64,
    /// Position loop gain (1/s): ω_ref = K_θ (θ_m,ref − θ_m). Ours (D22).
    pub position_gain: f64,
    /// Speed limit as a fraction of the no-load speed V_dc/k_t (DC-link voltage headroom).
    pub speed_limit_fraction: f64,
    /// Period of the position and speed loops (s); a multiple of the electrical step.
    pub control_period_s: f64,
    /// Hysteresis band of the current controller, full width (A).
    pub hysteresis_a: f64,
    /// Bar stroke: commands are clamped to ±stroke and the bar stops mechanically there (deg).
    pub stroke_deg: f64,
    /// Electrical integration step of the switched model (s); with event-driven integration
    /// the step of the fixed-step fallback and the time grid of control and exchanges.
    pub dt_switched_s: f64,
    /// How the switched model is integrated: `event` (from switching event to switching
    /// event in closed form, the default) or `fixed-step` (forward Euler at `dt_switched_s`).
    pub switched_integration: SwitchedIntegration,
    /// Integration step of the averaged model (s).
    pub dt_averaged_s: f64,
    /// Efficiency η of the harmonic gearbox, applied in both directions: driving, the motor
    /// supplies the bar's power over η; back-driven, the motor receives η of it (D45).
    /// 1 is the paper's lossless gear.
    pub gear_efficiency: f64,
    /// Motor speed over which the gear's loss builds up from zero to its full value (rad/s),
    /// so that it is continuous through zero speed (D45).
    pub gear_loss_speed_rad_s: f64,
    /// Continuous (thermal) torque rating of the motor (N·m); the run's RMS torque is checked
    /// against it (`flags.thermal`, D48).
    pub continuous_torque_nm: f64,
}

impl Default for BldcParams {
    fn default() -> Self {
        BldcParams {
            v_dc: 780.0,
            r_s: 0.19,
            l_s: 4.6e-3,
            b_f: 0.005,
            j_rot: 0.116,
            k_t: 7.15,
            poles: 8,
            n_r: 200.0,
            l1: 2.0,
            l2: 0.7,
            speed_kp: 18.64,
            speed_ki: 7324.7,
            torque_limit_nm: 600.0,
            current_limit_a: 90.0,
            position_gain: 40.0,
            speed_limit_fraction: 0.9,
            control_period_s: 1e-4,
            hysteresis_a: 2.0,
            stroke_deg: 5.0,
            dt_switched_s: 1e-6,
            dt_averaged_s: 2e-5,
            switched_integration: SwitchedIntegration::Event,
            gear_efficiency: GEAR_EFFICIENCY,
            gear_loss_speed_rad_s: 1.0,
            continuous_torque_nm: 200.0,
        }
    }
}

/// The harmonic gearbox's efficiency by default (docs/model.md D45: Harmonic Drive catalogue
/// values for a high-ratio unit at the drive's speeds).
pub const GEAR_EFFICIENCY: f64 = 0.7;

impl BldcParams {
    /// Checks every field.
    pub fn validate(&self, c: &mut Checker) {
        c.positive("bldc.v_dc", self.v_dc, 5000.0, "V");
        c.positive("bldc.r_s", self.r_s, 100.0, "Ω");
        c.positive("bldc.l_s", self.l_s, 1.0, "H");
        c.range("bldc.b_f", self.b_f, 0.0, 100.0, "N·m·s/rad");
        c.positive("bldc.j_rot", self.j_rot, 100.0, "kg·m²");
        c.positive("bldc.k_t", self.k_t, 1000.0, "N·m/A");
        c.require(
            self.poles >= 2 && self.poles.is_multiple_of(2) && self.poles <= 64,
            "bldc.poles",
            self.poles,
            "an even integer in [2, 64]",
        );
        c.positive("bldc.n_r", self.n_r, 10_000.0, "");
        c.positive("bldc.l1", self.l1, 10.0, "m");
        c.positive("bldc.l2", self.l2, 10.0, "m");
        c.range("bldc.speed_kp", self.speed_kp, 0.0, 1e6, "N·m·s/rad");
        c.range("bldc.speed_ki", self.speed_ki, 0.0, 1e8, "N·m/rad");
        c.positive("bldc.torque_limit_nm", self.torque_limit_nm, 1e5, "N·m");
        c.positive("bldc.current_limit_a", self.current_limit_a, 1e4, "A");
        c.positive("bldc.position_gain", self.position_gain, 1e4, "1/s");
        c.positive(
            "bldc.speed_limit_fraction",
            self.speed_limit_fraction,
            1.0,
            "",
        );
        c.positive("bldc.hysteresis_a", self.hysteresis_a, 100.0, "A");
        c.positive("bldc.stroke_deg", self.stroke_deg, 45.0, "deg");
        c.range("bldc.dt_switched_s", self.dt_switched_s, 1e-8, 1e-4, "s");
        c.range("bldc.dt_averaged_s", self.dt_averaged_s, 1e-6, 1e-3, "s");
        c.require(
            self.gear_efficiency > 0.3 && self.gear_efficiency <= 1.0,
            "bldc.gear_efficiency",
            self.gear_efficiency,
            "an efficiency in (0.3, 1]",
        );
        c.range(
            "bldc.gear_loss_speed_rad_s",
            self.gear_loss_speed_rad_s,
            0.1,
            100.0,
            "rad/s",
        );
        c.positive(
            "bldc.continuous_torque_nm",
            self.continuous_torque_nm,
            1e5,
            "N·m",
        );
        c.range(
            "bldc.control_period_s",
            self.control_period_s,
            1e-6,
            1e-2,
            "s",
        );
    }

    /// Motor angle per bar angle, G = n_r L1/(2 L2) (eq 1 and the gearbox).
    pub fn gear(&self) -> f64 {
        self.n_r * self.l1 / (2.0 * self.l2)
    }

    /// No-load speed V_dc/k_t with friction: the steady state of V = 2R i + k_t ω,
    /// k_t i = B ω, i.e. ω = V/(k_t + 2R B/k_t) (rad/s).
    pub fn no_load_speed(&self) -> f64 {
        self.v_dc / (self.k_t + 2.0 * self.r_s * self.b_f / self.k_t)
    }
}

/// The harmonic gearbox's loss (docs/model.md D45). The bar's torque reflected to the motor
/// shaft, T_b = k_vr (δ_a − ψ)/G, is what an ideal gear would load the motor with. With
/// efficiency η the motor sees T_l = T_b/η when it drives the bar (T_b ω > 0: the loss adds to
/// the motor's torque) and T_l = η T_b when the bar drives it (T_b ω < 0: the loss takes from
/// the torque the bar delivers). Near zero speed the loss builds up linearly over
/// |ω| < ω_ε: T_l = T_b (1 + μ |s|), s = sat(ω/ω_ε), μ = 1/η − 1 driving and −(1 − η)
/// back-driven, so T_l is continuous in ω (no chattering at a reversal), equals T_b at rest,
/// and the loss (T_l − T_b) ω is never negative.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GearLoss {
    /// 1/η − 1.
    mu_drive: f64,
    /// 1 − η.
    mu_back: f64,
    /// 1/ω_ε (s/rad).
    pub(super) inv_w_eps: f64,
}

impl GearLoss {
    /// The loss of a gear of efficiency `eta` building up over `w_eps` (rad/s).
    pub fn new(eta: f64, w_eps: f64) -> Self {
        GearLoss {
            mu_drive: 1.0 / eta - 1.0,
            mu_back: 1.0 - eta,
            inv_w_eps: 1.0 / w_eps,
        }
    }

    /// Whether the gear is lossless (η = 1).
    #[inline]
    pub fn lossless(&self) -> bool {
        self.mu_drive == 0.0
    }

    /// The signed coefficient μ for bar torque `t_b` and direction `dir` of the rotor's motion.
    #[inline]
    pub(super) fn mu(&self, t_b: f64, dir: f64) -> f64 {
        if t_b * dir >= 0.0 {
            self.mu_drive
        } else {
            -self.mu_back
        }
    }

    /// The load torque on the motor, T_l, for bar torque `t_b` (N·m, motor side) at rotor
    /// speed `w` (rad/s).
    #[inline]
    pub fn load(&self, t_b: f64, w: f64) -> f64 {
        let s = (w * self.inv_w_eps).clamp(-1.0, 1.0);
        t_b * (1.0 + self.mu(t_b, s) * s.abs())
    }
}

/// How the switched electrics are integrated between exchanges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SwitchedIntegration {
    /// Event-driven: exact switching and commutation instants, the linear circuit between
    /// them integrated in closed form to third order (`bldc/event.rs`).
    #[default]
    Event,
    /// Forward Euler at `dt_switched_s`, comparators sampled every step.
    FixedStep,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gear_law_is_continuous_dissipative_and_reaches_its_efficiency() {
        // T_l(T_b, ω) of docs/model.md D45 against its definition: T_b/η driving and η·T_b
        // back-driven at and beyond ω_ε, T_b at rest, continuous in ω (the largest jump
        // between neighbouring speeds 1e-4·ω_ε apart is the slope's 1e-4·μ·T_b), and the loss
        // (T_l − T_b)·ω never negative.
        let eta = 0.7;
        let g = GearLoss::new(eta, 1.0);
        for tb in [-300.0, -1.0, 0.0, 2.0, 450.0] {
            for w in [1.0, 3.0, 90.0] {
                let drive = g.load(tb, w * f64::signum(tb + 1e-300));
                let back = g.load(tb, -w * f64::signum(tb + 1e-300));
                assert!(
                    (drive - tb / eta).abs() <= 1e-12 * tb.abs(),
                    "{tb} {w}: {drive}"
                );
                assert!(
                    (back - eta * tb).abs() <= 1e-12 * tb.abs(),
                    "{tb} {w}: {back}"
                );
            }
            assert_eq!(g.load(tb, 0.0), tb);
            let mut prev = g.load(tb, -2.0);
            for k in -20_000..=20_000 {
                let w = k as f64 * 1e-4;
                let tl = g.load(tb, w);
                assert!((tl - prev).abs() <= 1e-4 * (1.0 / eta - 1.0) * tb.abs() + 1e-12);
                assert!((tl - tb) * w >= 0.0, "{tb} at {w}: loss {}", (tl - tb) * w);
                prev = tl;
            }
        }
        assert!(GearLoss::new(1.0, 1.0).lossless());
    }
}
