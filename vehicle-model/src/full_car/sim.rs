//! Time integration of the whole car: classical RK4 on x' = A x + B u at a fixed step, the
//! track evaluated at the stage times and the drives held over the step, as the half
//! vehicle's plant integrates (docs/model.md, "Integration").

use nalgebra::SVector;

use super::inputs::{CarInputs, NW};
use super::outputs::{passengers, wheel_forces, Passenger, WheelForces};
use super::{input_col, FullCar, FullCarStateSpace, State, NU};

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

    /// Advances one step `h` (s) with the drives' bar angles `delta` (rad) held and the track
    /// `track(τ)` at time τ ∈ [0, h] into the step.
    pub fn step(&mut self, h: f64, delta: [f64; 2], track: impl Fn(f64) -> CarInputs) {
        let u0 = input_vector(delta, &track(0.0));
        let um = input_vector(delta, &track(0.5 * h));
        let u1 = input_vector(delta, &track(h));
        let (a, b) = (&self.ss.a, &self.ss.b);
        let f = |x: &State, u: &SVector<f64, NU>| a * x + b * u;
        let x = self.x;
        let k1 = f(&x, &u0);
        let k2 = f(&(x + k1 * (h / 2.0)), &um);
        let k3 = f(&(x + k2 * (h / 2.0)), &um);
        let k4 = f(&(x + k3 * h), &u1);
        self.x = x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        self.t += h;
    }

    /// Applies the velocity jump of a jump `d_rate` (rad/s) of the cant rate under wheelset
    /// `j` (a ramp corner reaching it): the integral of B's θ̈_o column across the impulse.
    pub fn cant_rate_jump(&mut self, j: usize, d_rate: f64) {
        let col = self.ss.b.column(input_col(j, 4)).into_owned();
        self.x += col * d_rate;
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
