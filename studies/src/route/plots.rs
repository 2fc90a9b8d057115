//! The route study's figures: the speed profiles along the line, P_CT at every transition
//! along the line, and the compensation trade-off (P_CT against the roll dose over ρ).

use std::path::{Path, PathBuf};

use tiltsim_report::plot::{write_chart, Chart, Line, PALETTE};
use tiltsim_report::plot::{write_scatter, Series};

use super::file::Route;
use super::outputs::chainages;
use super::profile::{Limits, Profile, Running};
use super::study::VariantResult;

/// Writes `dir/route_speed`, `dir/route_p_ct` and, when variants differ in ρ,
/// `dir/route_trade_off` (each `.svg` and `.png`).
pub fn write(
    dir: &Path,
    route: &Route,
    limits: &Limits,
    results: &[VariantResult],
) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let x: Vec<f64> = chainages(route).iter().map(|s| s / 1000.0).collect();
    let speed = |r: Running| {
        let p = Profile::new(route, r, limits);
        chainages(route)
            .iter()
            .map(|&s| p.speed_at(s) * 3.6)
            .collect::<Vec<f64>>()
    };
    let title = format!("{}: speed profiles", route.name);
    let chart = Chart {
        title: &title,
        x_label: "chainage (km)",
        y_label: "speed (km/h)",
        lines: vec![
            Line {
                label: "conventional",
                y: speed(Running::Conventional),
                colour: PALETTE[0],
                ..Default::default()
            },
            Line {
                label: "tilting",
                y: speed(Running::Tilting),
                colour: PALETTE[1],
                ..Default::default()
            },
        ],
        ..Default::default()
    };
    let mut files = write_chart(dir, "route_speed", &chart, &x)?.to_vec();
    let series: Vec<Series> = results
        .iter()
        .enumerate()
        .map(|(k, r)| Series {
            label: &r.label,
            colour: PALETTE[k % PALETTE.len()],
            points: r
                .transitions
                .iter()
                .map(|t| (t.chainage_m / 1000.0, t.comfort.p_ct.standing))
                .collect(),
            labels: Vec::new(),
            joined: true,
        })
        .collect();
    let title = format!(
        "{}: P_CT standing (EN 12299) at every transition",
        route.name
    );
    files.extend(write_scatter(
        dir,
        "route_p_ct",
        &title,
        "chainage (km)",
        "P_CT standing (%)",
        &series,
    )?);
    if let Some(f) = trade_off(dir, route, results)? {
        files.extend(f);
    }
    Ok(files)
}

/// P_CT (worst transition) against the roll-acceleration dose per hour at the window seat,
/// one joined series per controller and running over ρ, each point labelled with its ρ.
fn trade_off(
    dir: &Path,
    route: &Route,
    results: &[VariantResult],
) -> std::io::Result<Option<[PathBuf; 2]>> {
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in results {
        let k = (
            r.controller.clone(),
            format!(
                "{} {:.0} mm",
                r.running.name(),
                r.limits.cant_deficiency_mm(r.running)
            ),
        );
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    if keys.len() == results.len() {
        return Ok(None);
    }
    let labels: Vec<String> = keys.iter().map(|(c, r)| format!("{c}, {r}")).collect();
    let series: Vec<Series> = keys
        .iter()
        .enumerate()
        .map(|(k, key)| {
            let mine: Vec<&VariantResult> = results
                .iter()
                .filter(|r| {
                    r.controller == key.0
                        && format!(
                            "{} {:.0} mm",
                            r.running.name(),
                            r.limits.cant_deficiency_mm(r.running)
                        ) == key.1
                })
                .collect();
            Series {
                label: &labels[k],
                colour: PALETTE[k % PALETTE.len()],
                points: mine.iter().map(|r| (dose(r), r.p_ct_worst[0])).collect(),
                labels: mine.iter().map(|r| format!("ρ {:.2}", r.rho)).collect(),
                joined: true,
            }
        })
        .collect();
    let title = format!(
        "{}: compensation trade-off, P_CT against the roll dose",
        route.name
    );
    write_scatter(
        dir,
        "route_trade_off",
        &title,
        "roll-acceleration dose per hour, window seat (rad/s^1.5)",
        "worst P_CT standing (%)",
        &series,
    )
    .map(Some)
}

/// The roll-acceleration dose per hour at the window seat (or the first position).
fn dose(r: &VariantResult) -> f64 {
    r.sickness
        .iter()
        .find(|(n, _)| n == "seat-window")
        .or(r.sickness.first())
        .map_or(0.0, |(_, d)| d.msdv_roll_per_hour)
}
