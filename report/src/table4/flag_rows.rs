//! The validity flags in the compare's tables: in `table.md` one row per flag with its
//! measured values in words, in `table.csv` one metric per number, its `flags` the flag's
//! code where the flag is raised.

use std::fmt::Write as _;

use super::tidy::{Key, Tidy};
use super::{Entry, Names};

/// A flag row's cell: raised, the measured value as text, and the numbers behind it.
type FlagCell = fn(&tiltsim_assessment::validity::Flags) -> (bool, String, Vec<f64>);

/// The numbers behind each validity flag in `table.csv`: key, unit and meaning, in the order
/// of the flag row's [`FlagCell`] values.
type FlagKeys = &'static [(&'static str, &'static str, &'static str)];

/// Validity flags, each with its measured value: in `table.md` one row per flag, in
/// `table.csv` one metric per number, its `flags` the flag's code where it is raised.
pub(super) fn flag_rows(
    md: &mut String,
    csv: &mut Tidy,
    ideal_columns: usize,
    entries: &[Entry],
    names: &Names,
) {
    for (name, code, keys, get) in FLAGS {
        let _ = write!(md, "| {name} |");
        for _ in 0..ideal_columns {
            let _ = write!(md, " — |");
        }
        for (i, e) in entries.iter().enumerate() {
            let (raised, text, values) = get(&e.summary.flags);
            if raised {
                let _ = write!(md, " ⚠ {text} |");
            } else {
                let _ = write!(md, " clear ({text}) |");
            }
            let flags: &[&str] = if raised { &[code] } else { &[] };
            for ((metric, unit, about), v) in keys.iter().zip(values) {
                let k = Key {
                    metric,
                    unit,
                    about,
                };
                csv.put(k, "", names.entry(entries, i), v, None, flags);
            }
        }
        md.push('\n');
    }
}

/// Each validity flag: its row in `table.md`, its code, the metrics of its numbers and how
/// to read them from the flags.
const FLAGS: [(&str, &str, FlagKeys, FlagCell); 5] = [
    (
        "Oscillation of θ_v − θ_ref (amplitude, frequency)",
        "oscillation",
        &[
            (
                "oscillation_amplitude_deg",
                "deg",
                "Amplitude of the oscillation of theta_v - theta_ref",
            ),
            (
                "oscillation_frequency_hz",
                "Hz",
                "Frequency of the oscillation of theta_v - theta_ref",
            ),
        ],
        |f| {
            let o = &f.oscillation;
            let text = format!("±{:.3}° at {:.2} Hz", o.amplitude_deg, o.frequency_hz);
            (o.raised, text, vec![o.amplitude_deg, o.frequency_hz])
        },
    ),
    (
        "Bump-stop contact (peak deflection, time, peak force a side)",
        "bump_stop",
        &[
            (
                "bump_stop_deflection_peak_mm",
                "mm",
                "Largest secondary lateral deflection",
            ),
            (
                "bump_stop_time_in_contact_s",
                "s",
                "Time in contact with a bump stop",
            ),
            (
                "bump_stop_force_peak_kn",
                "kN",
                "Largest bump-stop force a side",
            ),
        ],
        |f| {
            let b = &f.bump_stop;
            let text = format!(
                "{:.1} mm, {:.3} s, {:.1} kN",
                b.deflection_peak_mm, b.time_in_contact_s, b.force_peak_kn
            );
            let v = vec![b.deflection_peak_mm, b.time_in_contact_s, b.force_peak_kn];
            (b.raised, text, v)
        },
    ),
    (
        "Time at a drive limit (s)",
        "drive_limit",
        &[
            ("drive_limit_time_s", "s", "Time at any drive limit"),
            (
                "drive_limit_torque_s",
                "s",
                "Time at the drive's torque limit",
            ),
            (
                "drive_limit_speed_s",
                "s",
                "Time at the drive's speed limit",
            ),
        ],
        |f| {
            let d = &f.drive_limit;
            let t = (d.time_at_any_limit_s, d.torque_s, d.speed_s);
            let text = format!("{:.3} (torque {:.3}, speed {:.3})", t.0, t.1, t.2);
            (d.raised, text, vec![t.0, t.1, t.2])
        },
    ),
    (
        "Energy dumped in the braking chopper (kJ)",
        "chopper",
        &[(
            "chopper_energy_j",
            "J",
            "Energy dumped in the braking chopper",
        )],
        |f| {
            let c = &f.chopper;
            (
                c.raised,
                format!("{:.2}", c.energy_j / 1e3),
                vec![c.energy_j],
            )
        },
    ),
    (
        "Largest P_CT (%; the formula's range is 0-100)",
        "p_ct_range",
        &[(
            "p_ct_largest_pct",
            "%",
            "Largest P_CT of the run (the formula's range is 0-100 %)",
        )],
        |f| {
            let p = &f.p_ct_range;
            (
                p.raised,
                format!("{:.1}", p.largest_pct),
                vec![p.largest_pct],
            )
        },
    ),
];
