//! FMI, both directions, checked with clients tiltsim did not write.
//!
//! * Export: FMPy validates tiltsim's FMUs (their ModelStructure declares every output free of
//!   direct feedthrough), and FMPy's own co-simulation of each, fed the
//!   inputs a participant received in a recorded run, gives that run's outputs bit for bit
//!   (the same model code runs the same IEEE arithmetic in the same order).
//! * Import: an FMU built by pythonfmu (FMI 2.0, equations in Python) plays the controller;
//!   every recorded command equals its equations applied to the recorded (delayed) inputs.
//! * Round trip: tiltsim's own FMUs in place of all three participants give a byte-identical
//!   `timeseries.csv`, over IPC and in-process.
//! * Bad FMUs and bad mappings are refused with exit 2 and a message naming the field; an FMU
//!   whose step fails or whose process is killed is a named participant failure.
//!
//! The FMI tools come from PyPI in `target/fmi-venv` (made by `scripts/fmi-venv.sh` on first
//! use; a failure to make it fails these tests).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use tiltsim_suite::{fmi_python, fmi_tool, leftovers, prefix, root, run, scenario, temp_dir};
use tiltsim_suite::{summary, Series, Tiltsim};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// `tiltsim export-fmu ROLE SCENARIO --out DIR/NAME` (FMI 3.0).
fn export(role: &str, scenario: &Path, out: &Path) -> PathBuf {
    export_version(role, scenario, out, "3")
}

/// `tiltsim export-fmu ROLE SCENARIO --out DIR/NAME --fmi-version V`.
fn export_version(role: &str, scenario: &Path, out: &Path, version: &str) -> PathBuf {
    let (code, _, err) = run(&[
        "export-fmu",
        role,
        s(scenario),
        "--out",
        s(out),
        "--fmi-version",
        version,
    ]);
    assert_eq!(code, 0, "export-fmu {role}: {err}");
    out.to_path_buf()
}

/// A scenario: the text of shipped scenario `base` renamed `name`, with `extra` appended,
/// written into `dir` (FMU paths in `extra` are relative to `dir`). A file rather than
/// `--set`: a scenario's FMU paths are read relative to the scenario file.
fn scenario_in(dir: &Path, base: &str, name: &str, extra: &str) -> PathBuf {
    let text = std::fs::read_to_string(scenario(base)).expect("scenario");
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with("name = ") {
            out.push_str(&format!("name = \"{name}\"\n"));
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    out.push('\n');
    out.push_str(extra);
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, out).expect("write scenario");
    p
}

/// Runs a scenario to completion; returns the run directory.
fn run_ok(sc: &Path, out: &Path, transport: &str, extra: &[&str]) -> PathBuf {
    Tiltsim::run(sc)
        .out(out)
        .transport(transport)
        .quiet()
        .args(extra)
        .success();
    out.to_path_buf()
}

/// The pythonfmu FMU of `tests/outside/fmpy/tilt_pi.py`, built once per test process.
fn tilt_pi_fmu() -> PathBuf {
    static FMU: OnceLock<PathBuf> = OnceLock::new();
    FMU.get_or_init(|| {
        let dir = temp_dir("fmi-pythonfmu");
        let src = root().join("tests/outside/fmpy/tilt_pi.py");
        let (code, out, err) = fmi_tool("pythonfmu", &["build", "-f", s(&src), "-d", s(&dir)]);
        assert_eq!(code, 0, "pythonfmu build: {out}{err}");
        let fmu = dir.join("TiltPi.fmu");
        assert!(fmu.is_file(), "pythonfmu wrote no {}", fmu.display());
        fmu
    })
    .clone()
}

/// `[participants.controller]` with the pythonfmu FMU copied into `dir`.
fn tilt_pi_table(dir: &Path, parameters: &str) -> String {
    std::fs::copy(tilt_pi_fmu(), dir.join("TiltPi.fmu")).expect("copy FMU");
    format!(
        "[participants.controller]\n\
         fmu = \"TiltPi.fmu\"\n\
         inputs = {{ theta_v_meas = \"theta_meas\" }}\n\
         outputs = {{ delta_a_cmd = \"u\" }}\n\
         parameters = {{ {parameters} }}\n\
         preload = [\"libpython3.11.so.1.0\"]\n"
    )
}

#[test]
fn fmpy_validates_the_exported_fmus_and_its_cosimulation_reproduces_a_recorded_run() {
    let _ = fmi_python();
    let dir = temp_dir("fmi-fmpy");
    // paper-mpc: the controller's QP every 50 ms, the actuator's switched electrics at 1 µs.
    let sc = scenario("paper-mpc.toml");
    let rec = run_ok(
        &sc,
        &dir.join("run"),
        "ipc",
        &["--record", "--duration", "1"],
    );
    let check = root().join("tests/outside/fmpy/fmpy_check.py");
    // (role, requests in 1 s, recorded fields compared, FMU outputs). The plant's 39 outputs
    // are its 16 recorded ones and the whole car's 23 `car` values, which `run.mcap` does not
    // record (zero for this half vehicle).
    let roles = [
        ("controller", 20, 4, 5),
        ("actuator", 1000, 10, 10),
        ("plant", 1000, 16, 39),
    ];
    let mcap = rec.join("run.mcap");
    // FMI 3.0 (the default) and FMI 2.0 exports of each participant.
    for version in ["3", "2"] {
        for (role, requests, fields, outputs) in roles {
            let what = format!("{role} (FMI {version})");
            let fmu = export_version(
                role,
                &sc,
                &dir.join(format!("{role}-{version}.fmu")),
                version,
            );
            let (code, out, err) = fmi_tool("python", &[s(&check), s(&fmu), s(&mcap), role]);
            assert_eq!(code, 0, "fmpy_check {what}: {err}");
            let r: serde_json::Value = serde_json::from_str(out.trim()).expect("JSON");
            assert_eq!(
                r["problems"],
                serde_json::json!([]),
                "{what}: FMPy validation"
            );
            // Every output in ModelStructure, each declared without direct feedthrough
            // (dependencies=""): the library's outputs change only in a step.
            let deps = r["dependencies"].as_object().expect("dependencies");
            assert_eq!(deps.len(), outputs, "{what}: outputs in ModelStructure");
            for (name, d) in deps {
                assert_eq!(
                    d,
                    &serde_json::json!([]),
                    "{what}: dependencies of `{name}`"
                );
            }
            assert_eq!(r["requests"], requests, "{what}: recorded requests");
            assert_eq!(r["steps"], requests, "{what}: FMPy's communication steps");
            // The plant's and the actuator's outputs at t = 0 are compared too.
            let outputs_compared = if role == "controller" {
                requests
            } else {
                requests + 1
            };
            assert_eq!(
                r["compared"],
                outputs_compared * fields,
                "{what}: values compared"
            );
            assert_eq!(
                r["mismatches"], 0,
                "{what}: FMPy's outputs differ from the run's: first {}, largest {}",
                r["first"], r["largest"]
            );
        }
    }
}

#[test]
fn a_pythonfmu_controller_plays_the_controller_and_its_commands_follow_its_equations() {
    let dir = temp_dir("fmi-import");
    // The measurement reaches the FMU 5 ticks late: its recorded inputs must be the plant's
    // measurement delayed exactly so, and its commands its equations of those inputs.
    let extra = format!(
        "{}\n[links.measurement]\ndelay_ticks = 5\n",
        tilt_pi_table(&dir, "k_p = 12.0")
    );
    let sc = scenario_in(&dir, "paper-pi.toml", "tilt-pi-fmu", &extra);
    let ipc = run_ok(&sc, &dir.join("ipc"), "ipc", &["--duration", "2"]);
    let inp = run_ok(&sc, &dir.join("inp"), "in-process", &["--duration", "2"]);
    let a = std::fs::read(ipc.join("timeseries.csv")).expect("csv");
    let b = std::fs::read(inp.join("timeseries.csv")).expect("csv");
    assert!(
        a == b,
        "the FMU participant gives different rows over IPC and in-process"
    );

    let t = Series::read(&ipc.join("timeseries.csv"));
    let (theta, rx, cmd) = (
        t.col("theta_v_meas"),
        t.col("rx_measurement"),
        t.col("delta_a_cmd"),
    );
    assert_eq!(cmd.len(), 2001);
    // Row k's theta_v_meas is the plant's output at k ms (after tick k − 1); the controller in
    // tick k − 1 (row k) is given the output at k − 1 ms, here 5 ticks later: theta_v_meas[k - 6].
    // Before the first delayed sample arrives it holds the first (the output at t₀).
    for k in 6..rx.len() {
        assert_eq!(
            rx[k].to_bits(),
            theta[k - 6].to_bits(),
            "measurement delay at row {k}"
        );
    }
    // tilt_pi.py with k_p = 12 (set by the scenario), k_i = 5, u_max = 0.0610865238198, h = 1 ms.
    let (kp, ki, umax, h) = (12.0f64, 5.0f64, 0.0610865238198f64, 1e-3f64);
    let mut integral = 0.0f64;
    let mut saturated = 0;
    // Row 0 is the start time: the FMU's initial output, no step taken.
    assert_eq!(cmd[0], 0.0);
    for k in 1..cmd.len() {
        let e = -rx[k];
        integral += e * h;
        let u = (kp * e + ki * integral).clamp(-umax, umax);
        saturated += usize::from(u.abs() == umax);
        assert_eq!(
            u.to_bits(),
            cmd[k].to_bits(),
            "row {k}: command {} vs equations {u}",
            cmd[k]
        );
    }
    // The body leans in the curve: the command is not a trivial zero.
    let peak = cmd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(peak > 0.01, "peak command {peak} rad");
    let _ = saturated;
}

#[test]
fn tiltsims_own_fmus_in_place_of_every_participant_give_the_native_rows_byte_for_byte() {
    let dir = temp_dir("fmi-round-trip");
    let base = scenario("paper-mpc.toml");
    // FMI 3.0 and FMI 2.0 exports, each imported through tiltsim's binding of that version.
    for version in ["3", "2"] {
        for role in ["plant", "actuator", "controller"] {
            export_version(
                role,
                &base,
                &dir.join(format!("{role}-{version}.fmu")),
                version,
            );
        }
        let extra = format!(
            "[participants.plant]\nfmu = \"plant-{version}.fmu\"\n\
             [participants.actuator]\nfmu = \"actuator-{version}.fmu\"\n\
             [participants.controller]\nfmu = \"controller-{version}.fmu\"\n"
        );
        let fmus = scenario_in(&dir, "paper-mpc.toml", "paper-mpc", &extra);
        for transport in ["ipc", "in-process"] {
            let native = dir.join(format!("native-{transport}"));
            if !native.exists() {
                run_ok(&base, &native, transport, &["--duration", "2"]);
            }
            let fmu = run_ok(
                &fmus,
                &dir.join(format!("fmu-{version}-{transport}")),
                transport,
                &["--duration", "2"],
            );
            let a = std::fs::read(native.join("timeseries.csv")).expect("csv");
            let b = std::fs::read(fmu.join("timeseries.csv")).expect("csv");
            assert!(
                a.len() > 100_000,
                "{transport}: a short series ({} bytes)",
                a.len()
            );
            assert!(
                a == b,
                "FMI {version}, {transport}: the FMUs' timeseries.csv differs from the native run's"
            );
        }
    }
}

/// Runs `sc` and expects exit 2 with every string of `says` in the message.
fn refused(sc: &Path, says: &[&str]) {
    let err = Tiltsim::run(sc)
        .out(sc.with_extension("out"))
        .quiet()
        .failure(2);
    for w in says {
        assert!(err.contains(w), "{}: `{w}` not in: {err}", sc.display());
    }
    assert!(!err.contains("panicked"), "{err}");
}

/// A copy of FMU `src` at `dst`, each archive entry `i` (its bytes `data`) passed through the
/// Python statements `code` (Python's zipfile).
fn rewrite_fmu(src: &Path, dst: &Path, code: &str) {
    let script = format!(
        "import zipfile\n\
         src = zipfile.ZipFile({src:?})\n\
         dst = zipfile.ZipFile({dst:?}, 'w')\n\
         for i in src.infolist():\n\
         \x20   data = src.read(i)\n\
         {code}\n\
         dst.close()\n",
        src = s(src),
        dst = s(dst),
    );
    let (c, _, err) = fmi_tool("python", &["-c", &script]);
    assert_eq!(c, 0, "{err}");
}

/// A refused mapping: (case, the text of the scenario's table replaced, its replacement, what
/// the error says).
type BadMapping = (
    &'static str,
    &'static str,
    &'static str,
    &'static [&'static str],
);

/// Mappings the FMU refuses: a variable it lacks, the wrong causality, the wrong type, a field
/// the role does not have, a parameter it lacks.
fn bad_mappings() -> [BadMapping; 5] {
    [
        (
            "no-var",
            "outputs = { delta_a_cmd = \"u\" }",
            "outputs = { delta_a_cmd = \"nope\" }",
            &[
                "participants.controller.outputs.delta_a_cmd",
                "has no `nope`",
                "its outputs: u, integral",
            ],
        ),
        (
            "causality",
            "outputs = { delta_a_cmd = \"u\" }",
            "outputs = { delta_a_cmd = \"theta_meas\" }",
            &[
                "participants.controller.outputs.delta_a_cmd",
                "causality `output`",
                "`theta_meas` is `input`",
            ],
        ),
        (
            "type",
            "outputs = { delta_a_cmd = \"u\" }",
            "outputs = { delta_a_cmd = \"u\", solver_status = \"integral\" }",
            &[
                "participants.controller.outputs.solver_status",
                "an integer",
                "is a Real",
            ],
        ),
        (
            "field",
            "inputs = { theta_v_meas = \"theta_meas\" }",
            "inputs = { theta = \"theta_meas\" }",
            &["participants.controller.inputs.theta", "t, s, theta_v_meas"],
        ),
        (
            "param",
            "k_p = 12.0",
            "k_q = 12.0",
            &[
                "participants.controller.parameters.k_q",
                "has no `k_q`",
                "k_p",
            ],
        ),
    ]
}

#[test]
fn bad_fmus_and_bad_mappings_are_refused_with_exit_2_naming_the_field() {
    let dir = temp_dir("fmi-bad");
    let exported = export(
        "controller",
        &scenario("paper-pi.toml"),
        &dir.join("pi.fmu"),
    );
    let table = tilt_pi_table(&dir, "k_p = 12.0");
    let case = |name: &str, extra: &str| scenario_in(&dir, "paper-pi.toml", name, extra);

    // Not an FMU at all.
    std::fs::write(dir.join("text.fmu"), "not a zip").expect("write");
    refused(
        &case("not-zip", "[participants.controller]\nfmu = \"text.fmu\"\n"),
        &["participants.controller.fmu", "not a zip archive"],
    );
    // No library for this platform, and a model-exchange-only FMU: rewritten copies of an
    // exported FMU (Python's zipfile).
    rewrite_fmu(
        &exported,
        &dir.join("nolib.fmu"),
        "    if not i.filename.startswith('binaries/'): dst.writestr(i, data)",
    );
    refused(
        &case("no-lib", "[participants.controller]\nfmu = \"nolib.fmu\"\n"),
        &[
            "participants.controller.fmu",
            "binaries/x86_64-linux/tiltsim_controller.so",
            "missing",
        ],
    );
    rewrite_fmu(
        &exported,
        &dir.join("me.fmu"),
        "    if i.filename == 'modelDescription.xml': data = data.replace(b'<CoSimulation ', b'<ModelExchange ')\n    dst.writestr(i, data)",
    );
    refused(
        &case("me-only", "[participants.controller]\nfmu = \"me.fmu\"\n"),
        &["participants.controller.fmu", "model exchange only"],
    );
    // Mappings: a variable the FMU lacks, the wrong causality, the wrong type, a field the
    // role does not have, a parameter the FMU lacks.
    let cases = bad_mappings();
    for (name, from, to, says) in cases {
        assert!(table.contains(from), "{name}");
        refused(&case(name, &table.replace(from, to)), says);
    }
    // A step the FMU cannot take: the exported plant steps with a fixed 1 ms; a 0.5 ms run
    // would need half steps.
    export("plant", &scenario("paper-pi.toml"), &dir.join("plant.fmu"));
    let sc = case("half-step", "[participants.plant]\nfmu = \"plant.fmu\"\n");
    let text = std::fs::read_to_string(&sc).expect("read").replacen(
        "[actuator]",
        "[run]\ndt_s = 0.0005\n\n[actuator]",
        1,
    );
    std::fs::write(&sc, text).expect("write");
    refused(
        &sc,
        &[
            "participants.plant.fmu",
            "fixed 0.001 s",
            "0.0005 s is not a whole multiple",
        ],
    );
}

/// A run of scenario `sc` whose FMU fails its step at 0.5 s, on `transport`: the failure names
/// the participant and the FMU, and the rows before it are kept, complete.
fn a_failing_step_is_named(dir: &Path, sc: &Path, transport: &str) {
    let pfx = prefix(&format!("fmi_fail_{}", transport.replace('-', "_")));
    let out = dir.join(transport);
    let err = Tiltsim::run(sc)
        .out(&out)
        .transport(transport)
        .duration(2)
        .ipc_prefix(&pfx)
        .failure(1);
    assert!(err.contains("participant controller"), "{transport}: {err}");
    assert!(
        err.contains("TiltPi.fmu") && err.contains("fmi2DoStep returned"),
        "{transport}: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // The rows before the failing step are kept, complete.
    let sum = summary(&out);
    assert_eq!(sum["steps_completed"], 500, "{transport}");
    assert_eq!(
        Series::read(&out.join("timeseries.csv")).rows.len(),
        501,
        "{transport}"
    );
    assert!(
        leftovers(&pfx).is_empty(),
        "{transport}: {:?}",
        leftovers(&pfx)
    );
}

/// The FMUs unpacked in the temporary directory by processes that no longer exist.
fn unpacked_fmus_of_dead_processes() -> Vec<String> {
    std::fs::read_dir(std::env::temp_dir())
        .expect("temp dir")
        .flatten()
        .filter_map(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            let pid: u32 = n
                .strip_prefix("tiltsim-fmu-")?
                .split('-')
                .next()?
                .parse()
                .ok()?;
            (!Path::new(&format!("/proc/{pid}")).exists()).then_some(n)
        })
        .collect()
}

#[test]
fn an_fmu_whose_step_fails_or_whose_process_is_killed_is_a_named_participant_failure() {
    let dir = temp_dir("fmi-failure");
    // tilt_pi.py fails every step from 0.5 s on.
    let sc = scenario_in(
        &dir,
        "paper-pi.toml",
        "failing-fmu",
        &tilt_pi_table(&dir, "k_p = 12.0, fail_at = 0.5"),
    );
    for transport in ["ipc", "in-process"] {
        a_failing_step_is_named(&dir, &sc, transport);
    }

    // A kill of the FMU's process at 8 s: detected, named and degraded exactly as for the
    // native controller; every row the same.
    let base = scenario("fault-controller-killed.toml");
    export("controller", &base, &dir.join("killed.fmu"));
    let fmu = scenario_in(
        &dir,
        "fault-controller-killed.toml",
        "fault-controller-killed",
        "[participants.controller]\nfmu = \"killed.fmu\"\n",
    );
    let native = run_ok(
        &base,
        &dir.join("native-kill"),
        "ipc",
        &["--duration", "10"],
    );
    let with_fmu = run_ok(&fmu, &dir.join("fmu-kill"), "ipc", &["--duration", "10"]);
    for f in ["timeseries.csv", "events.csv"] {
        let a = std::fs::read(native.join(f)).expect(f);
        let b = std::fs::read(with_fmu.join(f)).expect(f);
        assert!(
            a == b,
            "{f} differs between the native and the FMU controller"
        );
    }
    let events = std::fs::read_to_string(with_fmu.join("events.csv")).expect("events");
    assert!(
        events
            .lines()
            .any(|l| l.contains("controller") && l.contains("kill")),
        "{events}"
    );
    assert_eq!(summary(&with_fmu)["status"], summary(&native)["status"]);
    // The killed process could not remove its unpacked FMU; the orchestrator did.
    let stale = unpacked_fmus_of_dead_processes();
    assert!(
        stale.is_empty(),
        "unpacked FMUs of dead processes left: {stale:?}"
    );
}

#[test]
fn the_shipped_fmu_example_runs_as_documented_and_its_parameter_takes_effect() {
    // The layout the example's comment describes: scenarios/ beside out/fmu/.
    let dir = temp_dir("fmi-example");
    std::fs::create_dir_all(dir.join("scenarios")).expect("mkdir");
    let text = std::fs::read_to_string(scenario("fmu-controller.toml")).expect("example");
    let example = dir.join("scenarios/fmu-controller.toml");
    std::fs::write(&example, &text).expect("write");
    export(
        "controller",
        &scenario("pi-drive.toml"),
        &dir.join("out/fmu/pi-drive-controller.fmu"),
    );
    let with_fmu = run_ok(&example, &dir.join("fmu"), "ipc", &["--duration", "2"]);
    // The same scenario with the native controller and kp = 0.45 in its own settings.
    let start = text.find("[participants.controller]").expect("table");
    let end = text.find("[links.measurement]").expect("links");
    assert!(text[..start].contains("\nkp = 0.5708\n"));
    let native_text = format!(
        "{}{}",
        text[..start].replace("\nkp = 0.5708\n", "\nkp = 0.45\n"),
        &text[end..]
    );
    // Without its `[participants.controller]` table, which `--set` cannot remove.
    let native_sc = dir.join("native.toml");
    std::fs::write(&native_sc, native_text).expect("write");
    let native = run_ok(&native_sc, &dir.join("native"), "ipc", &["--duration", "2"]);
    let a = std::fs::read(native.join("timeseries.csv")).expect("csv");
    let b = std::fs::read(with_fmu.join("timeseries.csv")).expect("csv");
    assert!(
        a == b,
        "the example's FMU run differs from the native run with kp = 0.45"
    );
    // And kp = 0.45 is not the exported scenario's 0.5708: the parameter changed the result.
    let other = run_ok(
        &scenario("pi-drive.toml"),
        &dir.join("drive"),
        "ipc",
        &[
            "--duration",
            "2",
            "--set",
            "links.measurement.delay_ticks=10",
        ],
    );
    let c = std::fs::read(other.join("timeseries.csv")).expect("csv");
    assert!(a != c, "kp = 0.45 gave the same rows as kp = 0.5708");
}

#[test]
fn a_recorded_run_with_an_fmu_replays_the_fmu_itself() {
    let dir = temp_dir("fmi-replay");
    let sc = scenario_in(
        &dir,
        "paper-pi.toml",
        "tilt-pi-recorded",
        &tilt_pi_table(&dir, "k_p = 12.0"),
    );
    let rec = run_ok(
        &sc,
        &dir.join("run"),
        "ipc",
        &["--record", "--duration", "1"],
    );
    for transport in ["in-process", "ipc"] {
        let out = dir.join(format!("replay-{transport}"));
        let (code, stdout, err) = run(&[
            "replay",
            s(&rec),
            "--participant",
            "controller",
            "--transport",
            transport,
            "--out",
            s(&out),
        ]);
        assert_eq!(code, 0, "{transport}: {err}");
        // tilt_pi.py's commands, not the native PI's: every output identical.
        assert!(
            stdout.contains("every output identical"),
            "{transport}: {stdout}"
        );
    }
}

#[test]
fn an_fmu_description_lacking_what_tiltsim_relies_on_is_named_in_a_warning() {
    let dir = temp_dir("fmi-lacking");
    let pi = scenario("paper-pi.toml");
    let whole = export_version("plant", &pi, &dir.join("whole.fmu"), "2");
    // The same FMU without <ModelStructure> and <DefaultExperiment> (Python's zipfile and re).
    rewrite_fmu(
        &whole,
        &dir.join("bare.fmu"),
        "    if i.filename == 'modelDescription.xml':\n\
         \x20       import re\n\
         \x20       data = re.sub(rb'<ModelStructure>.*</ModelStructure>', b'', data, flags=re.S)\n\
         \x20       data = re.sub(rb'<DefaultExperiment[^>]*/>', b'', data)\n\
         \x20   dst.writestr(i, data)",
    );
    let runs = |name: &str, fmu: &str| {
        let sc = scenario_in(
            &dir,
            "paper-pi.toml",
            name,
            &format!("[participants.plant]\nfmu = \"{fmu}\"\n"),
        );
        Tiltsim::run(&sc)
            .out(dir.join(name))
            .transport_in_process()
            .duration(0.2)
            .result()
    };
    let (code, _, err) = runs("bare", "bare.fmu");
    assert_eq!(code, 0, "{err}");
    for says in [
        "participants.plant.fmu",
        "bare.fmu",
        "no <ModelStructure>",
        "no <DefaultExperiment>",
        "every 0.001 s",
    ] {
        assert!(err.contains(says), "`{says}` not in: {err}");
    }
    // The FMU as exported: nothing to say.
    let (code, _, err) = runs("whole", "whole.fmu");
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("participants.plant.fmu"), "{err}");

    // A step it declares it cannot take: an FMI 2.0 controller that steps with its period only
    // (0.05 s, canHandleVariableCommunicationStepSize=false) in a run that steps it every 0.02 s.
    let mpc = scenario("paper-mpc.toml");
    let (code, _, err) = run(&[
        "export-fmu",
        "controller",
        s(&mpc),
        "--out",
        s(&dir.join("period.fmu")),
        "--fmi-version",
        "2",
        "--steps",
        "period",
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&mpc).expect("scenario");
    assert!(text.contains("period_s = 0.05"), "paper-mpc's period");
    let sc = dir.join("fast.toml");
    // A file beside period.fmu: the FMU's path is read relative to the scenario file.
    std::fs::write(
        &sc,
        format!(
            "{}\n[participants.controller]\nfmu = \"period.fmu\"\n",
            text.replace("period_s = 0.05", "period_s = 0.02").replacen(
                "name = \"paper-mpc\"",
                "name = \"fast\"",
                1
            )
        ),
    )
    .expect("write");
    let (code, _, err) = Tiltsim::run(&sc).out(dir.join("fast")).result();
    assert!(
        err.contains("participants.controller.fmu")
            && err.contains("stepSize=\"0.05\"")
            && err.contains("period 0.02 s is not a whole multiple"),
        "{err}"
    );
    // And it did refuse: the run fails naming the step.
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("fmi2DoStep"), "{err}");
}
