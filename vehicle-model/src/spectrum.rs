//! Track-geometry irregularity drawn from a published power spectral density.
//!
//! The ORE/ERRI B176 spectra for lateral alignment and cross-level, at their low and high
//! levels (one-sided in the spatial angular frequency Ω (rad/m): the variance of the
//! irregularity is ∫₀^∞ S(Ω) dΩ):
//!
//! * alignment y_o (m): `S_a(Ω) = A_a Ω_c² / ((Ω² + Ω_r²)(Ω² + Ω_c²))` (m²/(rad/m));
//! * cross-level angle (rad): `S_c(Ω) = (A_v / b²) Ω_c² Ω² / ((Ω² + Ω_r²)(Ω² + Ω_c²)(Ω² + Ω_s²))`
//!   (rad²/(rad/m)), b = 0.75 m half the distance between the rails' contact points;
//!
//! with Ω_c = 0.8246, Ω_r = 0.0206, Ω_s = 0.438 rad/m; A_a = 2.119e-7 (low) / 6.125e-7 (high)
//! m·rad, A_v = 4.032e-7 (low) / 1.08e-6 (high) m·rad (docs/model.md D40 gives the sources).
//!
//! A realisation on a periodic grid of N = 2^k points, spacing Δs, length L = N·Δs:
//! `x(s) = Σ_k (a_k cos Ω_k s + b_k sin Ω_k s)`, Ω_k = 2πk/L inside the band
//! [2π/λ_max, 2π/λ_min], a_k and b_k independent Gaussian with variance S(Ω_k)·ΔΩ, ΔΩ = 2π/L,
//! so that E[x²] = Σ S(Ω_k) ΔΩ, the band's share of the spectrum's integral. The value and its
//! first three derivatives are computed exactly on the grid (inverse FFT of (iΩ)^m times the
//! coefficients) and joined by cubic Hermite interpolation, so the value, the rate and the
//! rate's rate seen by the plant are smooth and consistent.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Ω_c (rad/m).
pub const OMEGA_C: f64 = 0.8246;
/// Ω_r (rad/m).
pub const OMEGA_R: f64 = 0.0206;
/// Ω_s (rad/m).
pub const OMEGA_S: f64 = 0.438;
/// Half the distance between the rails' contact points b (m) of the cross-level spectrum.
pub const HALF_GAUGE_M: f64 = 0.75;

/// Level of the ERRI B176 spectra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Level {
    /// Low level (good track).
    Low,
    /// High level (poor track).
    High,
}

impl Level {
    /// Kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            Level::Low => "low",
            Level::High => "high",
        }
    }
    /// A_a of the alignment spectrum (m·rad).
    pub fn a_alignment(self) -> f64 {
        match self {
            Level::Low => 2.119e-7,
            Level::High => 6.125e-7,
        }
    }
    /// A_v of the vertical and cross-level spectra (m·rad).
    pub fn a_vertical(self) -> f64 {
        match self {
            Level::Low => 4.032e-7,
            Level::High => 1.08e-6,
        }
    }
}

/// Alignment PSD S_a(Ω) (m²/(rad/m)), Ω in rad/m.
pub fn alignment_psd(level: Level, omega: f64) -> f64 {
    let w2 = omega * omega;
    level.a_alignment() * OMEGA_C * OMEGA_C / ((w2 + OMEGA_R * OMEGA_R) * (w2 + OMEGA_C * OMEGA_C))
}

/// Cross-level angle PSD S_c(Ω) (rad²/(rad/m)), Ω in rad/m.
pub fn cross_level_psd(level: Level, omega: f64) -> f64 {
    let w2 = omega * omega;
    level.a_vertical() / (HALF_GAUGE_M * HALF_GAUGE_M) * OMEGA_C * OMEGA_C * w2
        / ((w2 + OMEGA_R * OMEGA_R) * (w2 + OMEGA_C * OMEGA_C) * (w2 + OMEGA_S * OMEGA_S))
}

/// A periodic band-limited realisation with its first three derivatives on a grid.
#[derive(Debug, Clone)]
pub struct Profile {
    ds: f64,
    /// x, x', x'', x''' at each grid point.
    grid: Vec<[f64; 4]>,
}

/// One complex number (re, im) of the FFT.
type C = (f64, f64);

/// In-place iterative radix-2 FFT of `a` (length a power of two) with the kernel
/// e^{+2πi·kn/N} (the inverse transform without the 1/N).
fn fft_inverse(a: &mut [C]) {
    let n = a.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            a.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = std::f64::consts::TAU / len as f64;
        let (wr, wi) = (ang.cos(), ang.sin());
        for start in (0..n).step_by(len) {
            let (mut cr, mut ci) = (1.0, 0.0);
            for k in 0..len / 2 {
                let (ur, ui) = a[start + k];
                let (xr, xi) = a[start + k + len / 2];
                let (vr, vi) = (xr * cr - xi * ci, xr * ci + xi * cr);
                a[start + k] = (ur + vr, ui + vi);
                a[start + k + len / 2] = (ur - vr, ui - vi);
                let nr = cr * wr - ci * wi;
                ci = cr * wi + ci * wr;
                cr = nr;
            }
        }
        len <<= 1;
    }
}

/// A standard normal draw (Box-Muller on two uniform draws).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl Profile {
    /// A realisation of the one-sided PSD `psd` (per rad/m) over at least `length_m`, with
    /// wavelengths in [`min_wavelength_m`, `max_wavelength_m`], from `rng`.
    pub fn generate(
        psd: impl Fn(f64) -> f64,
        length_m: f64,
        min_wavelength_m: f64,
        max_wavelength_m: f64,
        rng: &mut ChaCha8Rng,
    ) -> Self {
        // Twelve points per shortest wavelength: cubic Hermite error (kΔs)⁴/384 ≈ 2e-4.
        let ds = min_wavelength_m / 12.0;
        // The period covers the track and the longest wavelength four times over.
        let need = (length_m.max(4.0 * max_wavelength_m) / ds).ceil() as usize;
        let n = need.max(16).next_power_of_two();
        let l = n as f64 * ds;
        let d_omega = std::f64::consts::TAU / l;
        let (lo, hi) = (
            std::f64::consts::TAU / max_wavelength_m,
            std::f64::consts::TAU / min_wavelength_m,
        );
        let mut coef: Vec<C> = vec![(0.0, 0.0); n];
        for (k, c) in coef.iter_mut().enumerate().take(n / 2).skip(1) {
            let w = k as f64 * d_omega;
            // Draw for every bin so that the band does not change the stream's later draws.
            let (a, b) = (normal(rng), normal(rng));
            if w >= lo && w <= hi {
                let sd = (psd(w) * d_omega).sqrt();
                // x = Re Σ c_k e^{iΩs} with c_k = a_k − i b_k.
                *c = (a * sd, -b * sd);
            }
        }
        let mut grid = vec![[0.0; 4]; n];
        for m in 0..4 {
            let mut buf: Vec<C> = coef
                .iter()
                .enumerate()
                .map(|(k, &(re, im))| {
                    // times (iΩ)^m
                    let w = k as f64 * d_omega;
                    let p = w.powi(m as i32);
                    let (re, im) = (re * p, im * p);
                    match m % 4 {
                        0 => (re, im),
                        1 => (-im, re),
                        2 => (-re, -im),
                        _ => (im, -re),
                    }
                })
                .collect();
            fft_inverse(&mut buf);
            for (g, v) in grid.iter_mut().zip(&buf) {
                g[m] = v.0;
            }
        }
        Profile { ds, grid }
    }

    /// The value and its first two derivatives at `s` (m) (periodic beyond the grid).
    pub fn at(&self, s: f64) -> (f64, f64, f64) {
        let n = self.grid.len();
        let x = (s / self.ds).rem_euclid(n as f64);
        let i = (x.floor() as usize).min(n - 1);
        let u = x - i as f64;
        let (p, q) = (&self.grid[i], &self.grid[(i + 1) % n]);
        let h = self.ds;
        // Cubic Hermite basis and its derivative.
        let (u2, u3) = (u * u, u * u * u);
        let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
        let h10 = u3 - 2.0 * u2 + u;
        let h01 = -2.0 * u3 + 3.0 * u2;
        let h11 = u3 - u2;
        let herm = |j: usize| h00 * p[j] + h10 * h * p[j + 1] + h01 * q[j] + h11 * h * q[j + 1];
        (herm(0), herm(1), herm(2))
    }

    /// Grid spacing (m).
    pub fn spacing(&self) -> f64 {
        self.ds
    }

    /// Grid values x at every point (the exact realisation on the grid).
    pub fn values(&self) -> impl Iterator<Item = f64> + '_ {
        self.grid.iter().map(|g| g[0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn fft_of_one_bin_is_a_complex_exponential() {
        let n = 64;
        let mut a = vec![(0.0, 0.0); n];
        a[3] = (1.0, 0.0);
        fft_inverse(&mut a);
        for (j, v) in a.iter().enumerate() {
            let ph = std::f64::consts::TAU * 3.0 * j as f64 / n as f64;
            assert!((v.0 - ph.cos()).abs() < 1e-12 && (v.1 - ph.sin()).abs() < 1e-12);
        }
    }

    #[test]
    fn derivatives_on_the_grid_match_finite_differences_of_the_interpolant() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let p = Profile::generate(
            |w| alignment_psd(Level::High, w),
            2000.0,
            3.0,
            150.0,
            &mut rng,
        );
        for &s in &[10.3, 377.7, 1234.56] {
            let h = 1e-4;
            let (_, d, dd) = p.at(s);
            let fd = (p.at(s + h).0 - p.at(s - h).0) / (2.0 * h);
            let fdd = (p.at(s + h).1 - p.at(s - h).1) / (2.0 * h);
            // Hermite: the first derivative of the value interpolant differs from the
            // interpolated derivative by O(Δs³·x⁗): 1e-3 of the slope's scale at most.
            assert!((d - fd).abs() < 1e-3 * d.abs().max(1e-5), "{d} {fd}");
            assert!((dd - fdd).abs() < 1e-2 * dd.abs().max(1e-5), "{dd} {fdd}");
        }
    }
}
