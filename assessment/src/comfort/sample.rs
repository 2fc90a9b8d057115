//! [`Sample`]: the comfort signals at one instant, as the assessors (P_CT in `assessor`, the
//! ride indices in `ride`) take them one plant step at a time.

/// The comfort signals at one instant (the fields of [`Signals`](super::Signals)).
#[derive(Debug, Clone, Copy, Default)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// ÿ (m/s²).
    pub lat_acc: f64,
    /// ÿ reference (m/s²).
    pub lat_acc_ref: f64,
    /// φ̇ (rad/s).
    pub roll_speed: f64,
    /// φ̇ reference (rad/s).
    pub roll_speed_ref: f64,
    /// Δs (m).
    pub deflection: f64,
    /// The other form of the passenger lateral acceleration (m/s²); see
    /// [`LateralAcceleration`](super::LateralAcceleration).
    pub lat_acc_other: f64,
    /// Tilt error θ_v − θ_v^d (rad).
    pub tilt_error: f64,
    /// Vertical acceleration at the passenger from the body's roll (m/s²); 0 on the centre
    /// line (see [`super::Position`]).
    pub vertical: f64,
}
