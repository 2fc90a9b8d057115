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
//!
//! With `vehicle.model = "full"` the plant steps the whole car instead
//! ([`vehicle_model::full_car`], the same RK4 at the same step, the corners met wheelset by
//! wheelset). Its output keeps the half vehicle's fields at the car's centre, so the
//! controllers and the comfort assessment take it unchanged (see [`Plant::output`]), and
//! carries the wheel-rail forces and the passengers along the body in `car`.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use tiltsim_protocol::msg::{FromPlant, ToPlant, CAR_VALUES};
use tiltsim_protocol::time::tick_time;
use tiltsim_protocol::{Participant, Role};

use crate::params::PlantSettings;
use vehicle_model::full_car::inputs::inputs_from_track;
use vehicle_model::full_car::{self, FullCar, FullCarParams, FullCarSim, NW};
use vehicle_model::vehicle::{ix, State, TrackInput, Vehicle};
use vehicle_model::{Track, VehicleModel};

/// The whole car as the plant steps it, and the bar angle held over the last step (both
/// drives get the one actuator's δ_a: docs/model.md, "The whole car in a run").
struct Whole {
    sim: FullCarSim,
    delta: f64,
}

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
    /// The whole car, when the scenario asks for it (`x` then stays at zero).
    whole: Option<Box<Whole>>,
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
            whole: (s.vehicle.model == VehicleModel::Full).then(|| {
                let car = FullCar::new(FullCarParams::from_half(&s.vehicle));
                Box::new(Whole {
                    sim: FullCarSim::new(car, v),
                    delta: 0.0,
                })
            }),
        }
    }

    /// The whole car's simulation, when the plant steps it.
    pub fn full_car(&self) -> Option<&FullCarSim> {
        self.whole.as_ref().map(|w| &w.sim)
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
        if let Some(w) = &mut self.whole {
            // The body centre at s = V t, as the half vehicle's bogie is.
            w.sim
                .advance_on_track(&self.track, 0.0, t0, t1 - t0, [delta_a; 2]);
            w.delta = delta_a;
            self.k += 1;
            return;
        }
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
        let slot = self.k / self.noise_hold;
        if let Some(n) = &self.noise {
            // One draw per hold interval, whatever the number of output calls.
            if self.noise_drawn != Some(slot) {
                self.noise_value = n.sample(&mut self.rng);
                self.noise_drawn = Some(slot);
            }
        }
        let noise = self.noise_value;
        let (x, car) = match &self.whole {
            Some(w) => self.whole_outputs(w, t, s),
            None => (self.x.into(), [0.0; CAR_VALUES]),
        };
        let th_v = x[ix::TH_V];
        FromPlant {
            header: Default::default(),
            t,
            s,
            curvature: p.curvature,
            cant: p.cant,
            x,
            psi: th_v - x[ix::TH_B],
            lat_acc: self.vehicle.lateral_acceleration(th_v, p.curvature, p.cant),
            theta_v_meas: th_v + noise,
            car,
        }
    }

    /// The whole car's outputs at time `t`, the body centre at `s = V t`: the half vehicle's
    /// nine states at the car's centre, and `car` (the wheel-rail forces of every wheelset,
    /// the body's lateral acceleration over each bogie and at the centre). The roll angles
    /// (body, mean of the bogies, mean reservoir) and rates are taken relative to the track
    /// plane at the centre, as the half vehicle's are, so that θ_o(s) + θ_v is the body's
    /// roll over the horizontal (the whole car's own φ_c is relative to the mean plane of its
    /// four wheelsets, which a cant irregularity makes differ); the bogie's lateral and its
    /// rate are those for which the half vehicle's y_v − h1 θ_v − y_b − h2 θ_b is the mean of
    /// the two secondary deflections, the chord's versine and the body's yaw included.
    fn whole_outputs(&self, w: &Whole, t: f64, s: f64) -> ([f64; 9], [f64; CAR_VALUES]) {
        use full_car::ix as c;
        let sim = &w.sim;
        let z = sim.state();
        let p = &sim.car.p;
        let inputs = inputs_from_track(p, &self.track, s, sim.v);
        let (tb, tc) = full_car::dynamics::body_tracks(&inputs);
        let eq = sim.car.equations(sim.v);
        let d: [(f64, f64, f64); 2] =
            std::array::from_fn(|i| eq.secondary_deflection(z.as_slice(), i, &tb[i], &tc));
        let shift = tc.cant - self.track.at(s).cant;
        let dshift = tc.cant_rate - self.track.cant_rate_at_time(t, sim.v);
        let mean = |f: fn(usize) -> usize| 0.5 * (z[f(0)] + z[f(1)]);
        let rate = |k: usize| z[c::rate(k)];
        let (th_v, dth_v) = (z[c::PHI_C] + shift, rate(c::PHI_C) + dshift);
        let th_b = mean(c::phi_b) + shift;
        let dth_b = 0.5 * (rate(c::phi_b(0)) + rate(c::phi_b(1))) + dshift;
        let x = [
            z[c::Y_C],
            th_v,
            z[c::Y_C] - p.h1 * th_v - p.h2 * th_b - 0.5 * (d[0].0 + d[1].0),
            th_b,
            rate(c::Y_C),
            dth_v,
            rate(c::Y_C) - p.h1 * dth_v - p.h2 * dth_b - 0.5 * (d[0].1 + d[1].1),
            dth_b,
            mean(c::th_r) + shift,
        ];
        let mut car = [0.0; CAR_VALUES];
        for (j, f) in sim.wheel_forces(&inputs).iter().enumerate() {
            car[5 * j..5 * j + 5]
                .copy_from_slice(&[f.sum_y, f.y_plus, f.y_minus, f.q_plus, f.q_minus]);
        }
        let places = sim.standard_places();
        for (i, q) in sim
            .passengers([w.delta; 2], &inputs, &places)
            .iter()
            .enumerate()
        {
            car[5 * NW + i] = q.lateral_acc;
        }
        (x, car)
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
