//! Studies of a whole line: a route file ([`file`]), its speed profiles ([`profile`]), the
//! route cut into segments run in parallel ([`run`]), and what a tilt engineer reads from
//! them ([`study`]: journey times, P_CT at every transition, N_MV on the straights, the
//! motion-sickness doses, the limit that binds at each curve, the compensation trade-off and
//! the sensitivity to the reading of EN 12299; written by [`outputs`]).

pub mod file;
pub mod outputs;
pub mod plots;
pub mod profile;
pub mod run;
pub mod study;

pub use file::{load, Route, RouteError};
pub use profile::{Limits, Profile, Running};
pub use study::{study, variants, Grid, Variant, VariantResult};
