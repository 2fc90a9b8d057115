//! The models' numbers: the plant's physics against independent values, the actuator, the
//! tilt controllers, ride comfort, the controller comparison and the figures `docs/results.md`
//! quotes. Every run here is in-process (`tiltsim run --transport in-process`, `tiltsim
//! compare`) or a plain library call; nothing needs a tool from outside the workspace.

mod actuator;
mod comfort;
mod controllers;
mod results_doc;
mod tilt_comparison;
mod vehicle_physics;
