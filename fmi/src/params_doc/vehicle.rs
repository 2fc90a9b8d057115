//! The vehicle, the track and the sensor (`vehicle_model::VehicleParams`, `TrackParams`,
//! `plant_proc::SensorParams`), the run values the plant receives beside them, and the
//! passenger positions of `[comfort]`.

use super::Row;

/// `(name, unit, description)`, as [`super`] describes them.
pub(super) const VEHICLE: &[Row] = &[
    // `[vehicle]`, Appendix A.2: the plant's vehicle, and the controller's design vehicle.
    ("vehicle.m_v", "kg", "Half carbody mass m_v"),
    ("vehicle.i_vr", "kg.m2", "Half carbody roll inertia i_vr"),
    ("vehicle.m_b", "kg", "Bogie mass m_b"),
    ("vehicle.i_br", "kg.m2", "Bogie roll inertia i_br"),
    ("vehicle.k_az", "N/m", "Airspring area stiffness k_az"),
    ("vehicle.k_sz", "N/m", "Airspring series stiffness k_sz"),
    ("vehicle.k_rz", "N/m", "Airspring reservoir stiffness k_rz"),
    ("vehicle.c_rz", "N.s/m", "Airspring reservoir damping c_rz"),
    ("vehicle.k_sy", "N/m", "Secondary lateral stiffness k_sy"),
    (
        "vehicle.c_sy",
        "N.s/m",
        "Secondary lateral damping c_sy (missing from the paper's printed equations)",
    ),
    (
        "vehicle.k_vr",
        "N.m/rad",
        "Anti-roll bar stiffness per bogie k_vr",
    ),
    (
        "vehicle.c_vr",
        "N.m.s/rad",
        "Body-to-bogie roll damping c_vr (not given by the paper)",
    ),
    ("vehicle.k_pz", "N/m", "Primary vertical stiffness k_pz"),
    ("vehicle.c_pz", "N.s/m", "Primary vertical damping c_pz"),
    ("vehicle.k_py", "N/m", "Primary lateral stiffness k_py"),
    ("vehicle.c_py", "N.s/m", "Primary lateral damping c_py"),
    ("vehicle.d1", "m", "Airspring semi-spacing d_1"),
    (
        "vehicle.d2",
        "m",
        "Primary vertical suspension semi-spacing d_2",
    ),
    (
        "vehicle.h1",
        "m",
        "Height of the secondary lateral suspension below the carbody c.o.g. h_1",
    ),
    (
        "vehicle.h2",
        "m",
        "Height of the secondary lateral suspension above the bogie c.o.g. h_2",
    ),
    (
        "vehicle.h3",
        "m",
        "Height of the primary lateral suspension relative to the bogie c.o.g. h_3",
    ),
    (
        "vehicle.h_gv",
        "m",
        "Height of the carbody c.o.g. above the rail h_gv",
    ),
    (
        "vehicle.h_gb",
        "m",
        "Height of the bogie c.o.g. above the rail h_gb",
    ),
    (
        "vehicle.bump_stop_m",
        "m",
        "Secondary lateral bump-stop clearance: the free play of Δs either way",
    ),
    (
        "vehicle.k_bump",
        "N/m",
        "Bump-stop contact stiffness per side, the linear part of its force",
    ),
    (
        "vehicle.k3_bump",
        "N/m3",
        "Bump-stop progression per side, the cubic part of its force",
    ),
    // `[track]`, section 2.3: the plant's track, and the controller's track database.
    ("track.speed_kmh", "km/h", "Vehicle speed v"),
    (
        "track.radius_m",
        "m",
        "Steady curve radius R; its sign gives the curve's direction",
    ),
    ("track.cant_deg", "deg", "Steady curve cant θ_o"),
    (
        "track.straight_before_m",
        "m",
        "Length of the straight before the curve",
    ),
    ("track.transition_m", "m", "Length of each transition"),
    (
        "track.transition_shape",
        "",
        "Transition shape: clothoid (linear ramp, the paper's), cosine or bloss (smoothed ends)",
    ),
    ("track.curve_m", "m", "Length of the steady curve"),
    (
        "track.straight_after_m",
        "m",
        "Length of the straight after the curve",
    ),
    (
        "track.irregularity.model",
        "",
        "Track irregularity model: knots (the paper's random cant) or spectrum (ERRI B176)",
    ),
    (
        "track.irregularity.amplitude_deg",
        "deg",
        "Knot model: amplitude bound of the random cant irregularity; 0 switches it off",
    ),
    (
        "track.irregularity.knot_spacing_m",
        "m",
        "Knot model: distance between random knots; sets the bandwidth (about v / spacing Hz)",
    ),
    (
        "track.irregularity.level",
        "",
        "Spectrum model: ERRI B176 level, low or high",
    ),
    (
        "track.irregularity.min_wavelength_m",
        "m",
        "Spectrum model: shortest wavelength drawn",
    ),
    (
        "track.irregularity.max_wavelength_m",
        "m",
        "Spectrum model: longest wavelength drawn",
    ),
    (
        "track.irregularity.alignment",
        "",
        "Spectrum model: draw the lateral alignment y_o",
    ),
    (
        "track.irregularity.cross_level",
        "",
        "Spectrum model: draw the cross-level, added to the cant",
    ),
    // `[sensor]`, eq 15.
    (
        "sensor.theta_v_noise_std_rad",
        "rad",
        "Standard deviation of the Gaussian noise υ on the measured carbody roll θ_v (eq 15)",
    ),
    (
        "sensor.noise_hold_s",
        "s",
        "How long each sensor noise sample is held; 0 draws a new one every plant step",
    ),
    // Run values the plant receives beside its sections (`PlantSettings`); the actuator
    // receives `dt_s` too, the controller `seed`.
    (
        "dt_s",
        "s",
        "Base tick of the run: the plant's step and the actuator's exchange period with it",
    ),
    (
        "seed",
        "",
        "Seed of the run (run.seed): irregularity and sensor noise, localisation noise",
    ),
    // `[[comfort.positions]]` (`tiltsim_assessment::comfort::Position`, an array of tables):
    // points of the carbody where passengers are.
    (
        "comfort.positions.name",
        "",
        "Name of a passenger position in the carbody",
    ),
    (
        "comfort.positions.height_m",
        "m",
        "Height of a passenger position above the rail",
    ),
    (
        "comfort.positions.offset_m",
        "m",
        "Lateral offset of a passenger position, positive towards the outside of the curve",
    ),
];
