//! `tiltsim falsify` split as sweeps are (`--shard I/N`, merged with `falsify-merge`) equals
//! the same restarts in one process (`--restarts N`); bad shard specifications, freeze
//! budgets and merges exit 2 naming the field; the measurement and the command searched at
//! once.

use std::path::Path;

use tiltsim_suite::{csv_table, temp_dir, Tiltsim};

const DURATION: &str = "3";
const BOUNDS: &str = "[actuator_command]\ndelay_ms = [0, 60]\njitter_ms = 10\nloss_pct = 1\n";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn falsify(bounds: &Path, out: &Path, extra: &[&str]) -> Tiltsim {
    Tiltsim::command(["falsify"])
        .arg(tiltsim_suite::scenario("paper-lqg.toml"))
        .arg("--bounds")
        .arg(bounds)
        .args(["--set", &format!("run.duration_s={DURATION}")])
        .args(extra)
        .out(out)
}

fn result(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap()
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// `result.json` without the figures measured on the clock (CPU and wall time).
fn deterministic(mut v: serde_json::Value) -> serde_json::Value {
    for k in ["evaluation_cpu_s", "plain_run_cpu_s", "search_s"] {
        v.as_object_mut().unwrap().remove(k);
    }
    v
}

/// Two shards run apart (one evaluation at a time; the second as a Slurm array task with
/// `--shard auto`), merged with `falsify-merge`, give the files `--restarts 2` gives in one
/// process with two evaluations in parallel: the progress, the worst trace and its replay's
/// rows byte for byte, the same result; run again, the restarts resume and change nothing. The merged worst is
/// the larger of the two shards' worsts, every evaluation of both is in the progress (the
/// budget of 7 split 4 + 3), and the merged worst trace replays to its rows.
#[test]
fn sharded_and_merged_equals_the_restarts_in_one_process() {
    let dir = temp_dir("falsify-shards");
    let b = write(&dir, "b.toml", BOUNDS);
    let common = ["--budget", "7", "--seed", "3", "-q"];
    falsify(&b, &dir.join("s0"), &common)
        .args(["--shard", "0/2", "--jobs", "1"])
        .success();
    // Shard 1 as the second task of a Slurm array of two.
    let mut task = falsify(&b, &dir.join("s1"), &common).args(["--shard", "auto", "--jobs", "1"]);
    for (k, v) in [
        ("SLURM_ARRAY_TASK_ID", "1"),
        ("SLURM_ARRAY_TASK_MIN", "0"),
        ("SLURM_ARRAY_TASK_MAX", "1"),
        ("SLURM_ARRAY_TASK_STEP", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "2"),
    ] {
        task = task.env(k, v);
    }
    task.success();
    Tiltsim::command(["falsify-merge"])
        .arg(dir.join("s1"))
        .arg(dir.join("s0"))
        .args(["-q"])
        .out(dir.join("merged"))
        .success();
    let one = dir.join("one");
    falsify(&b, &one, &common)
        .args(["--restarts", "2", "--jobs", "2"])
        .success();
    let merged = dir.join("merged");
    for f in ["progress.csv", "worst/timing.csv", "worst/timeseries.csv"] {
        assert!(
            bytes(&merged.join(f)) == bytes(&one.join(f)),
            "{f}: merged shards differ from --restarts 2"
        );
    }
    assert_eq!(deterministic(result(&merged)), deterministic(result(&one)));
    // Run again, the restarts take every evaluation they kept and write the same files.
    let err = falsify(&b, &one, &common)
        .args(["--restarts", "2", "--jobs", "1"])
        .failure(0);
    assert_eq!(err.matches("resuming:").count(), 2, "{err}");
    assert!(bytes(&merged.join("progress.csv")) == bytes(&one.join("progress.csv")));
    let (r0, r1, m) = (
        result(&dir.join("s0")),
        result(&dir.join("s1")),
        result(&merged),
    );
    assert_eq!(r0["budget"], 4);
    assert_eq!(r1["budget"], 3);
    assert_ne!(r0["seed"], r1["seed"]);
    let w = |r: &serde_json::Value| r["worst_objective"].as_f64().unwrap();
    assert_eq!(w(&m), w(&r0).max(w(&r1)));
    let from = if w(&r1) > w(&r0) {
        &dir.join("s1")
    } else {
        &dir.join("s0")
    };
    assert!(bytes(&merged.join("worst/timing.csv")) == bytes(&from.join("worst/timing.csv")));
    assert_eq!(m["merged_shards"], 2);
    assert_eq!(m["budget"], 7);
    let rows = csv_table(&std::fs::read_to_string(merged.join("progress.csv")).unwrap());
    assert_eq!(rows[0][0], "shard");
    assert_eq!(rows.len(), 1 + 14);
    let shards: Vec<&str> = rows[1..8].iter().map(|r| r[0].as_str()).collect();
    assert_eq!(shards, ["0", "0", "0", "0", "1", "1", "1"]);
    Tiltsim::command(["replay-timing"])
        .arg(merged.join("worst"))
        .args(["--no-plots", "-q"])
        .out(dir.join("again"))
        .success();
    assert!(
        bytes(&dir.join("again/timeseries.csv")) == bytes(&merged.join("worst/timeseries.csv"))
    );
}

/// A shard that is not `I/N` with `I < N`, `--shard auto` outside an array task, more
/// shards than evaluations, and a merge missing a shard or given one twice exit 2 naming
/// the flag or file and field.
#[test]
fn bad_shards_and_merges_exit_2_naming_the_field() {
    let dir = temp_dir("falsify-bad-shards");
    let b = write(&dir, "b.toml", BOUNDS);
    let out = dir.join("out");
    for (shard, want) in [
        ("2/2", "--shard `2/2`: expected I/N with 0 <= I < N"),
        ("x", "--shard `x`: expected I/N"),
        ("0/9", "--shard 0/9: 9 shards for --budget 4"),
    ] {
        let err = falsify(&b, &out, &["--budget", "4", "--shard", shard]).failure(2);
        assert!(err.contains(want), "{shard}: {err}");
    }
    let err = falsify(&b, &out, &["--budget", "4", "--shard", "auto"])
        .env("SLURM_ARRAY_TASK_ID", "")
        .failure(2);
    assert!(err.contains("--shard auto"), "{err}");
    let err = falsify(&b, &out, &["--budget", "4", "--restarts", "5"]).failure(2);
    assert!(err.contains("--restarts 5"), "{err}");
    let s0 = dir.join("s0");
    falsify(
        &b,
        &s0,
        &["--budget", "2", "--shard", "0/2", "--jobs", "1", "-q"],
    )
    .success();
    let err = Tiltsim::command(["falsify-merge"])
        .arg(&s0)
        .out(dir.join("m"))
        .failure(2);
    assert!(err.contains("the search has 2 shards"), "{err}");
    let err = Tiltsim::command(["falsify-merge"])
        .arg(&s0)
        .arg(&s0)
        .out(dir.join("m"))
        .failure(2);
    assert!(
        err.contains("shard.json: index: shard 0 given twice"),
        "{err}"
    );
    let err = Tiltsim::command(["falsify-merge"])
        .arg(&out)
        .out(dir.join("m"))
        .failure(2);
    assert!(err.contains("shard.json"), "{err}");
}

/// A freeze budget below zero, or longer than the run, exits 2 naming the file, the link and
/// the field.
#[test]
fn a_bad_freeze_budget_exits_2_naming_the_field() {
    let dir = temp_dir("falsify-bad-freeze");
    let out = dir.join("out");
    let neg = write(
        &dir,
        "neg.toml",
        "[measurement]\ndelay_ms = [0, 10]\nfreeze_ms = -20\n",
    );
    let err = falsify(&neg, &out, &[]).failure(2);
    assert!(
        err.contains("neg.toml: [measurement] freeze_ms: -20; allowed: >= 0 ms"),
        "{err}"
    );
    let long = write(
        &dir,
        "long.toml",
        "[actuator_command]\ndelay_ms = [0, 10]\nfreeze_ms = 4000\n",
    );
    let err = falsify(&long, &out, &[]).failure(2);
    assert!(
        err.contains("long.toml: [actuator_command] freeze_ms: 4000 ms is longer than the run")
            && err.contains("allowed: 0 to 3000 ms"),
        "{err}"
    );
}

/// The measurement and the command searched at once, each with loss and freeze budgets: the
/// point has both links' coordinates; with a budget of one, the search's one evaluation is the
/// first obvious adversary (every link at its largest delay) beside one random timing, so the
/// worst trace delays the controller's measurements and the actuator's commands (reads other
/// than the lock-step ones on both links), and `replay-timing` replays it byte for byte.
#[test]
fn the_measurement_and_the_command_are_searched_at_once() {
    let dir = temp_dir("falsify-two-links");
    let b = write(
        &dir,
        "b.toml",
        "[actuator_command]\ndelay_ms = [0, 60]\njitter_ms = 10\nloss_pct = 1\nfreeze_ms = 40\n[measurement]\ndelay_ms = [0, 20]\njitter_ms = 5\nloss_pct = 1\nfreeze_ms = 30\n",
    );
    let out = dir.join("out");
    falsify(&b, &out, &["--budget", "1", "--jobs", "2", "-q"]).success();
    // Per link: 6 knots, the jitter's amplitude and half-period, two loss windows and two
    // stalls (a position and a share each).
    let r = result(&out);
    assert_eq!(r["dims"], 2 * (6 + 2 + 4 + 4));
    // Every candidate was admissible (within both budgets) and replayed.
    assert_eq!(r["failed_evaluations"], 0);
    let text = std::fs::read_to_string(out.join("worst/timing.csv")).unwrap();
    let body: String = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| format!("{l}\n"))
        .collect();
    let rows = csv_table(&body);
    let col = |name: &str| rows[0].iter().position(|c| c == name).unwrap();
    let (role, step) = (col("role"), col("step"));
    let (from_plant, from_controller) = (col("from_plant"), col("from_controller"));
    let late = |who: &str, from: usize, lock_step: &dyn Fn(i64) -> i64| {
        rows[1..]
            .iter()
            .filter(|r| r[role] == who)
            .filter(|r| r[from].parse::<i64>().unwrap() != lock_step(r[step].parse().unwrap()))
            .count()
    };
    assert!(
        late("controller", from_plant, &|k| k - 1) > 0,
        "measurement never late"
    );
    assert!(
        late("actuator", from_controller, &|k| k) > 0,
        "command never late"
    );
    Tiltsim::command(["replay-timing"])
        .arg(out.join("worst"))
        .args(["--no-plots", "-q"])
        .out(dir.join("r"))
        .success();
    assert!(bytes(&dir.join("r/timeseries.csv")) == bytes(&out.join("worst/timeseries.csv")));
}

/// `cp -r from to`, `sha256sum` and the like, run in `dir`; panics naming the command.
fn sh(dir: &Path, script: &str) -> String {
    let out = std::process::Command::new("sh")
        .args(["-c", script])
        .current_dir(dir)
        .output()
        .unwrap_or_else(|e| panic!("{script}: {e}"));
    assert!(out.status.success(), "{script}: {out:?}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A copy of shard `from` as `dir/name`, with `edit` applied to its file `file`.
fn tampered(dir: &Path, from: &Path, name: &str, file: &str, edit: impl Fn(&str) -> String) {
    sh(dir, &format!("cp -r '{}' '{name}'", from.display()));
    let p = dir.join(name).join(file);
    let text = std::fs::read_to_string(&p).unwrap();
    let changed = edit(&text);
    assert_ne!(changed, text, "{file}: the edit changed nothing");
    std::fs::write(&p, changed).unwrap();
}

/// The first evaluation's `objective` in a `progress.csv` set to 99999.
fn objective_99999(text: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let head: Vec<&str> = lines[0].split(',').collect();
    let col = head.iter().position(|c| *c == "objective").unwrap();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[col] = "99999".into();
    lines[1] = cells.join(",");
    lines.join("\n") + "\n"
}

/// A merge verifies what it merges. Each finished shard writes `sha256.txt` (the form
/// `sha256sum -c` checks, and it does); a shard whose `progress.csv` or `shard.json` was
/// changed afterwards is refused naming the file; one whose digests were written again over
/// an edited objective is refused because its worst trace, replayed, does not give what it
/// claims.
#[test]
fn a_merge_refuses_shards_changed_after_they_finished() {
    let dir = temp_dir("falsify-tampered");
    let b = write(&dir, "b.toml", BOUNDS);
    let (s0, s1) = (dir.join("s0"), dir.join("s1"));
    for (d, shard) in [(&s0, "0/2"), (&s1, "1/2")] {
        falsify(
            &b,
            d,
            &["--budget", "2", "--shard", shard, "--jobs", "1", "-q"],
        )
        .success();
    }
    sh(&s0, "sha256sum -c sha256.txt");
    let merge = |first: &Path| {
        Tiltsim::command(["falsify-merge"])
            .arg(first)
            .arg(&s1)
            .out(dir.join("m"))
    };
    merge(&s0).success();

    tampered(&dir, &s0, "t-progress", "progress.csv", objective_99999);
    let err = merge(&dir.join("t-progress")).failure(2);
    assert!(
        err.contains("t-progress/progress.csv") && err.contains("SHA-256"),
        "{err}"
    );
    tampered(&dir, &s0, "t-seed", "shard.json", |t| {
        let v: serde_json::Value = serde_json::from_str(t).unwrap();
        let seed = v["shard_seed"].as_u64().unwrap();
        t.replace(
            &format!("\"shard_seed\": {seed}"),
            &format!("\"shard_seed\": {}", seed + 1),
        )
    });
    let err = merge(&dir.join("t-seed")).failure(2);
    assert!(
        err.contains("t-seed/shard.json") && err.contains("SHA-256"),
        "{err}"
    );
    tampered(&dir, &s0, "t-redigested", "progress.csv", objective_99999);
    let t = dir.join("t-redigested");
    sh(
        &t,
        "sha256sum shard.json result.json progress.csv bounds.toml worst/timing.csv > sha256.txt",
    );
    let err = merge(&t).failure(2);
    assert!(
        err.contains("t-redigested/progress.csv") && err.contains("replays to"),
        "{err}"
    );
}
