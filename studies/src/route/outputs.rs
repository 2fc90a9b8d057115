//! What a route study writes: `transitions.csv` (every transition of every variant),
//! `straights.csv` (N_MV per straight segment), `variants.csv` (one line per variant: journey
//! time, P_CT under each reading, N_MV, the doses), `profile.csv` (the conventional and tilting
//! speed profiles), `route.json` (all of it), `route.md` (the tables) and `plots/`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::file::Route;
use super::profile::{Limits, Profile, Running};
use super::study::{Column, VariantResult};

/// The names of the readings of EN 12299 in [`VariantResult::p_ct_worst`]'s order.
pub const READING_NAMES: [&str; 4] = [
    "0.3 Hz (EN 12299)",
    "0.25 Hz",
    "0.4 Hz",
    "0.3 Hz, roll speed unfiltered",
];

/// The journey times of the route's two profiles under `limits`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Journey {
    /// Conventional running (s).
    pub conventional_s: f64,
    /// Tilting running (s).
    pub tilting_s: f64,
    /// Time saved by tilting (s).
    pub saved_s: f64,
    /// As a share of the conventional time (%).
    pub saved_pct: f64,
}

impl Journey {
    /// The journey times of `route` under `limits`.
    pub fn of(route: &Route, limits: &Limits) -> Self {
        let c = Profile::new(route, Running::Conventional, limits).journey_time();
        let t = Profile::new(route, Running::Tilting, limits).journey_time();
        Journey {
            conventional_s: c,
            tilting_s: t,
            saved_s: c - t,
            saved_pct: 100.0 * (c - t) / c,
        }
    }
}

/// What the study cost.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cost {
    /// Wall time of the runs (s).
    pub wall_s: f64,
    /// CPU time of the process over the runs, user and system (s).
    pub cpu_s: f64,
    /// Parallel runs.
    pub jobs: usize,
}

#[derive(Serialize)]
struct RouteJson<'a> {
    route: &'a str,
    file: String,
    length_m: f64,
    sections: usize,
    curves: usize,
    limits: &'a Limits,
    journey: Journey,
    cost: Cost,
    variants: &'a [VariantResult],
}

/// Writes every file of the study into `out`; returns the files written.
pub fn write(
    out: &Path,
    route: &Route,
    limits: &Limits,
    results: &[VariantResult],
    cost: Cost,
) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out)?;
    let journey = Journey::of(route, limits);
    let mut files = vec![
        put(out, "transitions.csv", &transitions_csv(results))?,
        put(out, "straights.csv", &straights_csv(results))?,
        put(out, "variants.csv", &variants_csv(results))?,
        put(out, "profile.csv", &profile_csv(route, limits))?,
    ];
    if results.iter().any(|r| !r.running_safety.is_empty()) {
        files.push(put(out, "safety.csv", &safety_csv(results))?);
    }
    let json = RouteJson {
        route: &route.name,
        file: route.file.display().to_string(),
        length_m: route.length_m(),
        sections: route.sections.len(),
        curves: route.curves(),
        limits,
        journey,
        cost,
        variants: results,
    };
    let text = serde_json::to_string_pretty(&json).map_err(std::io::Error::other)?;
    files.push(put(out, "route.json", &(text + "\n"))?);
    files.push(put(
        out,
        "route.md",
        &markdown(route, limits, &journey, results),
    )?);
    files.extend(super::plots::write(
        &out.join("plots"),
        route,
        limits,
        results,
    )?);
    Ok(files)
}

fn put(dir: &Path, name: &str, text: &str) -> std::io::Result<PathBuf> {
    let p = dir.join(name);
    std::fs::write(&p, text)?;
    Ok(p)
}

/// A number as the CSV files give it: shortest round-trip form.
fn num(x: f64) -> String {
    if x.is_finite() {
        let mut b = ryu::Buffer::new();
        b.format(x).trim_end_matches(".0").to_string()
    } else {
        String::new()
    }
}

fn transitions_csv(results: &[VariantResult]) -> String {
    let cols = super::study::transition_columns(results);
    let names: Vec<&str> = cols.iter().map(|(n, _)| *n).collect();
    let mut s = names.join(",") + "\n";
    let n = results.iter().map(|r| r.transitions.len()).sum::<usize>();
    for i in 0..n {
        let cells: Vec<String> = cols
            .iter()
            .map(|(_, c)| match c {
                Column::Num(v) => num(v[i]),
                Column::Text(v) => quote(&v[i]),
            })
            .collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

/// A CSV cell: quoted when it holds a comma, a quote or a semicolon.
fn quote(text: &str) -> String {
    if text.contains([',', '"', ';']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn straights_csv(results: &[VariantResult]) -> String {
    let mut s = String::from("variant,from_m,to_m,speed_kmh,windows,n_mv_lateral\n");
    for r in results {
        for x in &r.straights {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{}",
                r.label,
                num(x.from_m),
                num(x.to_m),
                num(x.speed_kmh),
                x.windows,
                num(x.n_mv_lateral)
            );
        }
    }
    s
}

/// The quantities of the running safety, in the order each segment's values give them.
const SAFETY: [(&str, &str); 5] = [
    ("(Y/Q)_2m", "y_q_2m"),
    ("(SumY)_2m", "sum_y_2m_n"),
    ("dQ/Q0", "dq_q0"),
    ("Y_qst", "y_qst_n"),
    ("Q_qst", "q_qst_n"),
];

/// `safety.csv`: the whole car's running safety on every segment of every variant, each
/// quantity's worst value and utilisation (empty where not assessed: the quasi-static ones on
/// a straight), the binding quantity and the flag.
fn safety_csv(results: &[VariantResult]) -> String {
    let mut s = String::from("variant,section,kind,from_m,to_m,speed_kmh");
    for (_, col) in SAFETY {
        let _ = write!(s, ",{col},{col}_utilisation");
    }
    s.push_str(",binding,binding_utilisation,flag,exceeded\n");
    for r in results {
        for x in &r.running_safety {
            let _ = write!(
                s,
                "{},{},{},{},{},{}",
                r.label,
                x.section,
                if x.curve { "curve" } else { "straight" },
                num(x.from_m),
                num(x.to_m),
                num(x.speed_kmh)
            );
            for (name, _) in SAFETY {
                match x.values.iter().find(|v| v.quantity == name) {
                    Some(v) => {
                        let _ = write!(s, ",{},{}", num(v.value), num(v.utilisation));
                    }
                    None => s.push_str(",,"),
                }
            }
            let _ = writeln!(
                s,
                ",{},{},{},{}",
                quote(x.flag.binding),
                num(x.flag.binding_utilisation),
                if x.flag.raised { "raised" } else { "" },
                quote(&x.flag.exceeded.join(";"))
            );
        }
    }
    s
}

/// `route.md`'s running-safety table of one variant: every segment's binding quantity, its
/// utilisation and the limits exceeded.
fn safety_table(r: &VariantResult) -> String {
    let mut s = format!(
        "\n## {} ({}, {} running): running safety of the whole car\n\n| section | kind | from (m) | to (m) | speed (km/h) | binding | utilisation | flag |\n|---|---|---|---|---|---|---|---|\n",
        r.label,
        r.controller,
        r.running.name()
    );
    for x in &r.running_safety {
        let flag = if x.flag.raised {
            format!("**exceeded: {}**", x.flag.exceeded.join(", "))
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} | {:.0} | {:.1} | {} | {:.3} | {} |",
            x.section,
            if x.curve { "curve" } else { "straight" },
            x.from_m,
            x.to_m,
            x.speed_kmh,
            x.flag.binding,
            x.flag.binding_utilisation,
            flag
        );
    }
    s
}

fn variants_csv(results: &[VariantResult]) -> String {
    let positions: Vec<&str> = results
        .first()
        .map(|r| r.sickness.iter().map(|(n, _)| n.as_str()).collect())
        .unwrap_or_default();
    let mut s = String::from(
        "variant,controller,rho,running,cant_deficiency_mm,journey_time_s,simulated_s,segments,failed,p_ct_worst_pct,p_ct_mean_pct,p_ct_worst_025hz_pct,p_ct_worst_04hz_pct,p_ct_worst_unfiltered_roll_pct,n_mv_median,n_mv_p95",
    );
    for p in &positions {
        let _ = write!(
            s,
            ",{p}_msdv_z,{p}_msdv_z_per_hour,{p}_msi_z_pct,{p}_msdv_y,{p}_msdv_y_per_hour,{p}_msdv_roll,{p}_msdv_roll_per_hour"
        );
    }
    s.push_str(",flags\n");
    for r in results {
        let _ = write!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.label,
            r.controller,
            num(r.rho),
            r.running.name(),
            num(r.limits.cant_deficiency_mm(r.running)),
            num(r.journey_time_s),
            num(r.simulated_s),
            r.segments,
            r.failed.len(),
            num(r.p_ct_worst[0]),
            num(r.p_ct_mean[0]),
            num(r.p_ct_worst[1]),
            num(r.p_ct_worst[2]),
            num(r.p_ct_worst[3]),
            num(r.n_mv_median),
            num(r.n_mv_p95)
        );
        for (_, d) in &r.sickness {
            let _ = write!(
                s,
                ",{},{},{},{},{},{},{}",
                num(d.msdv_z),
                num(d.msdv_z_per_hour),
                num(d.msi_z_pct),
                num(d.msdv_y),
                num(d.msdv_y_per_hour),
                num(d.msdv_roll),
                num(d.msdv_roll_per_hour)
            );
        }
        let _ = writeln!(s, ",{}", quote(&r.flags.join(";")));
    }
    s
}

/// Chainage every 25 m and the last point.
pub fn chainages(route: &Route) -> Vec<f64> {
    let start = route.sections[0].chainage_m;
    let end = start + route.length_m();
    let n = ((end - start) / 25.0).ceil() as usize;
    (0..=n)
        .map(|k| (start + 25.0 * k as f64).min(end))
        .collect()
}

fn profile_csv(route: &Route, limits: &Limits) -> String {
    let c = Profile::new(route, Running::Conventional, limits);
    let t = Profile::new(route, Running::Tilting, limits);
    let mut s = String::from("chainage_m,conventional_kmh,tilting_kmh\n");
    for x in chainages(route) {
        let _ = writeln!(
            s,
            "{},{},{}",
            num(x),
            num(c.speed_at(x) * 3.6),
            num(t.speed_at(x) * 3.6)
        );
    }
    s
}

/// `route.md`: the line, the journey times, each variant's summary and its transitions.
pub fn markdown(route: &Route, limits: &Limits, j: &Journey, results: &[VariantResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Route {}: {:.1} km, {} curves\n\nSpeed profiles: cant deficiency {} mm conventional, {} mm tilting; acceleration {} m/s², braking {} m/s², from standstill to standstill.\n\n| running | journey time | time saved |\n|---|---|---|\n| conventional | {} | |\n| tilting | {} | {:.0} s ({:.1} %) |\n",
        route.name,
        route.length_m() / 1000.0,
        route.curves(),
        limits.cant_deficiency_conventional_mm,
        limits.cant_deficiency_tilting_mm,
        limits.accel_m_s2,
        limits.brake_m_s2,
        clock(j.conventional_s),
        clock(j.tilting_s),
        j.saved_s,
        j.saved_pct
    );
    s.push_str(&variants_table(results));
    s.push_str(&sensitivity_table(results));
    for r in results {
        let _ = writeln!(
            s,
            "\n## {} ({}, {} running): every transition\n",
            r.label,
            r.controller,
            r.running.name()
        );
        s.push_str("| curve | transition | chainage (m) | R (m) | cant (mm) | shape | speed (km/h) | cant deficiency (mm) | P_CT standing (%) | P_CT seated (%) | binding |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
        for t in &r.transitions {
            let _ = writeln!(
                s,
                "| {} | {} | {:.0} | {:.0} | {:.0} | {} | {:.1} | {:.0} | {:.2} | {:.2} | {} |",
                t.curve,
                t.transition,
                t.chainage_m,
                t.radius_m,
                t.cant_mm,
                t.shape,
                t.speed_kmh,
                t.cant_deficiency_mm,
                t.comfort.p_ct.standing,
                t.comfort.p_ct.seated,
                t.binding
            );
        }
        if !r.running_safety.is_empty() {
            s.push_str(&safety_table(r));
        }
    }
    s
}

/// mm:ss.
fn clock(t: f64) -> String {
    let m = (t / 60.0).floor();
    format!("{:.0} min {:04.1} s", m, t - 60.0 * m)
}

/// One line per variant: journey time, comfort, ride and doses at the window seat (or the
/// first position).
pub fn variants_table(results: &[VariantResult]) -> String {
    let mut s = String::from(
        "| variant | controller | ρ | running | journey time | P_CT standing worst / mean (%) | N_MV straights median / p95 | MSDV_z per hour (m/s^1.5) | lateral dose per hour (m/s^1.5) | roll-acceleration dose per hour (rad/s^1.5) | failed segments |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        let d = r
            .sickness
            .iter()
            .find(|(n, _)| n == "seat-window")
            .or(r.sickness.first())
            .map(|(_, d)| *d)
            .unwrap_or_default();
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {} | {} | {:.2} / {:.2} | {:.3} / {:.3} | {:.4} | {:.3} | {:.4} | {} |",
            r.label,
            r.controller,
            r.rho,
            r.running.name(),
            clock(r.journey_time_s),
            r.p_ct_worst[0],
            r.p_ct_mean[0],
            r.n_mv_median,
            r.n_mv_p95,
            d.msdv_z_per_hour,
            d.msdv_y_per_hour,
            d.msdv_roll_per_hour,
            r.failed.len()
        );
    }
    s
}

/// The worst and mean P_CT standing of each variant under each reading of EN 12299.
pub fn sensitivity_table(results: &[VariantResult]) -> String {
    let mut s = String::from("\nP_CT standing over the route's transitions, worst / mean (%), under each reading of EN 12299:\n\n| variant |");
    for n in READING_NAMES {
        let _ = write!(s, " {n} |");
    }
    s.push_str("\n|---|---|---|---|---|\n");
    for r in results {
        let _ = write!(s, "| {} |", r.label);
        for k in 0..4 {
            let _ = write!(s, " {:.2} / {:.2} |", r.p_ct_worst[k], r.p_ct_mean[k]);
        }
        s.push('\n');
    }
    s
}
