//! The speed profile along a route: the running speed each section allows, and the fastest
//! run under it from standstill to standstill with bounded acceleration and braking.
//!
//! A section's limit is its line speed for the kind of running, and on a curve also the speed
//! at which the cant deficiency reaches its limit I:
//! `V = √(g·R·(h + I)/1500 mm)` (h the cant; the uncompensated lateral acceleration is
//! g·I/1500 mm), which applies over the whole curve, transitions included. The profile is
//! the least of the limit, the forward envelope (accelerating at `accel` from the start and
//! after every drop of the limit) and the backward one (braking at `brake` into every lower
//! limit and to a stop at the end): `v(s) = min(L(s), √(F_i² + 2a·x), √(B_i² + 2b·(ℓ_i − x)))`
//! in section i of length ℓ_i, x from its start, F_i and B_i its entry and exit envelopes.
//! Times follow in closed form piece by piece.

use serde::Serialize;

use super::file::{Route, Section, CANT_BASE_MM};

/// Standard gravity (m/s²).
const G: f64 = 9.81;

/// Conventional or tilting running.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Running {
    /// A vehicle that does not tilt: the conventional limits.
    Conventional,
    /// A tilting vehicle: the tilting limits.
    Tilting,
}

impl Running {
    /// Kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            Running::Conventional => "conventional",
            Running::Tilting => "tilting",
        }
    }
}

/// The limits a profile is drawn under.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    /// Cant deficiency allowed in conventional running (mm).
    pub cant_deficiency_conventional_mm: f64,
    /// Cant deficiency allowed in tilting running (mm).
    pub cant_deficiency_tilting_mm: f64,
    /// Acceleration (m/s²).
    pub accel_m_s2: f64,
    /// Braking (m/s²).
    pub brake_m_s2: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            cant_deficiency_conventional_mm: 150.0,
            cant_deficiency_tilting_mm: 275.0,
            accel_m_s2: 0.5,
            brake_m_s2: 0.6,
        }
    }
}

impl Limits {
    /// The cant deficiency allowed in `running` (mm).
    pub fn cant_deficiency_mm(&self, running: Running) -> f64 {
        match running {
            Running::Conventional => self.cant_deficiency_conventional_mm,
            Running::Tilting => self.cant_deficiency_tilting_mm,
        }
    }
}

/// What sets a section's limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Bound {
    /// The section's speed limit.
    SpeedLimit,
    /// The cant deficiency limit.
    CantDeficiency,
}

impl Bound {
    /// As tables print it.
    pub fn name(self) -> &'static str {
        match self {
            Bound::SpeedLimit => "speed limit",
            Bound::CantDeficiency => "cant deficiency",
        }
    }
}

/// The speed limit of a section (m/s) and what sets it.
pub fn section_limit(s: &Section, running: Running, limits: &Limits) -> (f64, Bound) {
    let line = match running {
        Running::Conventional => s.vmax_conventional_kmh,
        Running::Tilting => s.vmax_tilting_kmh,
    } / 3.6;
    match s.curve {
        None => (line, Bound::SpeedLimit),
        Some(c) => {
            let cd = limits.cant_deficiency_mm(running);
            let v = (G * c.radius_m.abs() * (c.cant_mm + cd) / CANT_BASE_MM).sqrt();
            if v < line {
                (v, Bound::CantDeficiency)
            } else {
                (line, Bound::SpeedLimit)
            }
        }
    }
}

/// One section of a profile.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SectionSpeed {
    /// Its limit (m/s).
    pub limit_m_s: f64,
    /// What sets the limit.
    pub bound: Bound,
    /// Forward envelope at its start, at most the limit (m/s).
    pub forward_in: f64,
    /// Backward envelope at its end, at most the limit (m/s).
    pub backward_out: f64,
    /// Length (m).
    pub length_m: f64,
    /// Start (m).
    pub chainage_m: f64,
}

impl SectionSpeed {
    /// The speed at `x` metres into the section (m/s).
    pub fn at(&self, x: f64, a: f64, b: f64) -> f64 {
        let x = x.clamp(0.0, self.length_m);
        let up = (self.forward_in.powi(2) + 2.0 * a * x).sqrt();
        let down = (self.backward_out.powi(2) + 2.0 * b * (self.length_m - x)).sqrt();
        self.limit_m_s.min(up).min(down)
    }

    /// The lowest speed in the section (the profile rises, holds, then falls: at an end).
    pub fn min_speed(&self, a: f64, b: f64) -> f64 {
        self.at(0.0, a, b).min(self.at(self.length_m, a, b))
    }

    /// The time to run through it (s), in closed form.
    pub fn time(&self, a: f64, b: f64) -> f64 {
        let (l, f, k, len) = (
            self.limit_m_s,
            self.forward_in,
            self.backward_out,
            self.length_m,
        );
        // Where the accelerating branch reaches the limit and the braking one leaves it.
        let xa = (l * l - f * f) / (2.0 * a);
        let xb = len - (l * l - k * k) / (2.0 * b);
        if xa <= xb {
            return (l - f) / a + (xb - xa) / l + (l - k) / b;
        }
        // The two branches cross below the limit.
        let xc = ((k * k + 2.0 * b * len - f * f) / (2.0 * (a + b))).clamp(0.0, len);
        let up = (f * f + 2.0 * a * xc).sqrt();
        let down = (k * k + 2.0 * b * (len - xc)).sqrt();
        // Accelerating from f over [0, xc], braking to k over [xc, len] (either may be empty).
        (up - f) / a + (down - k) / b
    }
}

/// The speed profile of a route for one kind of running.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Profile {
    /// The running it is drawn for.
    pub running: Running,
    /// Acceleration and braking (m/s²).
    pub accel_m_s2: f64,
    #[allow(missing_docs)]
    pub brake_m_s2: f64,
    /// Each section's speeds.
    pub sections: Vec<SectionSpeed>,
}

impl Profile {
    /// The profile of `route` in `running` under `limits`, from standstill to standstill.
    pub fn new(route: &Route, running: Running, limits: &Limits) -> Self {
        let (a, b) = (limits.accel_m_s2, limits.brake_m_s2);
        let lim: Vec<(f64, Bound)> = route
            .sections
            .iter()
            .map(|s| section_limit(s, running, limits))
            .collect();
        let n = lim.len();
        let mut forward_in = vec![0.0; n];
        let mut v = 0.0f64;
        for (i, s) in route.sections.iter().enumerate() {
            forward_in[i] = v.min(lim[i].0);
            v = lim[i]
                .0
                .min((forward_in[i].powi(2) + 2.0 * a * s.length_m).sqrt());
        }
        let mut backward_out = vec![0.0; n];
        let mut v = 0.0f64;
        for (i, s) in route.sections.iter().enumerate().rev() {
            backward_out[i] = v.min(lim[i].0);
            v = lim[i]
                .0
                .min((backward_out[i].powi(2) + 2.0 * b * s.length_m).sqrt());
        }
        let sections = route
            .sections
            .iter()
            .enumerate()
            .map(|(i, s)| SectionSpeed {
                limit_m_s: lim[i].0,
                bound: lim[i].1,
                forward_in: forward_in[i],
                backward_out: backward_out[i],
                length_m: s.length_m,
                chainage_m: s.chainage_m,
            })
            .collect();
        Profile {
            running,
            accel_m_s2: a,
            brake_m_s2: b,
            sections,
        }
    }

    /// The speed (m/s) at chainage `s` (m).
    pub fn speed_at(&self, s: f64) -> f64 {
        let i = self
            .sections
            .partition_point(|x| x.chainage_m + x.length_m < s)
            .min(self.sections.len() - 1);
        let x = &self.sections[i];
        x.at(s - x.chainage_m, self.accel_m_s2, self.brake_m_s2)
    }

    /// Time through section `i` (s).
    pub fn section_time(&self, i: usize) -> f64 {
        self.sections[i].time(self.accel_m_s2, self.brake_m_s2)
    }

    /// Lowest speed in section `i` (m/s).
    pub fn section_min_speed(&self, i: usize) -> f64 {
        self.sections[i].min_speed(self.accel_m_s2, self.brake_m_s2)
    }

    /// Journey time from standstill to standstill (s).
    pub fn journey_time(&self) -> f64 {
        (0..self.sections.len()).map(|i| self.section_time(i)).sum()
    }

    /// Time (s) between chainages `from` and `to` within section `i`, by the closed forms
    /// applied to the sub-interval (the profile restricted to it is a profile of the same
    /// kind, with the envelopes at its ends).
    pub fn time_between(&self, i: usize, from: f64, to: f64) -> f64 {
        let x = &self.sections[i];
        let (a, b) = (self.accel_m_s2, self.brake_m_s2);
        let (x0, x1) = (from - x.chainage_m, to - x.chainage_m);
        let sub = SectionSpeed {
            forward_in: x
                .limit_m_s
                .min((x.forward_in.powi(2) + 2.0 * a * x0).sqrt()),
            backward_out: x
                .limit_m_s
                .min((x.backward_out.powi(2) + 2.0 * b * (x.length_m - x1)).sqrt()),
            length_m: x1 - x0,
            chainage_m: from,
            ..*x
        };
        sub.time(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn route(body: &str) -> Route {
        let h = "chainage_m,length_m,radius_m,cant_mm,transition_m,shape,vmax_conventional_kmh,vmax_tilting_kmh\n";
        super::super::file::parse(&format!("{h}{body}"), Path::new("t.csv")).unwrap()
    }

    /// ∫ ds/v by the midpoint rule in θ with s = L(1 − cos πθ)/2: ds/dθ vanishes at the
    /// standstills as v does (v ~ √s ~ θ there), so the integrand stays finite and the rule
    /// converges as 1/N²: an independent reckoning of the closed forms.
    fn numeric_time(p: &Profile, length: f64) -> f64 {
        use std::f64::consts::PI;
        let n = 2_000_000;
        let h = 1.0 / n as f64;
        (0..n)
            .map(|k| {
                let th = (k as f64 + 0.5) * h;
                let s = length * (1.0 - (PI * th).cos()) / 2.0;
                let ds = length * PI / 2.0 * (PI * th).sin() * h;
                ds / p.speed_at(s)
            })
            .sum()
    }

    #[test]
    fn a_straight_run_takes_the_closed_form_time() {
        // 10 km at 200 km/h from and to standstill: t = V/a + V/b + (L − V²/2a − V²/2b)/V.
        let r = route(
            "0,10000,,,,,200,200\n10000,1000,1000,100,100,clothoid,200,200\n11000,1,,,,,200,200\n",
        );
        let mut r = r;
        r.sections.truncate(1);
        let lim = Limits::default();
        let p = Profile::new(&r, Running::Tilting, &lim);
        let v: f64 = 200.0 / 3.6;
        let (a, b) = (lim.accel_m_s2, lim.brake_m_s2);
        let want = v / a + v / b + (10000.0 - v * v / (2.0 * a) - v * v / (2.0 * b)) / v;
        assert!(
            (p.journey_time() - want).abs() < 1e-9,
            "{} vs {want}",
            p.journey_time()
        );
        // Too short to reach the limit: a triangle, peak √(2abL/(a+b)).
        r.sections[0].length_m = 500.0;
        let p = Profile::new(&r, Running::Tilting, &lim);
        let peak = (2.0 * a * b * 500.0 / (a + b)).sqrt();
        assert!((p.journey_time() - (peak / a + peak / b)).abs() < 1e-9);
    }

    #[test]
    fn curves_limit_by_cant_deficiency_and_times_match_a_numeric_integral() {
        let r = route(
            "0,3000,,,,,200,230\n3000,800,1000,150,100,clothoid,200,230\n3800,400,,,,,200,230\n\
             4200,900,-2500,100,120,bloss,160,180\n5100,2000,,,,,200,230\n",
        );
        let lim = Limits::default();
        for running in [Running::Conventional, Running::Tilting] {
            let p = Profile::new(&r, running, &lim);
            // R = 1000 m, h = 150 mm: V = √(9.81·1000·(150 + I)/1500).
            let i = lim.cant_deficiency_mm(running);
            let want = (9.81 * 1000.0 * (150.0 + i) / 1500.0).sqrt();
            assert_eq!(p.sections[1].bound, Bound::CantDeficiency);
            assert!((p.sections[1].limit_m_s - want).abs() < 1e-12);
            // R = 2500 m: the line speed binds.
            assert_eq!(p.sections[3].bound, Bound::SpeedLimit);
            // The closed forms against ∫ds/v (2e6 points: the rule's error is about
            // 1e-12 of the time where the profile is smooth; each kink of the profile, where
            // a branch meets the limit, costs O(h²) more).
            let num = numeric_time(&p, r.length_m());
            assert!(
                (p.journey_time() - num).abs() < 1e-3,
                "{running:?}: {} vs {num}",
                p.journey_time()
            );
            // The profile never exceeds a limit and runs the curves at most at theirs.
            for k in 0..7100 {
                let s = k as f64;
                let sec = r
                    .sections
                    .iter()
                    .position(|x| s >= x.chainage_m && s <= x.end_m())
                    .unwrap();
                assert!(p.speed_at(s) <= p.sections[sec].limit_m_s + 1e-9);
            }
            // Time between two points adds up to the section's time.
            let (c, e) = (r.sections[0].chainage_m, r.sections[0].end_m());
            let split = p.time_between(0, c, 1234.0) + p.time_between(0, 1234.0, e);
            assert!((split - p.section_time(0)).abs() < 1e-9);
        }
        let conv = Profile::new(&r, Running::Conventional, &lim).journey_time();
        let tilt = Profile::new(&r, Running::Tilting, &lim).journey_time();
        assert!(tilt < conv);
    }
}
