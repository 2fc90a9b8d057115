//! Vehicle and track parameters. Defaults are the paper's values (Appendix A.2, section 2.3)
//! with the corrections of `model-notes.md`; every number can be overridden from a scenario
//! file. All values SI and radians unless the name says otherwise (`_deg`, `_kmh`).

use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;

/// Vehicle parameters (paper Appendix A.2). A one-bogie half-vehicle (model-notes 5).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct VehicleParams {
    /// Half body mass m_v (kg).
    pub m_v: f64,
    /// Half body roll inertia i_vr (kg·m²).
    pub i_vr: f64,
    /// Bogie mass m_b (kg).
    pub m_b: f64,
    /// Bogie roll inertia i_br (kg·m²).
    pub i_br: f64,
    /// Airspring area stiffness k_az (N/m).
    pub k_az: f64,
    /// Airspring series stiffness k_sz (N/m).
    pub k_sz: f64,
    /// Airspring reservoir stiffness k_rz (N/m).
    pub k_rz: f64,
    /// Airspring reservoir damping c_rz (N·s/m).
    pub c_rz: f64,
    /// Secondary lateral stiffness k_sy (N/m).
    pub k_sy: f64,
    /// Secondary lateral damping c_sy (N·s/m); missing from the printed equations (model-notes 3).
    pub c_sy: f64,
    /// Anti-roll bar stiffness per bogie k_vr (N·m/rad).
    pub k_vr: f64,
    /// Body-to-bogie roll damping c_vr (N·m·s/rad); used, never given by the paper (model-notes 3).
    pub c_vr: f64,
    /// Primary vertical stiffness k_pz (N/m).
    pub k_pz: f64,
    /// Primary vertical damping c_pz (N·s/m).
    pub c_pz: f64,
    /// Primary lateral stiffness k_py (N/m).
    pub k_py: f64,
    /// Primary lateral damping c_py (N·s/m).
    pub c_py: f64,
    /// Airspring semi-spacing d_1 (m).
    pub d1: f64,
    /// Primary vertical suspension semi-spacing d_2 (m).
    pub d2: f64,
    /// Secondary lateral suspension height below the body c.o.g. h_1 (m).
    pub h1: f64,
    /// Secondary lateral suspension height above the bogie c.o.g. h_2 (m).
    pub h2: f64,
    /// Primary lateral suspension height relative to the bogie c.o.g. h_3 (m).
    pub h3: f64,
    /// Body c.o.g. height above rail h_gv (m) (model-notes 2: the appendix swaps h_g1/h_g2).
    pub h_gv: f64,
    /// Bogie c.o.g. height above rail h_gb (m).
    pub h_gb: f64,
    /// Secondary lateral bump-stop clearance (m): the free play of Δs either way.
    pub bump_stop_m: f64,
    /// Bump-stop contact stiffness per side (N/m), the linear part of its force.
    pub k_bump: f64,
    /// Bump-stop progression per side (N/m³), the cubic part of its force.
    pub k3_bump: f64,
    /// Which model the plant steps: the paper's half vehicle (the default) or the whole car
    /// built on these values ([`crate::full_car::FullCarParams::from_half`]). Written out only
    /// when it is the whole car, so a half vehicle's settings serialise as before.
    #[serde(skip_serializing_if = "VehicleModel::is_half")]
    pub model: VehicleModel,
}

/// The vehicle model a plant steps (`[vehicle] model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum VehicleModel {
    /// The paper's one-bogie half vehicle, 9 states (eqs 9-13).
    #[default]
    Half,
    /// The whole car: body, two bogies, four wheelsets on linear creep ([`crate::full_car`]).
    Full,
}

impl VehicleModel {
    /// Whether it is the half vehicle.
    pub fn is_half(&self) -> bool {
        *self == VehicleModel::Half
    }
    /// Its name in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            VehicleModel::Half => "half",
            VehicleModel::Full => "full",
        }
    }
}

impl Default for VehicleParams {
    fn default() -> Self {
        VehicleParams {
            m_v: 19_000.0,
            i_vr: 25_000.0,
            m_b: 2_500.0,
            i_br: 1_500.0,
            k_az: 210_000.0,
            k_sz: 620_000.0,
            k_rz: 244_000.0,
            c_rz: 33_000.0,
            k_sy: 260_000.0,
            c_sy: 33_000.0,
            k_vr: 2_000_000.0,
            c_vr: 0.0,
            k_pz: 2_000_000.0,
            c_pz: 20_000.0,
            k_py: 35_000_000.0,
            c_py: 16_000.0,
            d1: 0.90,
            d2: 1.00,
            h1: 0.90,
            h2: 0.25,
            h3: -0.09,
            h_gv: 1.52,
            h_gb: 0.37,
            bump_stop_m: 0.060,
            k_bump: 1.0e6,
            k3_bump: 1.0e10,
            model: VehicleModel::Half,
        }
    }
}

impl VehicleParams {
    /// Force of one side's secondary lateral bump stop (N) at deflection `ds` (m), acting
    /// like the spring: zero inside the clearance c, beyond it
    /// `sign(Δs)·(k_bump·δ + k3_bump·δ³)` with δ = |Δs| − c. A progressive elastic stop with
    /// free play, the usual model of a rubber bump stop (Bruni et al., Vehicle System
    /// Dynamics 49(7), 2011, section 2); the numbers are ours (docs/model.md D49).
    pub fn bump_stop_force(&self, ds: f64) -> f64 {
        let d = ds.abs() - self.bump_stop_m;
        if d <= 0.0 {
            0.0
        } else {
            ds.signum() * (self.k_bump * d + self.k3_bump * d * d * d)
        }
    }

    /// Checks every field; errors are reported under `prefix`.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        for (f, v, hi, unit) in [
            ("m_v", self.m_v, 1e6, "kg"),
            ("i_vr", self.i_vr, 1e7, "kg·m²"),
            ("m_b", self.m_b, 1e5, "kg"),
            ("i_br", self.i_br, 1e6, "kg·m²"),
            ("k_az", self.k_az, 1e9, "N/m"),
            ("k_sz", self.k_sz, 1e9, "N/m"),
            ("k_rz", self.k_rz, 1e9, "N/m"),
            ("c_rz", self.c_rz, 1e8, "N·s/m"),
            ("k_sy", self.k_sy, 1e9, "N/m"),
            ("k_pz", self.k_pz, 1e10, "N/m"),
            ("k_py", self.k_py, 1e10, "N/m"),
            ("d1", self.d1, 5.0, "m"),
            ("d2", self.d2, 5.0, "m"),
            ("h_gv", self.h_gv, 5.0, "m"),
            ("h_gb", self.h_gb, 5.0, "m"),
            ("bump_stop_m", self.bump_stop_m, 1.0, "m"),
        ] {
            c.positive(f, v, hi, unit);
        }
        for (f, v, hi, unit) in [
            ("c_sy", self.c_sy, 1e8, "N·s/m"),
            ("k_vr", self.k_vr, 1e9, "N·m/rad"),
            ("c_vr", self.c_vr, 1e8, "N·m·s/rad"),
            ("c_pz", self.c_pz, 1e8, "N·s/m"),
            ("c_py", self.c_py, 1e8, "N·s/m"),
            ("k_bump", self.k_bump, 1e9, "N/m"),
            ("k3_bump", self.k3_bump, 1e14, "N/m³"),
        ] {
            c.range(f, v, 0.0, hi, unit);
        }
        for (f, v) in [("h1", self.h1), ("h2", self.h2), ("h3", self.h3)] {
            c.range(f, v, -3.0, 3.0, "m");
        }
        c
    }
}

/// Track geometry and speed (paper section 2.3, model-notes 1 and 6).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct TrackParams {
    /// Vehicle speed v (km/h).
    pub speed_kmh: f64,
    /// Steady curve radius R (m); positive for the paper's curve.
    pub radius_m: f64,
    /// Steady curve cant θ_o (deg).
    pub cant_deg: f64,
    /// Straight before the curve (m).
    pub straight_before_m: f64,
    /// Length of each transition (m).
    pub transition_m: f64,
    /// How curvature and cant run along a transition: `clothoid` (linear, the paper's and the
    /// default), `cosine` or `bloss` (smoothed: no jump of the cant rate at the ends).
    #[serde(skip_serializing_if = "TransitionShape::is_clothoid")]
    pub transition_shape: TransitionShape,
    /// Steady curve length (m).
    pub curve_m: f64,
    /// Straight after the curve (m).
    pub straight_after_m: f64,
    /// Stochastic cant irregularity.
    pub irregularity: IrregularityParams,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            speed_kmh: 162.0,
            radius_m: 1000.0,
            cant_deg: 6.0,
            // 3 s straight, 2.4 s transition, 6 s curve, 2.4 s transition, 3 s straight = 16.8 s
            straight_before_m: 135.0,
            transition_m: 108.0,
            transition_shape: TransitionShape::Clothoid,
            curve_m: 270.0,
            straight_after_m: 135.0,
            irregularity: IrregularityParams::default(),
        }
    }
}

/// The shape of a transition curve (`[track] transition_shape`): curvature and cant run from
/// the straight's to the curve's as r(u), u ∈ [0, 1] along the transition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum TransitionShape {
    /// r = u: the clothoid with a linear cant ramp (the paper's); the cant rate jumps at
    /// both ends.
    #[default]
    Clothoid,
    /// r = (1 − cos πu)/2: the cosine (half-sine) transition; r' = 0 at both ends.
    Cosine,
    /// r = 3u² − 2u³: Bloss's transition; r' = 0 at both ends.
    Bloss,
}

impl TransitionShape {
    /// Kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            TransitionShape::Clothoid => "clothoid",
            TransitionShape::Cosine => "cosine",
            TransitionShape::Bloss => "bloss",
        }
    }
    /// Whether it is the clothoid (the default, left out of a written scenario).
    pub fn is_clothoid(&self) -> bool {
        *self == TransitionShape::Clothoid
    }
    /// r(u), dr/du and d²r/du² for u in [0, 1].
    pub fn ramp(self, u: f64) -> (f64, f64, f64) {
        use std::f64::consts::PI;
        match self {
            TransitionShape::Clothoid => (u, 1.0, 0.0),
            TransitionShape::Cosine => (
                0.5 * (1.0 - (PI * u).cos()),
                0.5 * PI * (PI * u).sin(),
                0.5 * PI * PI * (PI * u).cos(),
            ),
            TransitionShape::Bloss => {
                (u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u), 6.0 - 12.0 * u)
            }
        }
    }
    /// The largest |dr/du| along the transition: the peak cant rate is this times the
    /// clothoid's (1 for the clothoid, π/2 for the cosine, 3/2 for Bloss).
    pub fn peak_slope(self) -> f64 {
        match self {
            TransitionShape::Clothoid => 1.0,
            TransitionShape::Cosine => std::f64::consts::FRAC_PI_2,
            TransitionShape::Bloss => 1.5,
        }
    }
}

/// Which irregularity the track carries (`[track.irregularity] model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum IrregularityModel {
    /// The paper's random cant: uniform values within ±`amplitude_deg` at knots
    /// `knot_spacing_m` apart, joined by a quintic blend (model-notes 6). Cant only.
    #[default]
    Knots,
    /// Lateral alignment y_o and cross-level drawn from the ERRI B176 spectra at `level`
    /// (`spectrum.rs`), band-limited to [`min_wavelength_m`, `max_wavelength_m`].
    Spectrum,
}

/// Track irregularity (`[track.irregularity]`): the knot model of the paper (default) or a
/// published track-geometry spectrum.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct IrregularityParams {
    /// `knots` (default) or `spectrum`.
    pub model: IrregularityModel,
    /// Knots: amplitude bound (deg); 0 switches it off. The paper uses 0.6.
    pub amplitude_deg: f64,
    /// Knots: distance between random knots (m); sets the bandwidth (about v / spacing Hz).
    pub knot_spacing_m: f64,
    /// Spectrum: ERRI B176 level, `low` or `high` (required with `model = "spectrum"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub level: Option<crate::spectrum::Level>,
    /// Spectrum: shortest wavelength drawn (m); default 3 (EN 13848-1's D1 band starts there).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_wavelength_m: Option<f64>,
    /// Spectrum: longest wavelength drawn (m); default 150 (the end of EN 13848-1's D3 band).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_wavelength_m: Option<f64>,
    /// Spectrum: draw the lateral alignment y_o (default true).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alignment: Option<bool>,
    /// Spectrum: draw the cross-level, added to the cant (default true).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_level: Option<bool>,
}

impl Default for IrregularityParams {
    fn default() -> Self {
        IrregularityParams {
            model: IrregularityModel::Knots,
            amplitude_deg: 0.0,
            knot_spacing_m: 10.0,
            level: None,
            min_wavelength_m: None,
            max_wavelength_m: None,
            alignment: None,
            cross_level: None,
        }
    }
}

impl IrregularityParams {
    /// Spectrum: the band [shortest, longest] wavelength (m), defaults filled in.
    pub fn band_m(&self) -> (f64, f64) {
        (
            self.min_wavelength_m.unwrap_or(3.0),
            self.max_wavelength_m.unwrap_or(150.0),
        )
    }

    /// Whether any irregularity is drawn.
    pub fn is_on(&self) -> bool {
        match self.model {
            IrregularityModel::Knots => self.amplitude_deg > 0.0,
            IrregularityModel::Spectrum => true,
        }
    }

    fn validate(&self, c: &mut Checker) {
        c.range(
            "irregularity.amplitude_deg",
            self.amplitude_deg,
            0.0,
            3.0,
            "deg",
        );
        c.range(
            "irregularity.knot_spacing_m",
            self.knot_spacing_m,
            1.0,
            1000.0,
            "m",
        );
        match self.model {
            IrregularityModel::Knots => {
                for (f, set) in [
                    ("level", self.level.is_some()),
                    ("min_wavelength_m", self.min_wavelength_m.is_some()),
                    ("max_wavelength_m", self.max_wavelength_m.is_some()),
                    ("alignment", self.alignment.is_some()),
                    ("cross_level", self.cross_level.is_some()),
                ] {
                    c.require(
                        !set,
                        &format!("irregularity.{f}"),
                        "set",
                        "only with model = \"spectrum\" (model is \"knots\")",
                    );
                }
            }
            IrregularityModel::Spectrum => {
                c.require(
                    self.level.is_some(),
                    "irregularity.level",
                    "missing",
                    "\"low\" or \"high\" (ERRI B176) with model = \"spectrum\"",
                );
                c.require(
                    self.amplitude_deg == 0.0,
                    "irregularity.amplitude_deg",
                    self.amplitude_deg,
                    "0 with model = \"spectrum\" (the knot model's amplitude; the level sets the spectrum's)",
                );
                let (lo, hi) = self.band_m();
                c.range("irregularity.min_wavelength_m", lo, 0.5, 100.0, "m");
                c.range("irregularity.max_wavelength_m", hi, 1.0, 1000.0, "m");
                c.require(
                    hi > lo,
                    "irregularity.max_wavelength_m",
                    hi,
                    "longer than min_wavelength_m",
                );
                c.require(
                    self.alignment.unwrap_or(true) || self.cross_level.unwrap_or(true),
                    "irregularity.cross_level",
                    false,
                    "true when alignment is false (one component at least)",
                );
            }
        }
    }
}

impl TrackParams {
    /// Checks every field; errors are reported under `prefix`.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        c.positive("speed_kmh", self.speed_kmh, 400.0, "km/h");
        c.require(
            self.radius_m.is_finite() && self.radius_m.abs() >= 50.0,
            "radius_m",
            self.radius_m,
            "|R| >= 50 m (sign gives the curve's direction)",
        );
        c.range("cant_deg", self.cant_deg, -10.0, 10.0, "deg");
        c.range("straight_before_m", self.straight_before_m, 0.0, 1e5, "m");
        c.positive("transition_m", self.transition_m, 1e4, "m");
        c.range("curve_m", self.curve_m, 0.0, 1e5, "m");
        c.range("straight_after_m", self.straight_after_m, 0.0, 1e5, "m");
        self.irregularity.validate(&mut c);
        c
    }
    /// Speed v (m/s).
    pub fn speed(&self) -> f64 {
        self.speed_kmh / 3.6
    }
    /// Total length (m).
    pub fn length(&self) -> f64 {
        self.straight_before_m + 2.0 * self.transition_m + self.curve_m + self.straight_after_m
    }
}
