//! The trade-off between curving and straight-track comfort: each controller's curve run
//! beside its straight run, as a table and as the points of its figure.

use std::fmt::Write as _;

use tiltsim_assessment::comfort::Comfort;

use super::tidy::{Key, Tidy, Who};
use super::{fmt, ideal_columns, straight_only, Entry};

/// One controller's curving comfort against its straight-track ride: the curve run and the
/// straight run of the same controller and actuator settings, with the curve run's ideal
/// tilt.
pub struct TradeOff<'a> {
    /// Controller label (without the scenario).
    pub controller: String,
    /// The curve run and its ideal-tilt column.
    pub curve: (&'a Entry, &'a Comfort),
    /// The straight run.
    pub straight: &'a Entry,
}

/// Pairs each curve run with the first straight-only run of the same controller and actuator.
pub fn trade_offs<'a>(entries: &'a [Entry], ideal_of: &[&'a Comfort]) -> Vec<TradeOff<'a>> {
    let mut out = Vec::new();
    for (e, ideal) in entries.iter().zip(ideal_of) {
        if straight_only(&e.scenario) {
            continue;
        }
        let twin = entries.iter().find(|o| {
            straight_only(&o.scenario)
                && o.scenario.controller == e.scenario.controller
                && o.scenario.actuator == e.scenario.actuator
        });
        if let Some(st) = twin {
            let controller = e.label.split(" [").next().unwrap_or(&e.label).to_string();
            out.push(TradeOff {
                controller,
                curve: (e, ideal),
                straight: st,
            });
        }
    }
    out
}

/// The curving-against-straight table: P_CT and the peak lateral acceleration over the ideal
/// tilt on the curve, EN 12299's lateral mean comfort and the roll measures on the straight.
pub(super) fn trade_off(
    md: &mut String,
    csv: &mut Tidy,
    ideal: &[(String, &Comfort)],
    of: &[usize],
    entries: &[Entry],
) {
    let ideal_of: Vec<&Comfort> = of.iter().map(|i| ideal[*i].1).collect();
    let pairs = trade_offs(entries, &ideal_of);
    if pairs.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Curving comfort against straight-track ride\n\nEach controller on the curve \
         (P_CT standing, EN 12299 per transition; peak lateral acceleration over the ideal tilt) \
         and on the straight irregular track (EN 12299 mean comfort, lateral part \
         6·a_YP95^Wd; tilt error and roll acceleration RMS). Lower is better in every \
         column.\n\n| controller | curve run | P_CT standing (%) | lateral acceleration \
         peak over ideal tilt (%g) | straight run | N_MV lateral part | tilt error RMS (deg) \
         | roll acceleration RMS (rad/s²) |\n|---|---|---|---|---|---|---|---|"
    );
    for t in pairs {
        let (c, i) = (&t.curve.0.summary.comfort, t.curve.1);
        let r = &t.straight.summary.comfort.ride;
        let over = c.lat_acc_peak_pct_g - i.lat_acc_peak_pct_g;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:+.3} | {} | {} | {} | {} |",
            t.controller,
            t.curve.0.scenario.name,
            fmt(c.p_ct_en12299.standing),
            over,
            t.straight.scenario.name,
            fmt(r.n_mv_lateral),
            fmt(r.tilt_error_rms_deg),
            fmt(r.roll_acc_rms_rad_s2)
        );
        let pair = format!("{}+{}", t.curve.0.scenario.name, t.straight.scenario.name);
        let who = Who {
            run: &pair,
            controller: &t.controller,
            ideal: "",
        };
        for (metric, unit, about, v) in [
            (
                "trade_off_p_ct_en12299_standing_pct",
                "%",
                "Trade-off: P_CT standing on the curve, EN 12299",
                c.p_ct_en12299.standing,
            ),
            (
                "trade_off_lat_acc_peak_over_ideal_pct_g",
                "%g",
                "Trade-off: lateral acceleration peak over ideal tilt on the curve",
                over,
            ),
            (
                "trade_off_n_mv_lateral",
                "1",
                "Trade-off: N_MV lateral part on the straight",
                r.n_mv_lateral,
            ),
            (
                "trade_off_tilt_error_rms_deg",
                "deg",
                "Trade-off: tilt error RMS on the straight",
                r.tilt_error_rms_deg,
            ),
            (
                "trade_off_roll_acc_rms_rad_s2",
                "rad/s2",
                "Trade-off: roll acceleration RMS on the straight",
                r.roll_acc_rms_rad_s2,
            ),
        ] {
            let k = Key {
                metric,
                unit,
                about,
            };
            csv.put(k, "", who, v, None, &[]);
        }
    }
}

/// One controller's point of the trade-off figure, kept in `compare.json` so that
/// `tiltsim plot` redraws the figure from the compare's files.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TradeOffPoint {
    /// The controller.
    pub controller: String,
    /// P_CT standing on the curve, EN 12299 per transition (%).
    pub p_ct_en12299_standing_pct: f64,
    /// The lateral part of N_MV on the straight.
    pub n_mv_lateral: f64,
}

/// The points of the trade-off figure: each curve run with a straight twin.
pub fn trade_off_points(entries: &[Entry]) -> Vec<TradeOffPoint> {
    let (ideal, of) = ideal_columns(entries);
    let ideal_of: Vec<&Comfort> = of.iter().map(|i| ideal[*i].1).collect();
    trade_offs(entries, &ideal_of)
        .into_iter()
        .map(|t| TradeOffPoint {
            controller: t.controller,
            p_ct_en12299_standing_pct: t.curve.0.summary.comfort.p_ct_en12299.standing,
            n_mv_lateral: t.straight.summary.comfort.ride.n_mv_lateral,
        })
        .collect()
}
