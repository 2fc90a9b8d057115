//! The PI tilt loop in the frequency domain: its margins, and a PI designed for a phase-margin
//! target (docs/model.md D24).
//!
//! Loop: `L(s) = C(s) · A(s) · P(s) · e^{−sτ}` with
//! * `C(s) = K_p + K_i/s`, the PI of section 3.1 on the roll error;
//! * `A(s)`, the bar's closed-loop response to its set-point: 1 for the ideal actuator; for
//!   the BLDC drive the position loop around the speed loop,
//!   `A = K_θ T_ω/(s + K_θ T_ω)` with `T_ω = (K_p,ω s + K_i,ω)/(J s² + K_p,ω s + K_i,ω)`
//!   (Table 1's speed PI on the rotor inertia; the bar's load reflected through the 286:1 gear,
//!   k_vr/G² ≈ 25 N·m/rad, is negligible against it);
//! * `P(s) = Ψ (sI − Π)⁻¹ Φ`, body roll per bar angle from the vehicle's linear model;
//! * `τ`: the sampled loop's delays, half a controller period (zero-order hold) plus one base
//!   tick (the lock-step exchange from measurement to bar command).
//!
//! The drive's rate limit (the speed limit, 19.6 °/s at the bar) is a nonlinearity the linear
//! loop cannot show: a loop that asks for more than that rate falls into a limit cycle even
//! where its linear margins are positive.

use nalgebra::{Complex, DMatrix};
use serde::Serialize;

use crate::design::LinearModel;

/// The bar's response to its set-point, as the loop analysis models it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum ActuatorLag {
    /// δ_a = δ_a,cmd.
    Ideal,
    /// The BLDC drive's position loop around its speed loop.
    Drive {
        /// Position-loop gain K_θ (1/s).
        position_gain: f64,
        /// Speed PI proportional gain (N·m·s/rad).
        speed_kp: f64,
        /// Speed PI integral gain (N·m/rad).
        speed_ki: f64,
        /// Rotor inertia J (kg·m²).
        j_rot: f64,
    },
}

impl ActuatorLag {
    fn at(&self, s: Complex<f64>) -> Complex<f64> {
        match *self {
            ActuatorLag::Ideal => Complex::new(1.0, 0.0),
            ActuatorLag::Drive {
                position_gain,
                speed_kp,
                speed_ki,
                j_rot,
            } => {
                let tw = (s * speed_kp + speed_ki) / (s * s * j_rot + s * speed_kp + speed_ki);
                tw * position_gain / (s + tw * position_gain)
            }
        }
    }
}

/// Margins of a loop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Margins {
    /// Gain crossover |L| = 1 (Hz); the first one from below.
    pub crossover_hz: f64,
    /// Phase margin 180° + ∠L at the crossover (deg); negative means unstable; NaN if |L|
    /// does not cross 1 between 0.01 and 100 Hz.
    pub phase_margin_deg: f64,
    /// Phase crossover ∠L = −180° (Hz), if the phase gets there in the range scanned.
    pub phase_crossover_hz: Option<f64>,
    /// Gain margin −20 log₁₀|L| at the phase crossover (dB); negative means unstable.
    pub gain_margin_db: Option<f64>,
}

/// The PI loop's plant side: vehicle, actuator and delays.
#[derive(Debug, Clone)]
pub struct PiLoop {
    model: LinearModel,
    /// The actuator's response.
    pub actuator: ActuatorLag,
    /// Total delay τ (s).
    pub delay_s: f64,
}

/// A PI designed for margins.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PiDesign {
    /// Target phase margin (deg).
    pub phase_margin_target_deg: f64,
    /// Target gain margin (dB).
    pub gain_margin_target_db: f64,
    /// Integral time T_i = K_p/K_i (s).
    pub ti_s: f64,
    /// K_p (rad/rad).
    pub kp: f64,
    /// K_i (1/s).
    pub ki: f64,
    /// The margins it gives.
    pub margins: Margins,
}

/// Log-spaced scan 0.01 … 100 Hz.
fn scan() -> impl Iterator<Item = f64> {
    let n = 6000;
    (0..=n).map(move |k| std::f64::consts::TAU * 0.01 * 10f64.powf(4.0 * k as f64 / n as f64))
}

impl PiLoop {
    /// The loop around `model` with `actuator`, a controller period `period_s` and a base tick
    /// `dt_s` (s).
    pub fn new(model: LinearModel, actuator: ActuatorLag, period_s: f64, dt_s: f64) -> Self {
        PiLoop {
            model,
            actuator,
            delay_s: 0.5 * period_s + dt_s,
        }
    }

    /// `A(jω)·P(jω)·e^{−jωτ}`: everything but the PI.
    pub fn plant(&self, w: f64) -> Complex<f64> {
        let s = Complex::new(0.0, w);
        let n = 9;
        let m: DMatrix<Complex<f64>> = DMatrix::from_fn(n, n, |i, j| {
            let d = if i == j { s } else { Complex::new(0.0, 0.0) };
            d - Complex::new(self.model.a[(i, j)], 0.0)
        });
        let b: DMatrix<Complex<f64>> = self.model.b.map(|x| Complex::new(x, 0.0));
        let x = m
            .lu()
            .solve(&b)
            .unwrap_or_else(|| DMatrix::from_element(n, 1, Complex::new(f64::NAN, 0.0)));
        let p: Complex<f64> = (0..n)
            .map(|i| x[(i, 0)] * self.model.c[(0, i)])
            .fold(Complex::new(0.0, 0.0), |a, b| a + b);
        p * self.actuator.at(s) * Complex::new(0.0, -w * self.delay_s).exp()
    }

    /// The whole loop with gains `kp`, `ki` at ω (rad/s).
    pub fn open_loop(&self, kp: f64, ki: f64, w: f64) -> Complex<f64> {
        (Complex::new(kp, 0.0) + Complex::new(0.0, -ki / w)) * self.plant(w)
    }

    /// Gain and phase margins of the loop with gains `kp`, `ki` (phase unwrapped along the
    /// scan from 0.01 Hz). The vehicle's roll modes can make |L| cross 1 several times: the
    /// phase margin is the smallest over every gain crossover, the gain margin the smallest
    /// over every phase crossover.
    pub fn margins(&self, kp: f64, ki: f64) -> Margins {
        let mut prev: Option<(f64, f64, f64)> = None; // (ω, |L|, unwrapped phase)
        let mut out = Margins {
            crossover_hz: f64::NAN,
            phase_margin_deg: f64::INFINITY,
            phase_crossover_hz: None,
            gain_margin_db: None,
        };
        for w in scan() {
            let l = self.open_loop(kp, ki, w);
            let (mag, mut ph) = (l.norm(), l.arg().to_degrees());
            if let Some((w0, m0, p0)) = prev {
                ph += 360.0 * ((p0 - ph) / 360.0).round();
                if (m0 - 1.0) * (mag - 1.0) <= 0.0 && m0 != mag {
                    let f = m0.ln() / (m0.ln() - mag.ln());
                    let pm = 180.0 + p0 + f * (ph - p0);
                    if pm < out.phase_margin_deg {
                        out.phase_margin_deg = pm;
                        out.crossover_hz = (w0 + f * (w - w0)) / std::f64::consts::TAU;
                    }
                }
                // Phase crossovers at −180° (mod 360°).
                let k = ((p0 + 180.0) / 360.0).floor();
                let level = -180.0 + 360.0 * k;
                if (p0 - level) * (ph - level) <= 0.0 && p0 != ph {
                    let f = (p0 - level) / (p0 - ph);
                    let m = m0 * (mag / m0).powf(f);
                    let gm = -20.0 * m.log10();
                    if out.gain_margin_db.is_none_or(|g| gm < g) {
                        out.gain_margin_db = Some(gm);
                        out.phase_crossover_hz = Some((w0 + f * (w - w0)) / std::f64::consts::TAU);
                    }
                }
            }
            prev = Some((w, mag, ph));
        }
        if !out.phase_margin_deg.is_finite() {
            out.phase_margin_deg = f64::NAN;
        }
        out
    }

    /// The PI with integral time `ti_s` = K_p/K_i and the largest K_p whose margins are at
    /// least `pm_deg` (every gain crossover) and `gm_db` (every phase crossover), found by
    /// bisection on K_p over [10⁻³, 10³]. `None` if even the smallest gain misses them.
    pub fn design(&self, pm_deg: f64, gm_db: f64, ti_s: f64) -> Option<PiDesign> {
        let ok = |kp: f64| {
            let m = self.margins(kp, kp / ti_s);
            // No gain crossover in the scan (NaN): the loop gain stays below 1 above 0.01 Hz.
            (m.phase_margin_deg.is_nan() || m.phase_margin_deg >= pm_deg)
                && m.gain_margin_db.is_none_or(|g| g >= gm_db)
        };
        let (mut lo, mut hi) = (1e-3f64, 1e3f64);
        if !ok(lo) {
            return None;
        }
        for _ in 0..50 {
            let mid = (lo * hi).sqrt();
            if ok(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let m = self.margins(lo, lo / ti_s);
        Some(PiDesign {
            phase_margin_target_deg: pm_deg,
            gain_margin_target_db: gm_db,
            ti_s,
            kp: lo,
            ki: lo / ti_s,
            margins: m,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vehicle_model::{TrackParams, VehicleParams};

    fn lp(actuator: ActuatorLag) -> PiLoop {
        let m = LinearModel::new(&VehicleParams::default(), TrackParams::default().speed());
        PiLoop::new(m, actuator, 1e-3, 1e-3)
    }

    #[test]
    fn plant_matches_the_static_gain_of_the_state_space_model() {
        // At low frequency P(jω) → −Ψ Π⁻¹ Φ.
        let l = lp(ActuatorLag::Ideal);
        let m = LinearModel::new(&VehicleParams::default(), TrackParams::default().speed());
        let dc = -(&m.c * m.a.clone().try_inverse().unwrap() * &m.b)[(0, 0)];
        let g = l.plant(1e-4);
        assert!((g.re - dc).abs() < 1e-4 * dc.abs(), "{g} vs {dc}");
    }

    #[test]
    fn a_designed_pi_has_the_margin_it_was_designed_for() {
        let drive = ActuatorLag::Drive {
            position_gain: 40.0,
            speed_kp: 18.64,
            speed_ki: 7324.7,
            j_rot: 0.116,
        };
        let l = lp(drive);
        let d = l.design(60.0, 6.0, 0.25).unwrap();
        let m = l.margins(d.kp, d.ki);
        // The largest gain with both margins: one of them is at its target.
        assert!(m.phase_margin_deg >= 60.0 - 1e-6 && m.gain_margin_db.unwrap() >= 6.0 - 1e-6);
        let at_pm = (m.phase_margin_deg - 60.0).abs() < 0.1;
        let at_gm = (m.gain_margin_db.unwrap() - 6.0).abs() < 0.1;
        assert!(at_pm || at_gm, "{m:?}");
        // 1 % more gain breaks one of them.
        let m2 = l.margins(1.01 * d.kp, 1.01 * d.ki);
        assert!(m2.phase_margin_deg < 60.0 || m2.gain_margin_db.unwrap() < 6.0);
        // The paper's gains: a working loop with the ideal bar (measured 30° at 6.4 Hz with the
        // 1.5 ms of sampling delay), no phase margin behind the drive's 25 ms position loop
        // (measured −19°).
        let paper = |a| lp(a).margins(38.24, 27.36);
        assert!(paper(ActuatorLag::Ideal).phase_margin_deg > 20.0);
        assert!(paper(drive).phase_margin_deg < 0.0, "{:?}", paper(drive));
    }
}
