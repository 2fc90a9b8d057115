//! FMI for tiltsim.
//!
//! * [`layout`]: the variables of a participant's FMU (inputs, outputs, parameters, value
//!   references), shared by the exporter and the FMU's library.
//! * [`description`]: `modelDescription.xml`, written (FMI 3.0) and read (FMI 2.0 and 3.0).
//! * [`archive`]: FMU archives, written and unpacked.
//! * [`binding`]: a small hand-written binding of the FMI C API over `libloading`.
//! * [`import`]: any co-simulation FMU as a participant.
//! * [`ssd`]: SSP 1.0 system structures of FMUs (`SystemStructure.ssd`).
//! * [`units`]: units of the variables.
//! * [`params_doc`]: what every parameter is (its unit and description).

pub mod archive;
pub mod binding;
pub mod description;
pub mod import;
pub mod layout;
pub mod params_doc;
pub mod ssd;
pub mod units;

pub use import::{FmuInit, FmuParticipant, FmuSettings};
pub use layout::{ActuatorIo, ControllerIo, Layout, PlantIo, Samples};
