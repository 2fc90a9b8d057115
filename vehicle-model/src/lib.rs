//! `vehicle-model`: the tilting vehicle's end-view model and the track it runs on, shared by
//! the plant (which simulates them) and the controller (whose design model and onboard track
//! database they are), so that no process crate depends on another.
//!
//! * [`params`]: vehicle and track settings with the paper's values as defaults.
//! * [`track`]: deterministic curve (straight, transition, steady curve, transition, straight)
//!   and the seeded, band-limited irregularity (the paper's random cant, or alignment and
//!   cross-level drawn from the ERRI B176 spectra of [`spectrum`]).
//! * [`vehicle`]: the 9-state model of paper eqs 9-13 and A.2, read as `model-notes.md` says.
//! * [`full_car`]: the whole car beside it: body, two bogies and four wheelsets on the rails
//!   through creep forces, one tilt drive per bogie, wheel forces and running safety.

pub mod full_car;
pub mod params;
pub mod spectrum;
pub mod track;
pub mod vehicle;

pub use params::{
    IrregularityModel, IrregularityParams, TrackParams, TransitionShape, VehicleModel,
    VehicleParams,
};
pub use track::Track;
pub use vehicle::{TrackInput, Vehicle};

/// Standard gravity (m/s²).
pub const G: f64 = 9.81;
