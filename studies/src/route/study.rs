//! A route study: one or more variants (a scenario's vehicle and controller, a kind of
//! running, the limits of the speed profile) run over a route, every segment of every variant
//! in one parallel pool, and each variant's results gathered in route order.

use serde::Serialize;
use tiltsim_assessment::comfort::{percentile, Sickness};
use tiltsim_scenario::scenario::Scenario;

use super::file::Route;
use super::profile::{Limits, Profile, Running};
use super::run::{self, RouteExec, SegmentResult, TransitionComfort};

/// One thing to run over the route.
#[derive(Debug, Clone)]
pub struct Variant {
    /// Its label in the tables (the scenario's name, with the swept values).
    pub label: String,
    /// The vehicle, actuator, controller and irregularity model.
    pub scenario: Scenario,
    /// The speed profile it runs.
    pub running: Running,
    /// The profile's limits.
    pub limits: Limits,
}

/// One transition of the route as a variant ran it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TransitionRow {
    /// The curve (1-based, in route order).
    pub curve: usize,
    /// `entry` or `exit`.
    pub transition: &'static str,
    /// Chainage where the transition starts (m).
    pub chainage_m: f64,
    /// The curve's radius (m, signed) and cant (mm).
    pub radius_m: f64,
    #[allow(missing_docs)]
    pub cant_mm: f64,
    /// Transition shape and length (m).
    pub shape: &'static str,
    #[allow(missing_docs)]
    pub transition_m: f64,
    /// Running speed (km/h).
    pub speed_kmh: f64,
    /// Cant deficiency at that speed (mm).
    pub cant_deficiency_mm: f64,
    /// P_CT and the other readings.
    pub comfort: TransitionComfort,
    /// The limits that bind there.
    pub binding: String,
}

/// One straight segment's ride.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StraightRow {
    /// Start and end chainage (m).
    pub from_m: f64,
    #[allow(missing_docs)]
    pub to_m: f64,
    /// Running speed (km/h).
    pub speed_kmh: f64,
    /// 5 s windows evaluated.
    pub windows: usize,
    /// Lateral part of N_MV.
    pub n_mv_lateral: f64,
}

/// What a variant gave over the route.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VariantResult {
    /// Its label.
    pub label: String,
    /// Controller name (passive, PI, LQG, MPC-KF).
    pub controller: String,
    /// Compensation factor ρ of its controller.
    pub rho: f64,
    /// The running and the profile's limits.
    pub running: Running,
    #[allow(missing_docs)]
    pub limits: Limits,
    /// Journey time of its speed profile, standstill to standstill (s).
    pub journey_time_s: f64,
    /// Time simulated over all segments (s).
    pub simulated_s: f64,
    /// Segments run, and those that did not complete (with why).
    pub segments: usize,
    #[allow(missing_docs)]
    pub failed: Vec<String>,
    /// Every transition.
    pub transitions: Vec<TransitionRow>,
    /// Every straight segment with at least one 5 s window.
    pub straights: Vec<StraightRow>,
    /// The worst and mean P_CT standing over the transitions under each reading: the
    /// standard's 0.3 Hz, 0.25 Hz, 0.4 Hz, 0.3 Hz with the roll speed unfiltered (%).
    pub p_ct_worst: [f64; 4],
    #[allow(missing_docs)]
    pub p_ct_mean: [f64; 4],
    /// Median and 95th percentile of the straights' N_MV (lateral part).
    pub n_mv_median: f64,
    #[allow(missing_docs)]
    pub n_mv_p95: f64,
    /// The trip's motion-sickness doses at each passenger position.
    pub sickness: Vec<(String, Sickness)>,
    /// Validity flags raised on any segment, each once.
    pub flags: Vec<String>,
    /// The whole car's running safety on every segment (`vehicle.model = "full"`; empty for
    /// the half vehicle, which has no wheelsets).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub running_safety: Vec<SafetyRow>,
}

/// The whole car's running safety on one segment of the route.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SafetyRow {
    /// The route section (1-based, in route order) and whether it is a curve (with its leads)
    /// or a piece of straight.
    pub section: usize,
    #[allow(missing_docs)]
    pub curve: bool,
    /// Start and end chainage of the segment (m).
    pub from_m: f64,
    #[allow(missing_docs)]
    pub to_m: f64,
    /// Running speed (km/h).
    pub speed_kmh: f64,
    /// Each quantity's worst value, wheelset, limit and source.
    pub values: Vec<tiltsim_assessment::running_safety::SafetyValue>,
    /// Whether a limit is exceeded, which, and the quantity closest to (or furthest beyond)
    /// its limit with its utilisation.
    pub flag: tiltsim_assessment::running_safety::RunningSafetyFlag,
}

/// The readings of one transition, in the order of [`VariantResult::p_ct_worst`].
pub fn readings(c: &TransitionComfort) -> [f64; 4] {
    [
        c.p_ct.standing,
        c.standing_at_cutoffs[0],
        c.standing_at_cutoffs[1],
        c.standing_unfiltered_roll,
    ]
}

/// The trip's doses at each of `v`'s passenger positions: its segments' doses combined.
fn trip_doses(v: &Variant, segs: &[SegmentResult]) -> Vec<(String, Sickness)> {
    let names: Vec<String> = v
        .scenario
        .comfort
        .positions
        .iter()
        .map(|p| p.name.clone())
        .collect();
    names
        .iter()
        .map(|name| {
            let parts: Vec<&Sickness> = segs
                .iter()
                .flat_map(|r| r.sickness.iter().filter(|(n, _)| n == name).map(|(_, d)| d))
                .collect();
            (name.clone(), Sickness::combine(parts))
        })
        .collect()
}

/// Runs every variant over `route`: all their segments in one pool of `ex.jobs` threads.
/// `None` when interrupted.
pub fn study(route: &Route, variants: &[Variant], ex: &RouteExec) -> Option<Vec<VariantResult>> {
    let mut jobs = Vec::new();
    let mut plans = Vec::new();
    for (k, v) in variants.iter().enumerate() {
        let profile = Profile::new(route, v.running, &v.limits);
        let segs = run::plan(route, &profile);
        for g in &segs {
            let s = run::segment_scenario(&v.scenario, route, g);
            jobs.push((format!("v{k:02}-{:04}", g.index), s, *g));
        }
        plans.push((profile, segs.len()));
    }
    let results = run::run_all(&jobs, ex);
    let mut it = results.into_iter();
    let mut out = Vec::new();
    for (v, (profile, n)) in variants.iter().zip(plans) {
        let segs: Option<Vec<SegmentResult>> = it.by_ref().take(n).collect();
        out.push(gather(route, v, &profile, &segs?));
    }
    Some(out)
}

/// A variant's results from its segments' (in route order).
fn gather(route: &Route, v: &Variant, profile: &Profile, segs: &[SegmentResult]) -> VariantResult {
    let mut transitions = Vec::new();
    let mut straights = Vec::new();
    let mut flags: Vec<String> = Vec::new();
    let mut curve_no = 0;
    for r in segs {
        for f in &r.flags {
            if !flags.contains(f) {
                flags.push(f.clone());
            }
        }
        let g = &r.segment;
        if !g.curve {
            if r.ride.windows > 0 {
                straights.push(StraightRow {
                    from_m: g.from_m,
                    to_m: g.to_m,
                    speed_kmh: g.speed_m_s * 3.6,
                    windows: r.ride.windows,
                    n_mv_lateral: r.ride.n_mv_lateral,
                });
            }
            continue;
        }
        curve_no += 1;
        let sec = &route.sections[g.section];
        let Some(c) = sec.curve else { continue };
        let binding = run::binding(profile, g.section, &r.met);
        let cd =
            g.speed_m_s.powi(2) / (9.81 * c.radius_m.abs()) * super::file::CANT_BASE_MM - c.cant_mm;
        for (k, t) in r.transitions.iter().enumerate() {
            transitions.push(TransitionRow {
                curve: curve_no,
                transition: if k == 0 { "entry" } else { "exit" },
                chainage_m: if k == 0 {
                    sec.chainage_m
                } else {
                    sec.end_m() - c.transition_m
                },
                radius_m: c.radius_m,
                cant_mm: c.cant_mm,
                shape: c.shape.name(),
                transition_m: c.transition_m,
                speed_kmh: g.speed_m_s * 3.6,
                cant_deficiency_mm: cd,
                comfort: *t,
                binding: binding.clone(),
            });
        }
    }
    let mut worst = [0.0f64; 4];
    let mut sum = [0.0f64; 4];
    for t in &transitions {
        for ((w, s), x) in worst
            .iter_mut()
            .zip(sum.iter_mut())
            .zip(readings(&t.comfort))
        {
            *w = w.max(x);
            *s += x;
        }
    }
    let n = transitions.len().max(1) as f64;
    let nmv: Vec<f64> = straights.iter().map(|s| s.n_mv_lateral).collect();
    let sickness = trip_doses(v, segs);
    VariantResult {
        label: v.label.clone(),
        controller: tiltsim_report::table4::controller_name(&v.scenario),
        rho: v.scenario.controller.rho,
        running: v.running,
        limits: v.limits,
        journey_time_s: profile.journey_time(),
        simulated_s: segs.iter().map(|r| r.simulated_s).sum(),
        segments: segs.len(),
        failed: segs
            .iter()
            .filter(|r| r.status != "completed")
            .map(|r| format!("segment {}: {}", r.segment.index, r.status))
            .collect(),
        transitions,
        straights,
        p_ct_worst: worst,
        p_ct_mean: sum.map(|x| x / n),
        n_mv_median: percentile(&nmv, 0.5),
        n_mv_p95: percentile(&nmv, 0.95),
        sickness,
        flags,
        running_safety: safety_rows(segs),
    }
}

/// The whole car's running safety of every segment that has it, in route order.
fn safety_rows(segs: &[SegmentResult]) -> Vec<SafetyRow> {
    segs.iter()
        .filter_map(|r| {
            let s = r.running_safety.as_ref()?;
            Some(SafetyRow {
                section: r.segment.section + 1,
                curve: r.segment.curve,
                from_m: r.segment.from_m,
                to_m: r.segment.to_m,
                speed_kmh: r.segment.speed_m_s * 3.6,
                values: s.values.clone(),
                flag: s.flag.clone(),
            })
        })
        .collect()
}

/// The variants a study runs beyond its scenarios: the compensation factors and tilting cant
/// deficiencies each tilting scenario runs at, and which profile a scenario runs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Grid {
    /// Each tilting scenario at each ρ (empty: its own).
    pub rho: Vec<f64>,
    /// Each tilting variant at each cant deficiency (mm; empty: the limits').
    pub cd_tilting_mm: Vec<f64>,
    /// Every scenario on this profile; `None`: conventional for the passive controller,
    /// tilting for the others.
    pub running: Option<Running>,
}

impl Grid {
    /// Checks the lists: ρ in [0, 1], cant deficiencies in [0, 400] mm.
    pub fn check(&self) -> Result<(), String> {
        if let Some(r) = self.rho.iter().find(|r| !(0.0..=1.0).contains(*r)) {
            return Err(format!("rho {r}: each compensation factor is in [0, 1]"));
        }
        if let Some(c) = self
            .cd_tilting_mm
            .iter()
            .find(|c| !(0.0..=400.0).contains(*c))
        {
            return Err(format!(
                "cd_tilting {c}: each cant deficiency is 0 to 400 mm"
            ));
        }
        Ok(())
    }
}

/// The variants of `scenarios` under `grid`, labelled by the scenario's name and the values
/// swept.
pub fn variants(scenarios: &[Scenario], limits: &Limits, grid: &Grid) -> Vec<Variant> {
    let mut out = Vec::new();
    for s in scenarios {
        let passive = s.controller.mode == controller_proc::Mode::Passive;
        let running = grid.running.unwrap_or(if passive {
            Running::Conventional
        } else {
            Running::Tilting
        });
        let rhos = if passive || grid.rho.is_empty() {
            vec![s.controller.rho]
        } else {
            grid.rho.clone()
        };
        let cds = if running == Running::Tilting && !grid.cd_tilting_mm.is_empty() {
            grid.cd_tilting_mm.clone()
        } else {
            vec![limits.cant_deficiency_tilting_mm]
        };
        for &rho in &rhos {
            for &cd in &cds {
                let mut v = s.clone();
                v.controller.rho = rho;
                let mut label = s.name.clone();
                if rhos.len() > 1 {
                    label.push_str(&format!(" ρ{rho:.2}"));
                }
                if cds.len() > 1 {
                    label.push_str(&format!(" {cd:.0}mm"));
                }
                out.push(Variant {
                    label,
                    scenario: v,
                    running,
                    limits: Limits {
                        cant_deficiency_tilting_mm: cd,
                        ..*limits
                    },
                });
            }
        }
    }
    out
}

/// A column of the per-transition table.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// Numbers.
    Num(Vec<f64>),
    /// Text.
    Text(Vec<String>),
}

/// The per-transition table of every variant, column by column, as `transitions.csv` has it.
pub fn transition_columns(results: &[VariantResult]) -> Vec<(&'static str, Column)> {
    let rows: Vec<(&VariantResult, &TransitionRow)> = results
        .iter()
        .flat_map(|r| r.transitions.iter().map(move |t| (r, t)))
        .collect();
    let text = |f: &dyn Fn(&VariantResult, &TransitionRow) -> String| {
        Column::Text(rows.iter().map(|(r, t)| f(r, t)).collect())
    };
    let num = |f: &dyn Fn(&VariantResult, &TransitionRow) -> f64| {
        Column::Num(rows.iter().map(|(r, t)| f(r, t)).collect())
    };
    vec![
        ("variant", text(&|r, _| r.label.clone())),
        ("controller", text(&|r, _| r.controller.clone())),
        ("rho", num(&|r, _| r.rho)),
        ("running", text(&|r, _| r.running.name().to_string())),
        ("curve", num(&|_, t| t.curve as f64)),
        ("transition", text(&|_, t| t.transition.to_string())),
        ("chainage_m", num(&|_, t| t.chainage_m)),
        ("radius_m", num(&|_, t| t.radius_m)),
        ("cant_mm", num(&|_, t| t.cant_mm)),
        ("shape", text(&|_, t| t.shape.to_string())),
        ("transition_m", num(&|_, t| t.transition_m)),
        ("speed_kmh", num(&|_, t| t.speed_kmh)),
        ("cant_deficiency_mm", num(&|_, t| t.cant_deficiency_mm)),
        ("p_ct_standing_pct", num(&|_, t| t.comfort.p_ct.standing)),
        ("p_ct_seated_pct", num(&|_, t| t.comfort.p_ct.seated)),
        ("lat_acc_m_s2", num(&|_, t| t.comfort.p_ct.lat_acc_m_s2)),
        ("jerk_m_s3", num(&|_, t| t.comfort.p_ct.jerk_m_s3)),
        (
            "roll_speed_deg_s",
            num(&|_, t| t.comfort.p_ct.roll_speed_deg_s),
        ),
        (
            "p_ct_standing_025hz_pct",
            num(&|_, t| t.comfort.standing_at_cutoffs[0]),
        ),
        (
            "p_ct_standing_04hz_pct",
            num(&|_, t| t.comfort.standing_at_cutoffs[1]),
        ),
        (
            "p_ct_standing_unfiltered_roll_pct",
            num(&|_, t| t.comfort.standing_unfiltered_roll),
        ),
        ("binding", text(&|_, t| t.binding.clone())),
    ]
}
