//! `tiltsim-assessment`: the railway assessment of a ride, computed from samples alone. It
//! knows nothing of processes, scenario files or recordings: a caller feeds it one sample per
//! plant step and reads the result.
//!
//! * [`comfort`]: the comfort indices of the paper's Table 4 (P_CT, the EN 12299 filters, the
//!   lateral-acceleration and jerk figures) and [`comfort::METRICS`], the one metric table
//!   that compare, sweeps and their plots are driven by. Use [`comfort::Assessor`]: `new`
//!   with the step and the curve transitions, `push` a [`comfort::Sample`] per step,
//!   `finish` for the [`comfort::Comfort`].
//! * [`validity`]: whether a run's numbers mean what they say ([`validity::Flagger`], the
//!   same `push` / `finish` shape, giving [`validity::Flags`]).
//! * [`running_safety`]: the whole car's running safety from its wheel-rail forces, against
//!   EN 14363's limits, and the report of comfort along the car.

pub mod comfort;
pub mod running_safety;
pub mod validity;
