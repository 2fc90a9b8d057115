//! `tiltsim sweep-merge`: shards whose files were changed after the sweep wrote them, that
//! hold samples of another shard or of no plan, twice or not at all, are refused naming the
//! file.

use std::path::Path;

use tiltsim_suite::{copy_dir, mc_args, run, run_strings, scenario_with, temp_dir};

/// Sets the checksum `sweep.json` records for `file` to the file's own, as a tamperer who
/// knows the format would.
fn reseal(dir: &Path, file: &str) {
    use sha2::Digest as _;
    let bytes = std::fs::read(dir.join(file)).unwrap();
    let sum: String = sha2::Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let p = dir.join("sweep.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["sha256"][file] = serde_json::Value::String(sum);
    std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

/// A change to a shard's file: the shard's directory and its file's lines in, the new text
/// out.
type Tamper = fn(&Path, &[String]) -> String;

/// Each tampering on a copy of shard 1 (samples 1 and 3): its name, the change, whether the
/// checksum is recomputed after it, and what the merge's error says.
fn tamperings() -> [(&'static str, Tamper, bool, &'static str); 7] {
    [
        // A factor changed, checksum left: the file no longer matches.
        (
            "factor",
            |_, l| {
                let mut l = l.to_vec();
                l[1] = l[1].replacen(",", ",9", 2);
                l.join("\n") + "\n"
            },
            false,
            "samples.csv: changed since the sweep wrote it",
        ),
        // The same with the checksum recomputed: the parameters are not the plan's.
        (
            "factor-resealed",
            |_, l| {
                let mut f: Vec<String> = l[1].split(',').map(str::to_string).collect();
                f[1] = "1.1".into();
                let mut l = l.to_vec();
                l[1] = f.join(",");
                l.join("\n") + "\n"
            },
            true,
            "are not the plan's",
        ),
        // An extra sample beyond the plan.
        (
            "extra",
            |_, l| {
                let mut l = l.to_vec();
                let mut f: Vec<String> = l[1].split(',').map(str::to_string).collect();
                f[0] = "9".into();
                l.push(f.join(","));
                l.join("\n") + "\n"
            },
            true,
            "sample 9 is not in the plan (5 samples)",
        ),
        // A sample of the other shard.
        (
            "other-shard",
            |_, l| {
                let mut l = l.to_vec();
                let mut f: Vec<String> = l[1].split(',').map(str::to_string).collect();
                f[0] = "2".into();
                l.push(f.join(","));
                l.join("\n") + "\n"
            },
            true,
            "sample 2 is not in shard 1/2",
        ),
        // A row twice.
        (
            "duplicate",
            |_, l| {
                let mut l = l.to_vec();
                l.push(l[1].clone());
                l.join("\n") + "\n"
            },
            true,
            "sample 1 appears twice",
        ),
        // A row missing.
        (
            "missing",
            |_, l| {
                let mut l = l.to_vec();
                l.remove(2);
                l.join("\n") + "\n"
            },
            true,
            "1 of the 2 samples of shard 1/2 missing",
        ),
        // Garbage in place of the series (samples.csv untouched; this case edits series.csv).
        (
            "series",
            |_, _| "garbage".into(),
            false,
            "series.csv: changed since the sweep wrote it",
        ),
    ]
}

/// The lines of file `p`.
fn lines(p: &Path) -> Vec<String> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn sweep_merge_refuses_tampered_extra_missing_and_duplicated_samples_naming_the_file() {
    // `sweep` takes a scenario file and no `--set`: a copy with the ideal actuator.
    let sc = scenario_with(
        "paper-lqg.toml",
        "model = \"bldc\"",
        "model = \"ideal\"",
        "sweep-tamper",
    );
    let sc = sc.to_str().unwrap();
    let dir = temp_dir("sweep-tamper");
    let s0 = dir.join("s0");
    let s1 = dir.join("s1");
    for (out, shard) in [(&s0, "0/2"), (&s1, "1/2")] {
        let (code, _, err) = run_strings(&mc_args(sc, out, "5", Some(shard)));
        assert_eq!(code, 0, "{err}");
    }
    let merge = |a: &Path, b: &Path| {
        run(&[
            "sweep-merge",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--out",
            dir.join("m").to_str().unwrap(),
        ])
    };
    let (code, _, err) = merge(&s0, &s1);
    assert_eq!(code, 0, "{err}");
    let good = std::fs::read(dir.join("m/samples.csv")).unwrap();
    let cases = tamperings();
    for (name, change, resealed, says) in cases {
        let t = dir.join(format!("t-{name}"));
        copy_dir(&s1, &t);
        let file = if name == "series" {
            "series.csv"
        } else {
            "samples.csv"
        };
        let text = change(&t, &lines(&t.join(file)));
        std::fs::write(t.join(file), text).unwrap();
        if resealed {
            reseal(&t, file);
        }
        let (code, _, err) = merge(&s0, &t);
        assert_eq!(code, 2, "{name}: {err}");
        assert!(
            err.contains(t.to_str().unwrap()) && err.contains(says),
            "{name}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
    // One shard given twice; the refused merges left the earlier merged files as they were.
    let (code, _, err) = merge(&s1, &s1);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("are both shard 1/2"), "{err}");
    assert!(std::fs::read(dir.join("m/samples.csv")).unwrap() == good);
}
