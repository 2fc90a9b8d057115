//! `plant-proc`: the tilting vehicle's end-view model and the track it runs on.
//!
//! * [`params`]: vehicle, track and sensor settings with the paper's values as defaults.
//! * [`track`]: deterministic curve (straight, transition, steady curve, transition, straight)
//!   and the seeded, band-limited cant irregularity.
//! * [`vehicle`]: the 9-state model of paper eqs 9-13 and A.2, read as `model-notes.md` says.
//! * [`plant`]: the plant as a co-simulation participant: RK4 at the plant step, exact
//!   treatment of the impulsive θ̈_o at the transition corners, sensor noise.

pub mod params;
pub mod plant;
pub mod track;
pub mod vehicle;

pub use params::{PlantSettings, SensorParams, TrackParams, VehicleParams};
pub use plant::Plant;
pub use track::Track;
pub use vehicle::{TrackInput, Vehicle};

/// Standard gravity (m/s²).
pub const G: f64 = 9.81;

/// Participant process entry: `--params JSON --prefix P --wait W`.
pub fn serve(args: &[String]) -> Result<(), String> {
    cosim::ipc::participant_main(args, |s: PlantSettings| Ok(Plant::new(&s)))
}
