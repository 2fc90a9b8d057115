//! Time integration of the whole car: classical RK4 on x' = A x + B u at a fixed step, the
//! track evaluated at the stage times and the drives held over the step, as the half
//! vehicle's plant integrates (docs/model.md, "Integration").

use nalgebra::SVector;

use super::inputs::{inputs_from_track, CarInputs, NW};
use super::outputs::{passengers, wheel_forces, Passenger, WheelForces};
use super::{input_col, ix, FullCar, FullCarStateSpace, State, NU};
use crate::track::Track;

/// A running car at one speed.
#[derive(Debug, Clone)]
pub struct FullCarSim {
    /// The model.
    pub car: FullCar,
    /// Speed V (m/s).
    pub v: f64,
    ss: FullCarStateSpace,
    x: State,
    t: f64,
}

fn input_vector(delta: [f64; 2], w: &CarInputs) -> SVector<f64, NU> {
    let mut u = SVector::<f64, NU>::zeros();
    u[0] = delta[0];
    u[1] = delta[1];
    for (j, wj) in w.iter().enumerate() {
        for (k, val) in wj.to_array().iter().enumerate() {
            u[input_col(j, k)] = *val;
        }
    }
    u
}

impl FullCarSim {
    /// The car at rest relative to the track at speed `v` (m/s).
    pub fn new(car: FullCar, v: f64) -> Self {
        let ss = car.state_space(v);
        FullCarSim {
            car,
            v,
            ss,
            x: State::zeros(),
            t: 0.0,
        }
    }
    /// The state.
    pub fn state(&self) -> &State {
        &self.x
    }
    /// Sets the state.
    pub fn set_state(&mut self, x: State) {
        self.x = x;
    }
    /// Time since the start (s).
    pub fn time(&self) -> f64 {
        self.t
    }
    /// The state space in use.
    pub fn state_space(&self) -> &FullCarStateSpace {
        &self.ss
    }

    /// The flanges' lateral acceleration of each wheelset (the model's one nonlinear element,
    /// left out of the state space), added to x' = A x + B u.
    fn flange_acc(&self, x: &State, w: &CarInputs) -> State {
        let p = &self.car.p;
        let mut f = State::zeros();
        if p.k_flange > 0.0 {
            for (j, wj) in w.iter().enumerate() {
                let y = x[ix::y_w(j)] - wj.y_o;
                f[ix::rate(ix::y_w(j))] = p.flange_force(y) / p.m_w;
            }
        }
        f
    }

    /// Advances one step `h` (s) with the drives' bar angles `delta` (rad) held and the track
    /// `track(τ)` at time τ ∈ [0, h] into the step.
    pub fn step(&mut self, h: f64, delta: [f64; 2], track: impl Fn(f64) -> CarInputs) {
        let (w0, wm, w1) = (track(0.0), track(0.5 * h), track(h));
        let (u0, um, u1) = (
            input_vector(delta, &w0),
            input_vector(delta, &wm),
            input_vector(delta, &w1),
        );
        let (a, b) = (&self.ss.a, &self.ss.b);
        let f =
            |x: &State, u: &SVector<f64, NU>, w: &CarInputs| a * x + b * u + self.flange_acc(x, w);
        let x = self.x;
        let k1 = f(&x, &u0, &w0);
        let k2 = f(&(x + k1 * (h / 2.0)), &um, &wm);
        let k3 = f(&(x + k2 * (h / 2.0)), &um, &wm);
        let k4 = f(&(x + k3 * h), &u1, &w1);
        self.x = x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        self.t += h;
    }

    /// Applies the velocity jump of a jump `d_rate` (rad/s) of the cant rate under wheelset
    /// `j` (a ramp corner reaching it): the integral of B's θ̈_o column across the impulse.
    pub fn cant_rate_jump(&mut self, j: usize, d_rate: f64) {
        let col = self.ss.b.column(input_col(j, 4)).into_owned();
        self.x += col * d_rate;
    }

    /// Advances from time `t0` to `t0 + h` on the project's `track`, the body centre at
    /// s = s0 + V t, as the half vehicle's plant does: the step is split at every instant a
    /// ramp corner reaches a wheelset (at s_corner − x_j from the body centre), where that
    /// wheelset's cant-rate jump is applied, and RK4 covers the pieces between.
    pub fn advance_on_track(&mut self, track: &Track, s0: f64, t0: f64, h: f64, delta: [f64; 2]) {
        let v = self.v;
        let p = self.car.p.clone();
        let mut events: Vec<(f64, usize, f64)> = Vec::new();
        for c in track.corners() {
            for j in 0..NW {
                let tc = (c.s - p.wheelset_x(j) - s0) / v;
                if tc > t0 && tc <= t0 + h {
                    events.push((tc, j, v * c.dslope));
                }
            }
        }
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut t = t0;
        for (tc, j, d_rate) in events {
            if tc > t {
                let start = t;
                self.step(tc - t, delta, |tau| {
                    inputs_from_track(&p, track, s0 + v * (start + tau), v)
                });
                t = tc;
            }
            self.cant_rate_jump(j, d_rate);
        }
        if t0 + h > t {
            let start = t;
            self.step(t0 + h - t, delta, |tau| {
                inputs_from_track(&p, track, s0 + v * (start + tau), v)
            });
        }
    }

    /// Wheel forces now, with the track `w` under the wheelsets.
    pub fn wheel_forces(&self, w: &CarInputs) -> [WheelForces; NW] {
        wheel_forces(&self.car.equations(self.v), self.x.as_slice(), w)
    }

    /// Passengers at `places` (x along the body, z above its c.o.g.) now.
    pub fn passengers(
        &self,
        delta: [f64; 2],
        w: &CarInputs,
        places: &[(f64, f64)],
    ) -> Vec<Passenger> {
        passengers(
            &self.car.equations(self.v),
            self.x.as_slice(),
            delta,
            w,
            places,
        )
    }

    /// The usual places: over the leading bogie, at the centre, over the trailing bogie, at
    /// the body's c.o.g. height.
    pub fn standard_places(&self) -> [(f64, f64); 3] {
        [(self.car.p.a, 0.0), (0.0, 0.0), (-self.car.p.a, 0.0)]
    }
}
