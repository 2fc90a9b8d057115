//! Where the controller believes the vehicle is: the position it reads its track database at,
//! with the error of a real localisation (odometry drifting between balises, a balise read
//! late): a bias and a noise held for a while, drawn from the run's seed.
//!
//! ±10 m is about ±0.2 s on the paper's 2.4 s transition at 162 km/h: enough to move the
//! corner peaks that decide P_CT.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;

/// The localisation error (`[controller.localisation]`); all zero by default (the controller
/// knows the true position, as in the paper).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LocalisationSettings {
    /// Constant error of the believed position (m); positive believes the vehicle further on.
    pub bias_m: f64,
    /// Standard deviation of a Gaussian error added to the bias (m).
    pub noise_std_m: f64,
    /// How long each noise sample is held (s).
    pub hold_s: f64,
}

impl Default for LocalisationSettings {
    fn default() -> Self {
        LocalisationSettings {
            bias_m: 0.0,
            noise_std_m: 0.0,
            hold_s: 1.0,
        }
    }
}

impl LocalisationSettings {
    /// Checks every field under `c` (its prefix is the controller section).
    pub fn validate(&self, c: &mut Checker) {
        c.range("localisation.bias_m", self.bias_m, -1000.0, 1000.0, "m");
        c.range(
            "localisation.noise_std_m",
            self.noise_std_m,
            0.0,
            1000.0,
            "m",
        );
        c.positive("localisation.hold_s", self.hold_s, 3600.0, "s");
    }
}

/// The believed position, one controller update at a time.
#[derive(Debug, Clone)]
pub struct Localiser {
    bias: f64,
    noise: Option<Normal<f64>>,
    hold_s: f64,
    rng: ChaCha8Rng,
    /// The hold interval the current noise value was drawn for.
    slot: Option<u64>,
    value: f64,
}

impl Localiser {
    /// A localiser with the error of `s`, its noise drawn from `seed` (a stream of its own).
    pub fn new(s: &LocalisationSettings, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Streams of the run's seed: 1 the track's knots, 2 the roll sensor, 3 and 4 the
        // track irregularity; 5 is this.
        rng.set_stream(5);
        Localiser {
            bias: s.bias_m,
            noise: (s.noise_std_m > 0.0)
                .then(|| Normal::new(0.0, s.noise_std_m).expect("validated finite and > 0")),
            hold_s: s.hold_s,
            rng,
            slot: None,
            value: 0.0,
        }
    }

    /// The position believed at time `t` (s) when the vehicle is at `s` (m).
    pub fn position(&mut self, t: f64, s: f64) -> f64 {
        if let Some(n) = &self.noise {
            // One draw per hold interval (a millisecond's rounding of t kept off the edges).
            let slot = ((t + 1e-9) / self.hold_s).floor().max(0.0) as u64;
            if self.slot != Some(slot) {
                self.value = n.sample(&mut self.rng);
                self.slot = Some(slot);
            }
        }
        s + self.bias + self.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bias_shifts_and_the_noise_has_its_spread_held_and_seeded() {
        let none = LocalisationSettings::default();
        assert_eq!(Localiser::new(&none, 1).position(3.0, 120.0), 120.0);
        let bias = LocalisationSettings {
            bias_m: -10.0,
            ..none.clone()
        };
        assert_eq!(Localiser::new(&bias, 1).position(3.0, 120.0), 110.0);

        let noisy = LocalisationSettings {
            noise_std_m: 5.0,
            hold_s: 0.5,
            ..none
        };
        let draws = |seed: u64| {
            let mut l = Localiser::new(&noisy, seed);
            // Every millisecond for 2000 s: 4000 hold intervals.
            (0..2_000_000)
                .map(|k| l.position(k as f64 * 1e-3, 0.0))
                .collect::<Vec<f64>>()
        };
        let a = draws(7);
        // Held: constant within each 0.5 s interval, new at each.
        assert!(a[..500].iter().all(|&x| x == a[0]));
        assert_ne!(a[499], a[500]);
        let held: Vec<f64> = a.iter().step_by(500).copied().collect();
        assert_eq!(held.len(), 4000);
        let n = held.len() as f64;
        let mean = held.iter().sum::<f64>() / n;
        let sd = (held.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        // 4000 draws: the mean within 4 standard errors (5/√4000 = 0.08 m), the standard
        // deviation within 5 % (its standard error is 5/√8000 = 0.056 m, 1.1 %).
        assert!(mean.abs() < 0.32, "mean {mean}");
        assert!((sd - 5.0).abs() < 0.25, "sd {sd}");
        assert_eq!(a, draws(7), "the same seed gives the same error");
        assert_ne!(a, draws(8), "another seed another");
    }
}
