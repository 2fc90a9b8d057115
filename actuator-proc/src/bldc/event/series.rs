//! The segment equations' Taylor series: the usual state's linear system and a
//! commutation's three conducting phases, from the drive's constants.

use super::roots::{Poly, ORDER};
use super::{Consts, Rotor};

/// 1/n for the Taylor recursion.
const INV_N: [f64; ORDER + 1] = [1.0, 1.0, 0.5, 1.0 / 3.0, 0.25, 0.2];

impl Consts {
    pub(in crate::bldc) fn new(
        p: &crate::bldc::BldcParams,
        link: &crate::DcLinkParams,
        k_vr: f64,
    ) -> Self {
        let g = p.gear();
        Consts {
            inv_2l: 1.0 / (2.0 * p.l_s),
            r_l: p.r_s / p.l_s,
            kt_2l: p.k_t / (2.0 * p.l_s),
            kt_j: p.k_t / p.j_rot,
            bf_j: p.b_f / p.j_rot,
            kappa_j: k_vr / (g * g * p.j_rot),
            inv_c: 1.0 / link.capacitance_f,
            g_r: 1.0 / link.supply_resistance_ohm,
            g_ch: 1.0 / link.chopper_resistance_ohm,
            g_aux: link.aux_conductance(p.v_dc),
            g,
            inv_g: 1.0 / g,
            k_vr_g: k_vr / g,
            lam: 0.5 * p.k_t,
            inv_l: 1.0 / p.l_s,
            lam_j: 0.5 * p.k_t / p.j_rot,
            inv_j: 1.0 / p.j_rot,
            k_t: p.k_t,
            two_r: 2.0 * p.r_s,
            b_f: p.b_f,
        }
    }

    /// Taylor coefficients of (I, ω, Δθ_m, v) from (I, ω, v) at the segment's start, with
    /// the pair at s·v, the rectifier's and chopper's conductances `g_r`, `g_ch`, the rotor
    /// at `theta_m` and the bar twisted by `psi` at the bogie, the supply at `v_s`, and the
    /// gearbox's load on the rotor as `gear` makes it over the segment.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn series(
        &self,
        s: f64,
        g_r: f64,
        g_ch: f64,
        x: [f64; 3],
        theta_m: f64,
        psi: f64,
        v_s: f64,
        gear: Rotor,
    ) -> [Poly; 4] {
        let g_v = (g_r + g_ch + self.g_aux) * self.inv_c;
        let s_c = s * self.inv_c;
        let s_2l = s * self.inv_2l;
        let (kappa_j, bf_j) = (gear.kappa_j, gear.bf_j);
        let a_x = |x: [f64; 4]| {
            [
                s_2l * x[3] - self.r_l * x[0] - self.kt_2l * x[1],
                self.kt_j * x[0] - bf_j * x[1] - kappa_j * x[2],
                x[1],
                -g_v * x[3] - s_c * x[0],
            ]
        };
        // θ_m is carried as Δθ_m from the segment's start (its coefficients stay small).
        let x0 = [x[0], x[1], 0.0, x[2]];
        let mut ck = a_x(x0);
        ck[1] -= kappa_j * (theta_m - self.g * psi);
        ck[3] += g_r * v_s * self.inv_c;
        let mut out = [[0.0; ORDER + 1]; 4];
        for k in 0..4 {
            out[k][0] = x0[k];
            out[k][1] = ck[k];
        }
        for (n, inv) in INV_N.iter().enumerate().skip(2) {
            ck = a_x(ck).map(|x| x * inv);
            for k in 0..4 {
                out[k][n] = ck[k];
            }
        }
        out
    }

    /// Taylor coefficients of (i_+, i_o, ω, Δθ_m, v) during a commutation: the two commutated
    /// phases on their legs (`s_p`, `s_m` = 1 at the link, 0 at 0 V) and the outgoing phase on
    /// its diode (`s_o`), all three conducting into the star point (v_n = Σ(v_x − e_x)/3,
    /// eq 3 per phase). Its back-EMF shape falls or rises linearly across the sector,
    /// f_o = f_o0 + k_o Δθ_m, so e_o = λ ω f_o and T_e = λ(2 i_+ + (1 + f_o) i_o) (eq 5) carry
    /// the products ω·Δθ_m and i_o·Δθ_m, taken into the recursion as Cauchy products.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn transient_series(
        &self,
        legs: [f64; 3],
        (f_o0, k_o): (f64, f64),
        (g_r, g_ch): (f64, f64),
        x: [f64; 4],
        theta_m: f64,
        psi: f64,
        v_s: f64,
        gear: Rotor,
    ) -> [Poly; 5] {
        let [s_p, s_m, s_o] = legs;
        let sum_s = s_p + s_m + s_o;
        let g_v = (g_r + g_ch + self.g_aux) * self.inv_c;
        let (kappa_j, bf_j) = (gear.kappa_j, gear.bf_j);
        // out[k][n]: state k = (i_+, i_o, ω, Δθ_m, v), coefficient n.
        let mut out = [[0.0; ORDER + 1]; 5];
        out[0][0] = x[0];
        out[1][0] = x[1];
        out[2][0] = x[2];
        out[4][0] = x[3];
        for n in 0..ORDER {
            let (mut wth, mut ith) = (0.0, 0.0);
            for j in 0..=n {
                wth += out[2][j] * out[3][n - j];
                ith += out[1][j] * out[3][n - j];
            }
            let [ip, io, w, th, v] = [out[0][n], out[1][n], out[2][n], out[3][n], out[4][n]];
            let e_o = self.lam * (f_o0 * w + k_o * wth);
            let vn = (sum_s * v - e_o) * (1.0 / 3.0);
            let mut d = [
                (s_p * v - vn - self.lam * w) * self.inv_l - self.r_l * ip,
                (s_o * v - vn - e_o) * self.inv_l - self.r_l * io,
                self.lam_j * (2.0 * ip + (1.0 + f_o0) * io + k_o * ith) - bf_j * w - kappa_j * th,
                w,
                -g_v * v - ((s_p - s_m) * ip + (s_o - s_m) * io) * self.inv_c,
            ];
            if n == 0 {
                d[2] -= kappa_j * (theta_m - self.g * psi);
                d[4] += g_r * v_s * self.inv_c;
            }
            for k in 0..5 {
                out[k][n + 1] = d[k] * INV_N[n + 1];
            }
        }
        out
    }
}
