//! What the replay of a free run's trace gives when the trace is edited, when it replays
//! another system, and when it does not belong to the scenario.

use std::path::Path;

use super::{bytes, replay, s};

/// The replay follows the trace: plant step 1000 told it read the bar angle at t₀ instead
/// gives other rows from there on, and the same rows before (`free`: the free run's rows).
pub fn an_edited_trace_changes_the_rows_from_its_step(dir: &Path, root: &Path, free: &[u8]) {
    let edited = root.join("edited");
    std::fs::create_dir_all(&edited).unwrap();
    std::fs::copy(dir.join("scenario.toml"), edited.join("scenario.toml")).unwrap();
    let text = std::fs::read_to_string(dir.join("timing.csv")).unwrap();
    let changed: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with("plant,1000,") {
                let mut c: Vec<&str> = l.split(',').collect();
                c[3] = "-1";
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
    let (a, b) = (lines(free), lines(&other));
    assert_eq!(a[..1001], b[..1001], "rows before step 1000 are unchanged");
    assert_ne!(a[1001..], b[1001..], "the edited step changes what follows");
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
}
