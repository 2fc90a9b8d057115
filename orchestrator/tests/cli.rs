//! The `tiltsim` command line: bad input gets a clear message and exit code 2, never a panic.

use std::process::Command;

fn tiltsim(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tiltsim"))
        .args(args)
        .output()
        .expect("run tiltsim");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn scenario_file(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tiltsim-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn shipped_scenarios_validate() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("scenarios");
    // Copies in the layout the FMU example documents: scenarios/ beside out/fmu/.
    let dir = std::env::temp_dir().join(format!("tiltsim-cli-shipped-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("scenarios")).unwrap();
    let mut copies = Vec::new();
    for e in std::fs::read_dir(root).unwrap() {
        let p = e.unwrap().path();
        let to = dir.join("scenarios").join(p.file_name().unwrap());
        std::fs::copy(&p, &to).unwrap();
        copies.push(to);
    }
    // Before its FMU is exported the example names what is missing.
    let example = dir.join("scenarios/fmu-controller.toml");
    let (code, _, err) = tiltsim(&["validate", example.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("participants.controller.fmu"), "{err}");
    assert!(err.contains("tiltsim export-fmu controller"), "{err}");
    let (code, _, err) = tiltsim(&[
        "export-fmu",
        "controller",
        dir.join("scenarios/pi-drive.toml").to_str().unwrap(),
        "--out",
        dir.join("out/fmu/pi-drive-controller.fmu")
            .to_str()
            .unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    for p in copies {
        let (code, out, err) = tiltsim(&["validate", p.to_str().unwrap()]);
        assert_eq!(code, 0, "{}: {err}", p.display());
        assert!(out.contains("valid"));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn malformed_scenarios_are_rejected_with_file_field_and_allowed_values() {
    let cases = [
        (
            "unknown.toml",
            "[vehicle]\nmass = 3\n",
            "unknown field `mass`",
        ),
        ("type.toml", "[track]\nspeed_kmh = \"fast\"\n", "speed_kmh"),
        (
            "range.toml",
            "[track]\nspeed_kmh = -10.0\n",
            "field `track.speed_kmh` = -10: allowed a number in (0, 400] km/h",
        ),
        (
            "enum.toml",
            "[run]\ntransport = \"carrier-pigeon\"\n",
            "carrier-pigeon",
        ),
        ("syntax.toml", "[run\n", "TOML parse error"),
    ];
    for (file, text, needle) in cases {
        let p = scenario_file(file, text);
        for cmd in ["validate", "run"] {
            let (code, _, err) = tiltsim(&[cmd, p.to_str().unwrap()]);
            assert_eq!(code, 2, "{cmd} {file}: {err}");
            assert!(
                err.contains(file) && err.contains(needle),
                "{cmd} {file}: {err}"
            );
            assert!(!err.contains("panicked"), "{err}");
        }
    }
    let (code, _, err) = tiltsim(&["validate", "/nonexistent/x.toml"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("/nonexistent/x.toml") && err.contains("cannot read"),
        "{err}"
    );
}

#[test]
fn bad_command_line_values_exit_2() {
    let p = scenario_file("ok.toml", "");
    let (code, _, err) = tiltsim(&[
        "run",
        p.to_str().unwrap(),
        "--duration=-1",
        "--transport",
        "in-process",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--duration") && err.contains("allowed a number in"),
        "{err}"
    );
    let (code, _, _) = tiltsim(&["run", p.to_str().unwrap(), "--transport", "smoke-signals"]);
    assert_eq!(code, 2);
}

#[test]
fn a_listing_piped_into_a_reader_that_stops_early_ends_quietly() {
    // `head` closes the pipe after one line; the plan has 20 000 more to write. The command
    // ends as any Unix filter does (SIGPIPE), never with a panic's message.
    let sc = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/paper-lqg.toml");
    let line = format!(
        "'{}' sweep '{}' --samples 20000 --plan-only | head -n 1",
        env!("CARGO_BIN_EXE_tiltsim"),
        sc.display()
    );
    let out = Command::new("sh").args(["-c", &line]).output().unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(stdout.starts_with("{\"sample\":0"), "{stdout}");
    assert!(stderr.is_empty(), "{stderr}");
}
