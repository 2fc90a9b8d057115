//! Passengers where they are: the accelerations at a point of the carbody away from its centre
//! of gravity, from the rigid body's kinematics, and the comfort there.
//!
//! The body rolls by φ (absolute, positive leaning into the curve) about the track's
//! longitudinal axis. The lateral signals are along the model's lateral axis, positive towards
//! the inside of the curve (y_v of eq 9; eq 13's ÿ is the inward specific force the
//! passenger is given): a point z above the centre of gravity moves inwards by z·θ_v when the
//! body rolls, as the secondary suspension h1 below it moves by −h1·θ_v in Δs. A point at
//! height `h` above the rail and `y` from the centre line (positive towards the outside of the
//! curve, where a window seat of the curve's outer side is) has the centre's acceleration
//! plus α × r + ω × (ω × r):
//! * lateral (inwards): ÿ_P = ÿ_G + (h − h_gv)·φ̈ + y·φ̇²,
//! * vertical (upwards): z̈_P = y·φ̈ − (h − h_gv)·φ̇².
//!
//! The model has no vertical suspension motion: z̈_P is the part of the vertical acceleration
//! the body's roll gives, and the ride index built from it says so (`n_mv_roll`).

use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;

use super::sample::Sample;
use super::{Pct, Ride};

/// A point of the carbody where passengers are (`[[comfort.positions]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Position {
    /// Its name, as the summary and the tables give it.
    pub name: String,
    /// Height above the rail (m).
    pub height_m: f64,
    /// Lateral offset from the centre line (m), positive towards the outside of the curve.
    pub offset_m: f64,
}

impl Position {
    /// The default positions: the floor on the centre line, where EN 12299 measures the mean
    /// comfort (floor 1.20 m above the rail), and a window seat (seat pan 0.45 m above that
    /// floor, 1.0 m off the centre line), where a seated passenger feels the roll most.
    pub fn defaults() -> Vec<Position> {
        vec![
            Position {
                name: "floor-centre".into(),
                height_m: 1.20,
                offset_m: 0.0,
            },
            Position {
                name: "seat-window".into(),
                height_m: 1.65,
                offset_m: 1.0,
            },
        ]
    }

    /// Checks the positions, by name, under `c`.
    pub fn validate_all(positions: &[Position], c: &mut Checker) {
        for (i, p) in positions.iter().enumerate() {
            let at = format!("positions[{i}]");
            c.require(
                !p.name.trim().is_empty(),
                &format!("{at}.name"),
                "\"\"",
                "a name for the position",
            );
            c.require(
                !positions[..i].iter().any(|q| q.name == p.name),
                &format!("{at}.name"),
                format!("{:?}", p.name),
                "a name no other position has",
            );
            c.range(&format!("{at}.height_m"), p.height_m, 0.0, 5.0, "m");
            c.range(&format!("{at}.offset_m"), p.offset_m, -2.5, 2.5, "m");
        }
    }

    /// `x`, the signals at the centre of gravity (height `cog_height` m), moved to this
    /// point, with the body's absolute roll speed φ̇ = `x.roll_speed` and roll acceleration
    /// `roll_acc` (rad/s²).
    pub fn moved(&self, x: &Sample, roll_acc: f64, cog_height: f64) -> Sample {
        let z = self.height_m - cog_height;
        let (w2, y) = (x.roll_speed * x.roll_speed, self.offset_m);
        let lateral = z * roll_acc + y * w2;
        Sample {
            lat_acc: x.lat_acc + lateral,
            lat_acc_other: x.lat_acc_other + lateral,
            vertical: y * roll_acc - z * w2,
            ..*x
        }
    }
}

/// The comfort at one [`Position`] (`summary.json` → `comfort.positions`).
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct PositionComfort {
    /// The position's name.
    pub name: String,
    /// Height above the rail (m).
    pub height_m: f64,
    /// Lateral offset from the centre line (m).
    pub offset_m: f64,
    /// P_CT there, the standard's evaluation.
    pub p_ct_en12299: Pct,
    /// P_CT there, the paper's form (whole-run peaks).
    pub p_ct_paper: Pct,
    /// Largest |lateral acceleration| there (%g).
    pub lat_acc_peak_pct_g: f64,
    /// The straight-track ride there, with the vertical part from roll (`n_mv_roll`).
    pub ride: Ride,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The point's acceleration from its world coordinates, differenced twice, turned into
    /// the body's axes: an independent route to the kinematics of [`Position::moved`].
    #[test]
    fn the_moved_signals_are_the_rigid_bodys_acceleration_at_the_point() {
        let (amp, w) = (0.05, std::f64::consts::TAU * 1.5);
        let phi = |t: f64| amp * (w * t).sin();
        let p = Position {
            name: "p".into(),
            height_m: 1.52 + 0.3,
            offset_m: 1.0,
        };
        let (y, z) = (p.offset_m, p.height_m - 1.52);
        // Body axes to world, lateral positive inwards: leaning into the curve (φ > 0) moves
        // the top inwards and the outer side (inward coordinate −y) up.
        let world = |t: f64| {
            let (f, yi) = (phi(t), -y);
            (yi * f.cos() + z * f.sin(), -yi * f.sin() + z * f.cos())
        };
        let h = 1e-4;
        for k in 0..50 {
            let t = 0.013 * k as f64;
            let (a, b, c) = (world(t - h), world(t), world(t + h));
            let ay = (a.0 - 2.0 * b.0 + c.0) / (h * h);
            let az = (a.1 - 2.0 * b.1 + c.1) / (h * h);
            let f = phi(t);
            // World acceleration into the body's axes (the inverse of the rotation above).
            let (body_y, body_z) = (ay * f.cos() - az * f.sin(), ay * f.sin() + az * f.cos());
            let rate = amp * w * (w * t).cos();
            let acc = -amp * w * w * (w * t).sin();
            let centre = Sample {
                roll_speed: rate,
                ..Default::default()
            };
            let m = p.moved(&centre, acc, 1.52);
            // Second differences at h = 0.1 ms: truncation ~h²·φ⁗ and rounding ~1e-16/h².
            assert!(
                (m.lat_acc - body_y).abs() < 2e-6,
                "{} {}",
                m.lat_acc,
                body_y
            );
            assert!(
                (m.vertical - body_z).abs() < 2e-6,
                "{} {}",
                m.vertical,
                body_z
            );
        }
    }
}
