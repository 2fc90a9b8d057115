//! What link effects and a stall leave in a free run's trace, events and rows, and what its
//! replay repeats of them.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use tiltsim_suite::{scenario, summary};

use super::trace::Step;
use super::{bytes, replay};

/// A free run's steps by `(role, step)`.
pub type ByStep<'a> = HashMap<(String, i64), &'a Step>;

/// The rows of a CSV file with a header, by column name.
pub type CsvRows = Vec<HashMap<String, String>>;

/// pi-drive with effects on three links and a stalled controller, written beside `dir`.
pub fn with_links_and_a_stall(dir: &Path) -> PathBuf {
    let base = std::fs::read_to_string(scenario("pi-drive.toml")).unwrap();
    let file = dir.join("links-and-stall.toml");
    std::fs::create_dir_all(dir).unwrap();
    // The stall is a `[[faults.schedule]]` entry, which `--set` cannot add: one file for all.
    std::fs::write(
        &file,
        format!(
            "{base}
[links.actuator_command]
delay_ticks = 20

[links.bar_angle]
drop_probability = 0.1

[links.measurement]
noise_std = 1e-4

[[faults.schedule]]
participant = \"controller\"
action = \"stall\"
at_s = 1.0
stall_s = 0.2
"
        ),
    )
    .unwrap();
    file
}

/// The command link's 20 ticks are wall time added to the real delivery: no actuator step
/// read a command sooner than 20 ms after the controller published it. A lower bound on
/// instants the trace recorded, which load can only raise (no duration of the test).
pub fn commands_arrive_the_link_delay_late(trace: &[Step], by: &ByStep) {
    let mut commands = 0;
    for x in trace.iter().filter(|x| x.role == "actuator") {
        let q = x.from["controller"];
        if q >= 0 {
            commands += 1;
            let published = by[&("controller".to_string(), q)].publish;
            assert!(
                x.read >= published + 20_000_000,
                "actuator step {} read controller step {q} {} ns after its publish",
                x.step,
                x.read - published
            );
        }
    }
    assert!(commands > 1000, "{commands} actuator steps read a command");
}

/// Lost bar-angle samples: each drawn from the seed per sample (so their number does not
/// depend on the timing), logged, and never read by the plant.
pub fn lost_samples_are_logged_and_never_read(trace: &[Step], events: &CsvRows) {
    let dropped: Vec<i64> = events
        .iter()
        .filter(|e| e["source"] == "bar_angle" && e["event"] == "drop")
        .map(|e| e["step"].parse().unwrap())
        .collect();
    // p = 0.1 over the 2000 samples of the run: 200 ± 6σ (σ = 13.4).
    assert!(
        (120..=280).contains(&dropped.len()),
        "{} drops",
        dropped.len()
    );
    for q in &dropped {
        for x in trace.iter().filter(|x| x.role == "plant") {
            assert_ne!(
                x.from["actuator"], *q,
                "plant step {} read a lost sample",
                x.step
            );
        }
    }
}

/// The noise reaches the controller: for row k, follow the trace from plant step k to the
/// actuator step it read, the controller step that one read and the plant step that one
/// read; what the controller received less what that plant step measured is the noise,
/// Gaussian with the declared deviation: 1e-4 within 6σ of a deviation estimated from the
/// n distinct samples read (σ/σ ≈ 1/√(2(n−1))), mean within 6σ/√n. How many distinct
/// samples the rows reach depends on the timing (a late or stalled step reads one for
/// several rows); without the noise every difference would be 0.
pub fn the_noise_reaches_the_controller(rows: &CsvRows, by: &ByStep) {
    let num = |r: &HashMap<String, String>, c: &str| r[c].parse::<f64>().unwrap();
    // Each plant sample's noise once (a stalled controller reads one sample for many rows).
    let mut noise_of: HashMap<i64, f64> = HashMap::new();
    // Row k + 1 holds plant step k (row 0 the outputs at the start time).
    for (k, r) in rows.iter().enumerate().skip(1).map(|(i, r)| (i - 1, r)) {
        let qa = by[&("plant".to_string(), k as i64)].from["actuator"];
        if qa < 0 {
            continue;
        }
        let qc = by[&("actuator".to_string(), qa)].from["controller"];
        if qc < 0 {
            continue;
        }
        let qp = by[&("controller".to_string(), qc)].from["plant"];
        if qp < 0 {
            continue;
        }
        noise_of.insert(
            qp,
            num(r, "rx_measurement") - num(&rows[qp as usize + 1], "theta_v_meas"),
        );
    }
    let noise: Vec<f64> = noise_of.into_values().collect();
    let n = noise.len() as f64;
    assert!(n >= 200.0, "{n} measurements traced back from the rows");
    let mean = noise.iter().sum::<f64>() / n;
    let sd = (noise.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let tolerance = 6.0 / (2.0 * (n - 1.0)).sqrt();
    assert!(
        (sd / 1e-4 - 1.0).abs() < tolerance,
        "noise deviation {sd} over {n} samples"
    );
    assert!(mean.abs() < 6.0 * 1e-4 / n.sqrt(), "noise mean {mean}");
}

/// The stall: SIGSTOP for 0.2 s of wall time when the plant reached 1.0 s. The controller
/// step due next started at least the rest of the stall late (a 1 ms period: > 0.15 s).
pub fn the_stalled_controller_started_late(trace: &[Step], events: &CsvRows) {
    assert!(events.iter().any(|e| e["source"] == "controller"
        && e["event"] == "fault-injected"
        && e["step"] == "1000"));
    let late = trace
        .iter()
        .filter(|x| x.role == "controller")
        .map(|x| x.read - x.due)
        .max()
        .unwrap();
    assert!(
        late >= 150_000_000,
        "the controller was at most {late} ns late"
    );
}

/// The replay (into `root/replay`) of the free run in `out` repeats the values and the
/// events, byte for byte, and gives the comfort and flags of what was replayed.
pub fn the_replay_repeats_values_events_and_flags(out: &Path, root: &Path) {
    let (code, err) = replay(out, &root.join("replay"), &[]);
    assert_eq!(code, 0, "{err}");
    for f in ["timeseries.csv", "events.csv"] {
        assert_eq!(
            bytes(&root.join("replay").join(f)),
            bytes(&out.join(f)),
            "{f}"
        );
    }
    // And gives the comfort of what was replayed, as the free run's summary does.
    let free = summary(out);
    let again = summary(&root.join("replay"));
    assert_eq!(free["comfort"], again["comfort"]);
    assert!(
        free["comfort"]["p_ct_en12299"]["standing_pct"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    // Every flag of the series is the replay's, and so is the free run's judgement on real
    // time, made again from the same trace (its lateness summed in other units: equal to 1 ns).
    let (mut f, mut a) = (free["flags"].clone(), again["flags"].clone());
    let nf = f.as_object_mut().unwrap().remove("not_real_time").unwrap();
    let na = a.as_object_mut().unwrap().remove("not_real_time").unwrap();
    assert_eq!(f, a);
    assert_eq!(nf["raised"], na["raised"]);
    assert_eq!(nf["margin_s"], na["margin_s"]);
    let late = |v: &serde_json::Value| v["plant_max_lateness_s"].as_f64().unwrap();
    assert!((late(&nf) - late(&na)).abs() < 1e-9, "{nf} {na}");
}
