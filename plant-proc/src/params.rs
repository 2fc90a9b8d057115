//! Sensor settings and what the plant process receives. Defaults are the paper's values
//! (section 2.3, eq 15). The vehicle and track parameters live in `vehicle-model`.

use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;
use vehicle_model::{TrackParams, VehicleParams};

/// Body roll sensor (paper eq 15).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// Standard deviation of the Gaussian noise on θ_v (rad). 1 mrad: band-limited white noise
    /// of power 1e-7 at 0.1 s (model-notes, Controllers), variance 1e-7/0.1 = 1e-6 rad².
    pub theta_v_noise_std_rad: f64,
    /// How long each noise sample is held (s): 0.1 s in the paper's band-limited white noise;
    /// 0 draws a new sample every plant step.
    pub noise_hold_s: f64,
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            theta_v_noise_std_rad: 1e-3,
            noise_hold_s: 0.1,
        }
    }
}

impl SensorParams {
    /// Checks every field.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        c.range(
            "theta_v_noise_std_rad",
            self.theta_v_noise_std_rad,
            0.0,
            0.1,
            "rad",
        );
        c.range("noise_hold_s", self.noise_hold_s, 0.0, 10.0, "s");
        c
    }
}

/// Everything the plant process needs, sent to it as JSON by the orchestrator.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct PlantSettings {
    /// Vehicle parameters.
    pub vehicle: VehicleParams,
    /// Track.
    pub track: TrackParams,
    /// Sensor.
    pub sensor: SensorParams,
    /// Plant step (s).
    pub dt_s: f64,
    /// Seed of the run (irregularity and sensor noise).
    pub seed: u64,
}
