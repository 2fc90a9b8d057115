//! `tiltsim bench --fmu`: each participant as its exported FMU against the native one.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use serde::Serialize;

use tiltsim_scenario::scenario::Scenario;

use crate::bench::{measure, BenchError};

/// The cost of one participant as an FMU against the native participant.
#[derive(Debug, Clone, Serialize)]
pub struct FmuCost {
    /// The role replaced by its exported FMU.
    pub role: &'static str,
    /// Median wall time per tick with the native participant (µs).
    pub native_us_per_tick: f64,
    /// Median wall time per tick with the FMU (µs).
    pub fmu_us_per_tick: f64,
    /// `fmu_us_per_tick / native_us_per_tick`.
    pub ratio: f64,
    /// The participant's own compute per step, p50 (µs): native, FMU (load, FMI calls and
    /// model).
    pub native_compute_p50_us: f64,
    /// See `native_compute_p50_us`.
    pub fmu_compute_p50_us: f64,
    /// Every run's wall time per tick (µs), native and FMU alternating.
    pub native_runs_us: Vec<f64>,
    /// See `native_runs_us`.
    pub fmu_runs_us: Vec<f64>,
}

/// `tiltsim bench --fmu`: each role of `base` in turn as its own exported FMU (FMI 3.0, in
/// its own process over the scenario's transport) against the native participant, `rounds`
/// runs of each, alternating so that the machine's drift hits both alike.
pub fn fmu(
    base: &Scenario,
    duration: f64,
    rounds: usize,
    exe: &Path,
    scratch: &Path,
    interrupt: &Arc<AtomicBool>,
    mut progress: impl FnMut(&str),
) -> Result<Vec<FmuCost>, BenchError> {
    let mut s = base.clone();
    s.run.duration_s = Some(duration);
    let _ = std::fs::create_dir_all(scratch);
    let median = |v: &[f64]| {
        let mut w = v.to_vec();
        w.sort_by(f64::total_cmp);
        w[w.len() / 2]
    };
    let mut out = Vec::new();
    for role in cosim::Role::ALL {
        let path = scratch.join(format!("{}.fmu", role.name()));
        tiltsim_master::export_fmu::export(
            &s,
            role,
            &path,
            &tiltsim_master::export_fmu::FmuOptions {
                version: tiltsim_fmi::description::FmiVersion::V3,
                stepping: tiltsim_fmi::layout::Stepping::Tick,
                library: None,
            },
        )
        .map_err(|e| BenchError::Run {
            config: format!("export {role}"),
            why: e.to_string(),
        })?;
        let mut with = s.clone();
        let settings = tiltsim_fmi::FmuSettings {
            fmu: path,
            inputs: Default::default(),
            outputs: Default::default(),
            parameters: Default::default(),
            preload: Vec::new(),
        };
        match role {
            cosim::Role::Plant => with.participants.plant = Some(settings),
            cosim::Role::Actuator => with.participants.actuator = Some(settings),
            cosim::Role::Controller => with.participants.controller = Some(settings),
        }
        let (mut nat, mut fmu, mut nat_c, mut fmu_c) = (vec![], vec![], vec![], vec![]);
        for r in 0..rounds {
            for (label, sc, walls, comp) in [
                ("native", &s, &mut nat, &mut nat_c),
                ("fmu", &with, &mut fmu, &mut fmu_c),
            ] {
                let name = format!("{role} {label} run {}", r + 1);
                progress(&name);
                let dir = scratch.join(format!("{role}-{label}-{r}"));
                let sum = measure(sc, exe, &dir, &name, false, interrupt)?;
                walls.push(sum.wall_time_s / sum.steps_completed.max(1) as f64 * 1e6);
                comp.push(sum.participants[role as usize].compute_us.p50);
            }
        }
        let (n, f) = (median(&nat), median(&fmu));
        out.push(FmuCost {
            role: role.name(),
            native_us_per_tick: n,
            fmu_us_per_tick: f,
            ratio: f / n,
            native_compute_p50_us: median(&nat_c),
            fmu_compute_p50_us: median(&fmu_c),
            native_runs_us: nat,
            fmu_runs_us: fmu,
        });
    }
    Ok(out)
}

/// The `--fmu` table.
pub fn fmu_table(scenario: &str, transport: &str, rows: &[FmuCost]) -> String {
    let mut t = format!(
        "each participant of {scenario} as its exported FMU vs native ({transport}; medians of alternating runs)\n\n\
         | role | native (us/tick) | FMU (us/tick) | FMU / native | compute p50 native (us) | compute p50 FMU (us) |\n\
         |---|---|---|---|---|---|\n"
    );
    for r in rows {
        t.push_str(&format!(
            "| {} | {:.2} | {:.2} | {:.3} | {:.2} | {:.2} |\n",
            r.role,
            r.native_us_per_tick,
            r.fmu_us_per_tick,
            r.ratio,
            r.native_compute_p50_us,
            r.fmu_compute_p50_us
        ));
    }
    t
}
