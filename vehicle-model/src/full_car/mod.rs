//! The whole car: carbody, two bogies and four wheelsets in lateral, yaw and roll, beside the
//! paper's half vehicle ([`crate::vehicle`]). docs/model.md, "The whole car", gives the
//! equations, parameters and sources.
//!
//! * [`params`]: [`FullCarParams`], built on the half vehicle's values.
//! * [`contact`]: Hertz contact ellipse and Kalker's linear creep coefficients.
//! * [`inputs`]: the track under each wheelset, with the delays between them.
//! * [`dynamics`]: the equations of motion, linear in state, drives and track.
//! * [`outputs`]: wheel-rail forces and passengers' lateral acceleration and roll.
//! * [`sim`]: RK4 at a fixed step, as the half vehicle's plant integrates.
//! * [`safety`]: running safety (EN 14363 quantities and limits).
//! * [`wheelset`]: one wheelset on springs to a frame that follows the track.
//!
//! Tilt: one drive per bogie, each twisting that bogie's anti-roll bar (input δ_1, δ_2).

pub mod contact;
pub mod dynamics;
pub mod inputs;
pub mod outputs;
pub mod params;
pub mod safety;
pub mod sim;
pub mod wheelset;

use nalgebra::{DMatrix, SMatrix, SVector};

pub use contact::Creep;
pub use dynamics::{ix, Equations, NQ, NX};
pub use inputs::{CarInputs, TrackSample, WheelsetInput, NW, NWI};
pub use outputs::{Passenger, WheelForces};
pub use params::FullCarParams;
pub use safety::{RunningSafety, SafetyLimits};
pub use sim::FullCarSim;

/// Inputs: the two drives' bar angles δ_1, δ_2, then [κ, κ̇, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o] for each
/// wheelset, leading first.
pub const NU: usize = 2 + NW * NWI;
/// Outputs of the force map: for each wheelset, ΣY (rails on wheelset, N) and
/// (Q_+y − Q_−y)/2 (N).
pub const NY: usize = 2 * NW;

/// State vector.
pub type State = SVector<f64, NX>;

/// Column of input `k` (0..NWI) of wheelset `j` in B.
pub const fn input_col(j: usize, k: usize) -> usize {
    2 + j * NWI + k
}

/// Continuous state space x' = A x + B u, and the wheelset force map y = C x + D u.
#[derive(Debug, Clone)]
pub struct FullCarStateSpace {
    /// A (NX × NX).
    pub a: SMatrix<f64, NX, NX>,
    /// B (NX × NU).
    pub b: SMatrix<f64, NX, NU>,
    /// C (NY × NX).
    pub c: SMatrix<f64, NY, NX>,
    /// D (NY × NU).
    pub d: SMatrix<f64, NY, NU>,
}

/// The whole car's model: parameters and the creep coefficients at the static wheel load.
#[derive(Debug, Clone)]
pub struct FullCar {
    /// Parameters.
    pub p: FullCarParams,
    /// Creep coefficients of one wheel at Q_0.
    pub creep: Creep,
}

fn split_u(u: &[f64]) -> ([f64; 2], CarInputs) {
    let w =
        std::array::from_fn(|j| WheelsetInput::from_array(&u[input_col(j, 0)..input_col(j, NWI)]));
    ([u[0], u[1]], w)
}

impl FullCar {
    /// The car with Kalker's coefficients at its static wheel load.
    pub fn new(p: FullCarParams) -> Self {
        let creep = Creep::new(
            p.static_wheel_load(),
            p.r0,
            p.rail_crown_radius,
            p.young,
            p.poisson,
            p.creep_factor,
        );
        FullCar { p, creep }
    }

    /// The equations at speed `v` (m/s).
    pub fn equations(&self, v: f64) -> Equations<'_> {
        Equations {
            p: &self.p,
            creep: self.creep,
            v,
        }
    }

    /// A, B, C, D at speed `v`, by unit vectors through the equations themselves (they are
    /// linear, so this is exact): one source of truth for simulation and analysis.
    pub fn state_space(&self, v: f64) -> FullCarStateSpace {
        let eq = self.equations(v);
        let f = |x: &[f64], u: &[f64]| {
            let (d, w) = split_u(u);
            (eq.deriv(x, d, &w), outputs::force_vector(&eq, x, &w))
        };
        let (x0, u0) = ([0.0; NX], [0.0; NU]);
        let (f0, y0) = f(&x0, &u0);
        let mut ss = FullCarStateSpace {
            a: SMatrix::zeros(),
            b: SMatrix::zeros(),
            c: SMatrix::zeros(),
            d: SMatrix::zeros(),
        };
        for k in 0..NX {
            let mut x = x0;
            x[k] = 1.0;
            let (fx, yx) = f(&x, &u0);
            for r in 0..NX {
                ss.a[(r, k)] = fx[r] - f0[r];
            }
            for r in 0..NY {
                ss.c[(r, k)] = yx[r] - y0[r];
            }
        }
        for k in 0..NU {
            let mut u = u0;
            u[k] = 1.0;
            let (fu, yu) = f(&x0, &u);
            for r in 0..NX {
                ss.b[(r, k)] = fu[r] - f0[r];
            }
            for r in 0..NY {
                ss.d[(r, k)] = yu[r] - y0[r];
            }
        }
        ss
    }

    /// Largest real part of the eigenvalues of A at speed `v` (1/s).
    pub fn max_real_part(&self, v: f64) -> f64 {
        max_real_part(&DMatrix::from_column_slice(
            NX,
            NX,
            self.state_space(v).a.as_slice(),
        ))
    }

    /// The critical (hunting) speed of the passive car (m/s): the lowest speed in [lo, hi] at
    /// which an eigenvalue reaches the imaginary axis, by bisection to `tol` (m/s); `None`
    /// unless the car is stable at `lo` and unstable at `hi`.
    pub fn critical_speed(&self, lo: f64, hi: f64, tol: f64) -> Option<f64> {
        bisect_stability(|v| self.max_real_part(v), lo, hi, tol)
    }

    /// The static solution on a steady curve: x with A x + B u + flange forces = 0 for the
    /// track `w` at every wheelset, drives at `delta` (rad), speed `v`. The flanges are found
    /// by an active set: solve, put every wheelset beyond its clearance on its flange (an
    /// affine force), solve again until the set no longer changes.
    pub fn steady_state(&self, v: f64, delta: [f64; 2], w: WheelsetInput) -> State {
        let ss = self.state_space(v);
        let mut u = SVector::<f64, NU>::zeros();
        u[0] = delta[0];
        u[1] = delta[1];
        for j in 0..NW {
            for (k, val) in w.to_array().iter().enumerate() {
                u[input_col(j, k)] = *val;
            }
        }
        let bu = ss.b * u;
        let p = &self.p;
        let mut side = [0.0_f64; NW]; // −1, 0, +1: which flange each wheelset runs on
        for _ in 0..=2 * NW {
            let mut a = DMatrix::from_column_slice(NX, NX, ss.a.as_slice());
            let mut rhs = DMatrix::from_column_slice(NX, 1, (-bu).as_slice());
            for (j, &s) in side.iter().enumerate() {
                if s != 0.0 && p.k_flange > 0.0 {
                    let (r, c) = (ix::rate(ix::y_w(j)), ix::y_w(j));
                    a[(r, c)] -= p.k_flange / p.m_w;
                    rhs[r] -= p.k_flange * (w.y_o + s * p.flange_clearance) / p.m_w;
                }
            }
            let sol = a
                .lu()
                .solve(&rhs)
                .expect("A is regular: every body is held to the track");
            let x = State::from_column_slice(sol.as_slice());
            let next: [f64; NW] = std::array::from_fn(|j| {
                let d = x[ix::y_w(j)] - w.y_o;
                if p.k_flange > 0.0 && d.abs() > p.flange_clearance {
                    d.signum()
                } else {
                    0.0
                }
            });
            if next == side {
                return x;
            }
            side = next;
        }
        panic!("the flanges' active set does not settle");
    }
}

/// Largest real part of the eigenvalues of a square matrix.
pub fn max_real_part(a: &DMatrix<f64>) -> f64 {
    a.complex_eigenvalues()
        .iter()
        .map(|l| l.re)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Bisection for the speed where `max_re` crosses zero from below.
pub fn bisect_stability(max_re: impl Fn(f64) -> f64, lo: f64, hi: f64, tol: f64) -> Option<f64> {
    let (mut lo, mut hi) = (lo, hi);
    if max_re(lo) >= 0.0 || max_re(hi) < 0.0 {
        return None;
    }
    while hi - lo > tol {
        let mid = 0.5 * (lo + hi);
        if max_re(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}
