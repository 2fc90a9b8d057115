//! What the replay of a free run's trace gives when the trace is edited, when it replays
//! another system, and when it does not belong to the scenario.

use std::path::Path;

use super::{bytes, replay, s};
use tiltsim_suite::summary;

/// The replay follows the trace: the first plant step from 1000 on that read a newer
/// actuator step than the step before it, told it read the same one as that step (one that
/// could have happened: a late sample), gives other rows from there on, and the same rows
/// before (`free`: the free run's rows).
pub fn an_edited_trace_changes_the_rows_from_its_step(dir: &Path, root: &Path, free: &[u8]) {
    let edited = root.join("edited");
    std::fs::create_dir_all(&edited).unwrap();
    std::fs::copy(dir.join("scenario.toml"), edited.join("scenario.toml")).unwrap();
    let text = std::fs::read_to_string(dir.join("timing.csv")).unwrap();
    let from_actuator = |step: usize| -> String {
        let l = text
            .lines()
            .find(|l| l.starts_with(&format!("plant,{step},")))
            .unwrap();
        l.split(',').nth(3).unwrap().to_string()
    };
    let k = (1000..1990)
        .find(|&k| from_actuator(k) != from_actuator(k - 1))
        .expect("the plant read the same actuator step from step 1000 to the end");
    let before = from_actuator(k - 1);
    let changed: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with(&format!("plant,{k},")) {
                let mut c: Vec<&str> = l.split(',').collect();
                c[3] = before.as_str();
                c.join(",")
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(edited.join("timing.csv"), changed.join("\n") + "\n").unwrap();
    let (code, err) = replay(&edited, &root.join("edited-out"), &[]);
    assert_eq!(code, 0, "{err}");
    let other = bytes(&root.join("edited-out/timeseries.csv"));
    let lines = |b: &[u8]| {
        String::from_utf8_lossy(b)
            .lines()
            .map(String::from)
            .collect::<Vec<_>>()
    };
    // The header, the row at the start and one row after each step: step k's is line k + 2.
    let (a, b) = (lines(free), lines(&other));
    assert_eq!(
        a[..k + 2],
        b[..k + 2],
        "rows before plant step {k} are unchanged"
    );
    assert_ne!(
        a[k + 2..],
        b[k + 2..],
        "the edited step {k} changes what follows"
    );
}

/// Another system under the same timing: twice the PI gain. Same time base, other commands.
pub fn another_system_is_replayed_under_the_same_timing(dir: &Path, root: &Path) {
    let resolved = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
    assert!(resolved.contains("\nkp = 0.5708\n"));
    let stiffer = root.join("stiffer.toml");
    std::fs::write(
        &stiffer,
        resolved.replace("\nkp = 0.5708\n", "\nkp = 1.1416\n"),
    )
    .unwrap();
    let (code, err) = replay(dir, &root.join("kp"), &["--scenario", s(&stiffer)]);
    assert_eq!(code, 0, "{err}");
    let kp = tiltsim_suite::Series::read(&root.join("kp/timeseries.csv"));
    let base = tiltsim_suite::Series::read(&dir.join("timeseries.csv"));
    assert_eq!(kp.col("time"), base.col("time"));
    assert_ne!(kp.col("delta_a_cmd"), base.col("delta_a_cmd"));
}

/// A trace that does not belong to the scenario is refused naming the file and the field;
/// so is one with a step missing.
pub fn a_foreign_or_gapped_trace_is_refused(dir: &Path, root: &Path) {
    let trace_file = dir.join("timing.csv");
    let name = trace_file.display().to_string();
    for (set, field) in [("run.dt_s=0.0005", "dt_s"), ("run.duration_s=1", "steps")] {
        let other = root.join(format!("foreign-{field}"));
        std::fs::create_dir_all(&other).unwrap();
        let (k, v) = set.split_once('=').unwrap();
        let text = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
        let mut doc: toml::Table = toml::from_str(&text).unwrap();
        let (sec, key) = k.split_once('.').unwrap();
        doc.get_mut(sec)
            .and_then(|t| t.as_table_mut())
            .unwrap()
            .insert(key.into(), toml::Value::Float(v.parse().unwrap()));
        let file = other.join("scenario.toml");
        std::fs::write(&file, toml::to_string(&doc).unwrap()).unwrap();
        let (code, err) = replay(dir, &other.join("out"), &["--scenario", s(&file)]);
        assert_eq!(code, 2, "{field}: {err}");
        assert!(err.contains(&name) && err.contains(field), "{field}: {err}");
    }
    let text = std::fs::read_to_string(&trace_file).unwrap();
    let gap = root.join("gap");
    std::fs::create_dir_all(&gap).unwrap();
    std::fs::copy(dir.join("scenario.toml"), gap.join("scenario.toml")).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with("actuator,500,"))
        .collect();
    std::fs::write(gap.join("timing.csv"), kept.join("\n") + "\n").unwrap();
    let (code, err) = replay(&gap, &root.join("gap-out"), &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("timing.csv") && err.contains("step") && err.contains("actuator step 500"),
        "{err}"
    );
    // A step that reads an older sample than the step before it read cannot have happened
    // (a consumer keeps the newest sample that reached it): plant step 1000 told it read the
    // bar angle at t₀, a thousand ticks old.
    let older = root.join("older");
    std::fs::create_dir_all(&older).unwrap();
    std::fs::copy(dir.join("scenario.toml"), older.join("scenario.toml")).unwrap();
    let mut line = 0;
    let changed: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if l.starts_with("plant,1000,") {
                line = i + 1;
                let mut c: Vec<&str> = l.split(',').collect();
                c[3] = "-1";
                c.join(",")
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(older.join("timing.csv"), changed.join("\n") + "\n").unwrap();
    let (code, err) = replay(&older, &root.join("older-out"), &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("timing.csv")
            && err.contains(&format!("line {line}: from_actuator"))
            && err.contains("plant step 1000 reads actuator step -1"),
        "{err}"
    );
}

/// A free run whose plant started a step 20 ms after it was due did not keep real time (the
/// margin is 10 ticks, 10 ms): its replay says so and its comfort is not valid, whatever the
/// rows. The trace is the run's with that one step's due instant moved 20 ms earlier.
pub fn a_late_plant_step_makes_the_replay_not_real_time(dir: &Path, root: &Path) {
    let late = root.join("late");
    std::fs::create_dir_all(&late).unwrap();
    std::fs::copy(dir.join("scenario.toml"), late.join("scenario.toml")).unwrap();
    let text = std::fs::read_to_string(dir.join("timing.csv")).unwrap();
    let changed: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with("plant,1500,") {
                let mut c: Vec<String> = l.split(',').map(String::from).collect();
                let read: u64 = c[9].parse().unwrap();
                c[8] = (read - 20_000_000).to_string();
                c.join(",")
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(late.join("timing.csv"), changed.join("\n") + "\n").unwrap();
    let (code, err) = replay(&late, &root.join("late-out"), &[]);
    assert_eq!(code, 0, "{err}");
    let sm = summary(&root.join("late-out"));
    let n = &sm["flags"]["not_real_time"];
    assert_eq!(n["raised"], true, "{n}");
    assert!(n["plant_max_lateness_s"].as_f64().unwrap() >= 0.020, "{n}");
    assert_eq!(sm["comfort_valid"], false, "{sm}");
}
