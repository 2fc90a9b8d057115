//! Vehicle and track parameters. Defaults are the paper's values (Appendix A.2, section 2.3)
//! with the corrections of `model-notes.md`; every number can be overridden from a scenario
//! file. All values SI and radians unless the name says otherwise (`_deg`, `_kmh`).

use cosim::settings::Checker;
use serde::{Deserialize, Serialize};

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
        }
    }
}

impl VehicleParams {
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
        ] {
            c.positive(f, v, hi, unit);
        }
        for (f, v, hi, unit) in [
            ("c_sy", self.c_sy, 1e8, "N·s/m"),
            ("k_vr", self.k_vr, 1e9, "N·m/rad"),
            ("c_vr", self.c_vr, 1e8, "N·m·s/rad"),
            ("c_pz", self.c_pz, 1e8, "N·s/m"),
            ("c_py", self.c_py, 1e8, "N·s/m"),
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
    /// Length of each linear transition (m).
    pub transition_m: f64,
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
            curve_m: 270.0,
            straight_after_m: 135.0,
            irregularity: IrregularityParams::default(),
        }
    }
}

/// Cant irregularity: uniform random values within ±amplitude at knots `knot_spacing_m` apart,
/// joined by a quintic blend so the cant rate and acceleration stay finite (model-notes 6).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct IrregularityParams {
    /// Amplitude bound (deg); 0 switches it off. The paper uses 0.6.
    pub amplitude_deg: f64,
    /// Distance between random knots (m); sets the bandwidth (about v / spacing Hz).
    pub knot_spacing_m: f64,
}

impl Default for IrregularityParams {
    fn default() -> Self {
        IrregularityParams {
            amplitude_deg: 0.0,
            knot_spacing_m: 10.0,
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
        c.range(
            "irregularity.amplitude_deg",
            self.irregularity.amplitude_deg,
            0.0,
            3.0,
            "deg",
        );
        c.range(
            "irregularity.knot_spacing_m",
            self.irregularity.knot_spacing_m,
            1.0,
            1000.0,
            "m",
        );
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
