//! Parameters of the whole car (docs/model.md, "The whole car"). SI units and radians.
//!
//! The body, secondary suspension and bogie frame take the half vehicle's values
//! ([`VehicleParams`], paper Appendix A.2) where it has them; the half vehicle's per-side
//! primary values are split over the bogie's two axleboxes on that side. What the half vehicle
//! does not have (yaw, wheelsets, contact, bogie spacing) comes from the sources docs/model.md
//! names next to each field.

use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;

use crate::params::VehicleParams;

/// Parameters of the full-car lateral model: carbody, two bogies, four wheelsets. Serde with
/// the half vehicle's conventions (unknown fields rejected, missing ones at their defaults),
/// ready for a scenario section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FullCarParams {
    /// Carbody mass m_c (kg): twice the half vehicle's m_v.
    pub m_c: f64,
    /// Carbody roll inertia about its c.o.g. I_cx (kg·m²): twice the half vehicle's i_vr.
    pub i_cx: f64,
    /// Carbody yaw inertia I_cz (kg·m²); the default is a uniform box's, m_c (L² + W²)/12,
    /// from the default dimensions (setting L or W alone leaves it as it is).
    pub i_cz: f64,
    /// Carbody length L behind the default I_cz (m).
    pub body_length: f64,
    /// Carbody width W behind the default I_cz (m).
    pub body_width: f64,
    /// Half the bogie centre distance a (m): bogie 1 at x = +a (leading), bogie 2 at −a.
    pub a: f64,
    /// Bogie frame mass m_b (kg).
    pub m_b: f64,
    /// Bogie frame roll inertia I_bx (kg·m²).
    pub i_bx: f64,
    /// Bogie frame yaw inertia I_bz (kg·m²).
    pub i_bz: f64,
    /// Half the bogie wheelbase b (m): wheelsets at ±b from the bogie centre.
    pub b: f64,
    /// Wheelset mass m_w (kg).
    pub m_w: f64,
    /// Wheelset yaw inertia I_wz (kg·m²).
    pub i_wz: f64,
    /// Nominal rolling radius r_0 (m).
    pub r0: f64,
    /// Half the distance between the contact points l_0 (m).
    pub l0: f64,
    /// Equivalent conicity λ (-).
    pub conicity: f64,
    /// Gravitational lateral stiffness per wheelset k_gy (N/m); 0 for conical treads on
    /// knife-edge rails (docs/model.md, "The whole car").
    pub k_gy: f64,
    /// Flangeway clearance c_f (m): the wheelset's free lateral play on the rails either way
    /// before a flange touches.
    pub flange_clearance: f64,
    /// Flange contact stiffness k_f (N/m): the rail's lateral give under a flanging wheel,
    /// acting beyond the clearance (0: no flange). Simulation only; the linear state space
    /// leaves it out (docs/model.md D60).
    pub k_flange: f64,
    /// Young's modulus of wheel and rail E (Pa).
    pub young: f64,
    /// Poisson's ratio of wheel and rail ν (-).
    pub poisson: f64,
    /// Transverse radius of the rail head R_rail (m) (the wheel tread is conical: flat across).
    pub rail_crown_radius: f64,
    /// Factor on Kalker's creep coefficients (1 = Kalker's values).
    pub creep_factor: f64,
    /// Secondary lateral stiffness per side per bogie k_sy (N/m).
    pub k_sy: f64,
    /// Secondary lateral damping per side per bogie c_sy (N·s/m).
    pub c_sy: f64,
    /// Secondary longitudinal stiffness per side per bogie k_sx (N/m), at ±d1: yaw stiffness.
    pub k_sx: f64,
    /// Yaw damper per side per bogie c_yd (N·s/m), at ±d_yd.
    pub c_yd: f64,
    /// Yaw damper lateral semi-spacing d_yd (m).
    pub d_yd: f64,
    /// Airspring area stiffness k_az (N/m).
    pub k_az: f64,
    /// Airspring series stiffness k_sz (N/m).
    pub k_sz: f64,
    /// Airspring reservoir stiffness k_rz (N/m).
    pub k_rz: f64,
    /// Airspring reservoir damping c_rz (N·s/m).
    pub c_rz: f64,
    /// Anti-roll bar stiffness per bogie k_vr (N·m/rad), twisted by that bogie's drive.
    pub k_vr: f64,
    /// Body-to-bogie roll damping per bogie c_vr (N·m·s/rad).
    pub c_vr: f64,
    /// Airspring semi-spacing d_1 (m).
    pub d1: f64,
    /// Secondary lateral suspension below the body c.o.g. h_1 (m).
    pub h1: f64,
    /// Secondary lateral suspension above the bogie c.o.g. h_2 (m).
    pub h2: f64,
    /// Primary lateral stiffness per axlebox k_py (N/m).
    pub k_py: f64,
    /// Primary lateral damping per axlebox c_py (N·s/m).
    pub c_py: f64,
    /// Primary longitudinal stiffness per axlebox k_px (N/m), at ±d_px: wheelset yaw stiffness.
    pub k_px: f64,
    /// Primary longitudinal semi-spacing d_px (m).
    pub d_px: f64,
    /// Primary vertical stiffness per axlebox k_pz (N/m).
    pub k_pz: f64,
    /// Primary vertical damping per axlebox c_pz (N·s/m).
    pub c_pz: f64,
    /// Primary vertical semi-spacing d_2 (m).
    pub d2: f64,
    /// Primary lateral suspension relative to the bogie c.o.g. h_3 (m), negative below.
    pub h3: f64,
    /// Body c.o.g. above rail h_gv (m).
    pub h_gv: f64,
    /// Bogie c.o.g. above rail h_gb (m).
    pub h_gb: f64,
}

impl Default for FullCarParams {
    fn default() -> Self {
        FullCarParams::from_half(&VehicleParams::default())
    }
}

impl FullCarParams {
    /// The whole car built on a half vehicle: body mass and roll inertia doubled, the
    /// per-side primary values of the half vehicle's one bogie split over two axleboxes,
    /// everything else of the half vehicle kept; the rest at the defaults of docs/model.md.
    pub fn from_half(h: &VehicleParams) -> Self {
        let (body_length, body_width) = (24.5, 2.9);
        let m_c = 2.0 * h.m_v;
        FullCarParams {
            m_c,
            i_cx: 2.0 * h.i_vr,
            i_cz: m_c * (body_length * body_length + body_width * body_width) / 12.0,
            body_length,
            body_width,
            a: 9.5,
            m_b: h.m_b,
            i_bx: h.i_br,
            i_bz: 3067.0,
            b: 1.28,
            m_w: 1813.0,
            i_wz: 1120.0,
            r0: 0.46,
            l0: 0.75,
            conicity: 0.15,
            k_gy: 0.0,
            flange_clearance: 0.005,
            k_flange: 40e6,
            young: 2.1e11,
            poisson: 0.3,
            rail_crown_radius: 0.3,
            creep_factor: 1.0,
            k_sy: h.k_sy,
            c_sy: h.c_sy,
            k_sx: 160_000.0,
            c_yd: 250_000.0,
            d_yd: 1.3,
            k_az: h.k_az,
            k_sz: h.k_sz,
            k_rz: h.k_rz,
            c_rz: h.c_rz,
            k_vr: h.k_vr,
            c_vr: h.c_vr,
            d1: h.d1,
            h1: h.h1,
            h2: h.h2,
            k_py: h.k_py / 2.0,
            c_py: h.c_py / 2.0,
            k_px: 31_391_000.0,
            d_px: 1.0,
            k_pz: h.k_pz / 2.0,
            c_pz: h.c_pz / 2.0,
            d2: h.d2,
            h3: h.h3,
            h_gv: h.h_gv,
            h_gb: h.h_gb,
        }
    }

    /// Checks every field; errors are reported under `prefix`. Masses, inertias, lengths,
    /// stiffnesses of the running gear and the contact's constants must be positive (the body
    /// held by its springs, the wheelsets by their creep); dampers, k_gy and the flange may be
    /// zero; heights may be negative.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        for (f, v, hi, unit) in [
            ("m_c", self.m_c, 1e6, "kg"),
            ("i_cx", self.i_cx, 1e7, "kg·m²"),
            ("i_cz", self.i_cz, 1e9, "kg·m²"),
            ("a", self.a, 20.0, "m"),
            ("m_b", self.m_b, 1e5, "kg"),
            ("i_bx", self.i_bx, 1e6, "kg·m²"),
            ("i_bz", self.i_bz, 1e6, "kg·m²"),
            ("b", self.b, 5.0, "m"),
            ("m_w", self.m_w, 1e5, "kg"),
            ("i_wz", self.i_wz, 1e5, "kg·m²"),
            ("r0", self.r0, 2.0, "m"),
            ("l0", self.l0, 2.0, "m"),
            ("conicity", self.conicity, 1.0, "-"),
            ("young", self.young, 1e13, "Pa"),
            ("rail_crown_radius", self.rail_crown_radius, 10.0, "m"),
            ("creep_factor", self.creep_factor, 10.0, "-"),
            ("k_sy", self.k_sy, 1e9, "N/m"),
            ("k_px", self.k_px, 1e10, "N/m"),
            ("d_px", self.d_px, 5.0, "m"),
            ("k_py", self.k_py, 1e10, "N/m"),
            ("k_pz", self.k_pz, 1e10, "N/m"),
            ("c_rz", self.c_rz, 1e8, "N·s/m"),
            ("d1", self.d1, 5.0, "m"),
            ("d2", self.d2, 5.0, "m"),
            ("flange_clearance", self.flange_clearance, 0.1, "m"),
        ] {
            c.positive(f, v, hi, unit);
        }
        c.range("poisson", self.poisson, 0.0, 0.5, "-");
        for (f, v, hi, unit) in [
            ("k_gy", self.k_gy, 1e13, "N/m"),
            ("k_flange", self.k_flange, 1e10, "N/m"),
            ("c_sy", self.c_sy, 1e8, "N·s/m"),
            ("k_sx", self.k_sx, 1e9, "N/m"),
            ("c_yd", self.c_yd, 1e8, "N·s/m"),
            ("d_yd", self.d_yd, 5.0, "m"),
            ("k_az", self.k_az, 1e9, "N/m"),
            ("k_sz", self.k_sz, 1e9, "N/m"),
            ("k_rz", self.k_rz, 1e9, "N/m"),
            ("k_vr", self.k_vr, 1e9, "N·m/rad"),
            ("c_vr", self.c_vr, 1e8, "N·m·s/rad"),
            ("c_py", self.c_py, 1e8, "N·s/m"),
            ("c_pz", self.c_pz, 1e8, "N·s/m"),
            ("body_length", self.body_length, 50.0, "m"),
            ("body_width", self.body_width, 5.0, "m"),
        ] {
            c.range(f, v, 0.0, hi, unit);
        }
        for (f, v) in [
            ("h1", self.h1),
            ("h2", self.h2),
            ("h3", self.h3),
            ("h_gv", self.h_gv),
            ("h_gb", self.h_gb),
        ] {
            c.range(f, v, -3.0, 5.0, "m");
        }
        c.require(
            self.b < self.a,
            "b",
            self.b,
            "less than a (the wheelsets of one bogie)",
        );
        c
    }

    /// Static vertical load on one wheel Q_0 (N): a quarter of the body, half a bogie frame
    /// and one wheelset per wheelset, shared by its two wheels.
    pub fn static_wheel_load(&self) -> f64 {
        0.5 * self.static_axle_load()
    }

    /// Static wheelset load P_0 = 2 Q_0 (N).
    pub fn static_axle_load(&self) -> f64 {
        (self.m_c / 4.0 + self.m_b / 2.0 + self.m_w) * crate::G
    }

    /// Lateral force of the rails' flanges on a wheelset (N, towards +y) at displacement `d`
    /// = y_w − y_o (m) from the rails' centre: zero within the clearance, beyond it
    /// −sign(d)·k_f·(|d| − c_f).
    pub fn flange_force(&self, d: f64) -> f64 {
        let over = d.abs() - self.flange_clearance;
        if over <= 0.0 {
            0.0
        } else {
            -d.signum() * self.k_flange * over
        }
    }

    /// Primary yaw stiffness per wheelset 2 k_px d_px² (N·m/rad).
    pub fn primary_yaw_stiffness(&self) -> f64 {
        2.0 * self.k_px * self.d_px * self.d_px
    }

    /// Secondary yaw stiffness per bogie 2 k_sx d_1² (N·m/rad).
    pub fn secondary_yaw_stiffness(&self) -> f64 {
        2.0 * self.k_sx * self.d1 * self.d1
    }

    /// Secondary yaw damping per bogie 2 c_yd d_yd² (N·m·s/rad).
    pub fn secondary_yaw_damping(&self) -> f64 {
        2.0 * self.c_yd * self.d_yd * self.d_yd
    }

    /// Longitudinal position of bogie `i` (0 leading, 1 trailing) from the body centre (m).
    pub fn bogie_x(&self, i: usize) -> f64 {
        if i == 0 {
            self.a
        } else {
            -self.a
        }
    }

    /// Longitudinal position of wheelset `j` (0..4, leading first) from its bogie centre (m).
    pub fn wheelset_dx(&self, j: usize) -> f64 {
        if j.is_multiple_of(2) {
            self.b
        } else {
            -self.b
        }
    }

    /// Longitudinal position of wheelset `j` from the body centre (m).
    pub fn wheelset_x(&self, j: usize) -> f64 {
        self.bogie_x(j / 2) + self.wheelset_dx(j)
    }
}
