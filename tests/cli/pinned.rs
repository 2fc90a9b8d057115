//! Pinned outputs: a few shipped scenarios, over both transports and both master algorithms,
//! must give exactly the `timeseries.csv` and `events.csv` recorded in `tests/pinned.txt`
//! (SHA-256) and the P_CT recorded there (to the bit). A refactoring of the orchestrator must
//! leave these unchanged; a change to a model or to the output format changes them on purpose,
//! and then the file is rewritten with
//!
//! ```sh
//! TILTSIM_REPIN=1 cargo test --release -p tiltsim-suite --test pinned
//! ```
//!
//! and the diff of `tests/pinned.txt` goes into the commit that explains it. The scenarios
//! avoid dense matrix products at run time whose last bits could depend on the CPU's vector
//! units: the passive vehicle, the PI on the switched drive, link effects and a fault.

use std::collections::BTreeMap;
use std::path::PathBuf;

use sha2::{Digest, Sha256};
use tiltsim_suite::{prefix, root, scenario, summary, temp_dir, Tiltsim};

const PINS: [(&str, &str, &str); 5] = [
    ("paper-passive.toml", "in-process", "gauss-seidel"),
    ("paper-passive.toml", "ipc", "jacobi"),
    ("pi-drive.toml", "in-process", "gauss-seidel"),
    ("pi-drive.toml", "ipc", "gauss-seidel"),
    ("pi-drive.toml", "in-process", "jacobi"),
];

fn pin_file() -> PathBuf {
    root().join("tests").join("pinned.txt")
}

/// The SHA-256 of a table in the form the pins were taken in, where a whole float was written
/// without its `.0` (`3` for 3.0): each cell that is a whole number with `.0` loses it. The
/// values pinned are unchanged by that form; the `.0` itself is checked by the writer's tests.
fn sha(path: &std::path::Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let pinned_form: String = text
        .split_inclusive('\n')
        .map(|line| {
            let (body, end) = match line.strip_suffix('\n') {
                Some(b) => (b, "\n"),
                None => (line, ""),
            };
            let cells: Vec<&str> = body.split(',').map(without_point_zero).collect();
            cells.join(",") + end
        })
        .collect();
    Sha256::digest(pinned_form.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `3` for `3.0` and `-0` for `-0.0`; any other cell as it is.
fn without_point_zero(cell: &str) -> &str {
    match cell.strip_suffix(".0") {
        Some(int)
            if !int.is_empty()
                && int
                    .trim_start_matches('-')
                    .bytes()
                    .all(|b| b.is_ascii_digit()) =>
        {
            int
        }
        _ => cell,
    }
}

/// The scenario of link effects and a fault: pi-drive with a jittered, biased command and a
/// controller killed at 8 s with the degraded fallback.
fn faulted() -> PathBuf {
    // The kill is a `[[faults.schedule]]` entry, which `--set` cannot add: one file for all.
    let text = std::fs::read_to_string(scenario("pi-drive.toml")).unwrap()
        + "\n[links.actuator_command]\ndelay_ticks = 5\njitter = \"uniform\"\njitter_ticks = 3\nbias = 0.001\n\
           \n[faults]\non_failure = \"degrade\"\n\n[[faults.schedule]]\nparticipant = \"controller\"\naction = \"kill\"\nat_s = 8.0\n";
    let p = temp_dir("pinned-faulted-scenario").join("pi-drive-faulted.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn outputs(
    name: &str,
    file: &std::path::Path,
    transport: &str,
    master: &str,
) -> Vec<(String, String)> {
    let out = temp_dir(name).join("out");
    let pfx = prefix(name);
    Tiltsim::run(file)
        .out(&out)
        .transport(transport)
        .master(master)
        .ipc_prefix(&pfx)
        .quiet()
        .success();
    let s = summary(&out);
    let pct = s["comfort"]["p_ct_paper"]["standing_pct"].as_f64().unwrap();
    vec![
        ("timeseries.csv".into(), sha(&out.join("timeseries.csv"))),
        ("events.csv".into(), sha(&out.join("events.csv"))),
        (
            "p_ct_standing_bits".into(),
            format!("{:016x}", pct.to_bits()),
        ),
    ]
}

#[test]
fn pinned_scenarios_give_the_recorded_bytes_on_both_transports_and_masters() {
    let mut got = BTreeMap::new();
    let mut cases: Vec<(String, PathBuf, &str, &str)> = PINS
        .iter()
        .map(|(f, t, m)| (f.to_string(), scenario(f), *t, *m))
        .collect();
    let fp = faulted();
    cases.push((
        "pi-drive-faulted".into(),
        fp.clone(),
        "in-process",
        "gauss-seidel",
    ));
    cases.push(("pi-drive-faulted".into(), fp, "ipc", "gauss-seidel"));
    for (label, file, transport, master) in &cases {
        let name = format!(
            "pin-{}-{transport}-{master}",
            label.trim_end_matches(".toml")
        );
        for (what, value) in outputs(&name, file, transport, master) {
            got.insert(format!("{label} {transport} {master} {what}"), value);
        }
    }
    let text: String = got.iter().map(|(k, v)| format!("{k} {v}\n")).collect();
    if std::env::var_os("TILTSIM_REPIN").is_some() {
        std::fs::write(pin_file(), &text).unwrap();
        eprintln!("rewrote {}", pin_file().display());
        return;
    }
    let want = std::fs::read_to_string(pin_file()).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (create it with TILTSIM_REPIN=1)",
            pin_file().display()
        )
    });
    let want: BTreeMap<&str, &str> = want.lines().filter_map(|l| l.rsplit_once(' ')).collect();
    assert_eq!(
        want.len(),
        got.len(),
        "tests/pinned.txt holds other cases than this test runs"
    );
    let mut differ = Vec::new();
    for (k, v) in &got {
        if want.get(k.as_str()) != Some(&v.as_str()) {
            differ.push(k.clone());
        }
    }
    assert!(differ.is_empty(), "outputs changed: {differ:#?}");
}
