//! `plant-proc`: the plant process. The vehicle model and the track are in `vehicle-model`
//! (re-exported here); this crate adds what the plant participant does with them.
//!
//! * [`params`]: sensor settings and the plant's init message.
//! * [`plant`]: the plant as a co-simulation participant: RK4 at the plant step, exact
//!   treatment of the impulsive θ̈_o at the transition corners, sensor noise.

pub mod params;
pub mod plant;

pub use params::{PlantSettings, SensorParams};
pub use plant::Plant;
pub use vehicle_model::{track, vehicle, G};
pub use vehicle_model::{
    IrregularityParams, Track, TrackInput, TrackParams, Vehicle, VehicleParams,
};

/// Participant process entry: `--params JSON --prefix P --wait W`.
#[cfg(feature = "process")]
pub fn serve(args: &[String]) -> Result<(), cosim::ipc::ServeError> {
    cosim::ipc::participant_main(args, |s: PlantSettings| Ok(Plant::new(&s)))
}
