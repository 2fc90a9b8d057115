//! The plant as a co-simulation participant.
//!
//! Integration: classical RK4 at the plant step (1 ms default). The fastest mode of the
//! vehicle (bogie lateral on the primary suspension, about 27 Hz, |λ| ≈ 170 s⁻¹) gives
//! |λ·h| ≈ 0.17, where RK4's local error is about (λh)⁵/120 ≈ 1e-6 of the state per step and
//! the method is far inside its stability region. On the irregular track a test measures
//! 7e-7 rad of difference in θ_v between 1 ms and 0.25 ms steps (the knots of the
//! irregularity's blend cost RK4 some order), 1000x below the 1 mrad sensor noise. The
//! track is a known function of time, so RK4 evaluates it at its stage times; δ_a is held
//! (zero-order hold) over the step. The cant-rate jumps at the ramp corners are applied as
//! exact velocity jumps at their instants, splitting the step there.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use tiltsim_protocol::msg::{FromPlant, ToPlant};
use tiltsim_protocol::time::tick_time;
use tiltsim_protocol::{Participant, Role};

use crate::params::PlantSettings;
use vehicle_model::vehicle::{ix, State, TrackInput, Vehicle};
use vehicle_model::Track;

/// The plant: vehicle, track, sensor and time.
pub struct Plant {
    vehicle: Vehicle,
    track: Track,
    dt: f64,
    x: State,
    k: u64,
    noise: Option<Normal<f64>>,
    rng: ChaCha8Rng,
    /// Plant steps per noise sample, the sample held and the index it was drawn for.
    noise_hold: u64,
    noise_value: f64,
    noise_drawn: Option<u64>,
}

impl Plant {
    /// A plant at rest at the start of the track.
    pub fn new(s: &PlantSettings) -> Self {
        let v = s.track.speed();
        let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
        rng.set_stream(2);
        let sigma = s.sensor.theta_v_noise_std_rad;
        Plant {
            vehicle: Vehicle::new(s.vehicle.clone(), v),
            track: Track::new(&s.track, s.seed),
            dt: s.dt_s,
            x: State::zeros(),
            k: 0,
            noise: (sigma > 0.0)
                .then(|| Normal::new(0.0, sigma).expect("sigma validated finite and > 0")),
            rng,
            noise_hold: ((s.sensor.noise_hold_s / s.dt_s).round() as u64).max(1),
            noise_value: 0.0,
            noise_drawn: None,
        }
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.x
    }
    /// Sets the state (tests).
    pub fn set_state(&mut self, x: State) {
        self.x = x;
    }
    /// The vehicle model.
    pub fn vehicle(&self) -> &Vehicle {
        &self.vehicle
    }
    /// The track.
    pub fn track(&self) -> &Track {
        &self.track
    }

    fn input_at(&self, t: f64) -> TrackInput {
        let v = self.vehicle.v;
        let p = self.track.at(v * t);
        TrackInput {
            curvature: p.curvature,
            cant: p.cant,
            cant_rate: v * p.dcant_ds,
            cant_acc: v * v * p.d2cant_ds2,
            y_o: p.y_o,
            dy_o: v * p.dy_o_ds,
        }
    }

    fn rk4(&self, x: &State, t: f64, h: f64, delta_a: f64) -> State {
        let f = |x: &State, t: f64| self.vehicle.deriv(x, delta_a, &self.input_at(t));
        let k1 = f(x, t);
        let k2 = f(&(x + k1 * (h / 2.0)), t + h / 2.0);
        let k3 = f(&(x + k2 * (h / 2.0)), t + h / 2.0);
        let k4 = f(&(x + k3 * h), t + h);
        x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)
    }

    /// Advances one plant step with δ_a held.
    pub fn advance(&mut self, delta_a: f64) {
        let t0 = tick_time(self.k, self.dt);
        let t1 = tick_time(self.k + 1, self.dt);
        let v = self.vehicle.v;
        let mut t = t0;
        let mut x = self.x;
        for c in self.track.corners() {
            let tc = c.s / v;
            if tc > t0 && tc <= t1 {
                if tc > t {
                    x = self.rk4(&x, t, tc - t, delta_a);
                    t = tc;
                }
                x += self.vehicle.cant_rate_jump(v * c.dslope);
            }
        }
        if t1 > t {
            x = self.rk4(&x, t, t1 - t, delta_a);
        }
        self.x = x;
        self.k += 1;
    }

    /// Output sample at the current time.
    pub fn output(&mut self) -> FromPlant {
        let t = tick_time(self.k, self.dt);
        let s = self.vehicle.v * t;
        let p = self.track.at(s);
        let th_v = self.x[ix::TH_V];
        let slot = self.k / self.noise_hold;
        if let Some(n) = &self.noise {
            // One draw per hold interval, whatever the number of output calls.
            if self.noise_drawn != Some(slot) {
                self.noise_value = n.sample(&mut self.rng);
                self.noise_drawn = Some(slot);
            }
        }
        let noise = self.noise_value;
        FromPlant {
            header: Default::default(),
            t,
            s,
            curvature: p.curvature,
            cant: p.cant,
            x: self.x.into(),
            psi: th_v - self.x[ix::TH_B],
            lat_acc: self.vehicle.lateral_acceleration(th_v, p.curvature, p.cant),
            theta_v_meas: th_v + noise,
        }
    }
}

impl Participant for Plant {
    type Input = ToPlant;
    type Output = FromPlant;
    const ROLE: Role = Role::Plant;

    fn initial_output(&mut self) -> FromPlant {
        self.output()
    }

    fn step(&mut self, input: &ToPlant) -> FromPlant {
        self.advance(input.delta_a);
        self.output()
    }
}
