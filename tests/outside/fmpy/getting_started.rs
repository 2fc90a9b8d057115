//! What a new user starts with, checked against FMPy: `tiltsim inspect` lists what FMPy's
//! reader of the model description finds in the same FMU.

use std::path::Path;

use tiltsim_suite::{fmi_tool, run, scenario, temp_dir};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn inspect_lists_what_fmpy_reads_from_the_same_fmu() {
    let dir = temp_dir("inspect");
    let sc = scenario("paper-mpc.toml");
    for (role, version) in [("controller", "3"), ("plant", "2")] {
        let fmu = dir.join(format!("{role}-{version}.fmu"));
        let (code, _, err) = run(&[
            "export-fmu",
            role,
            s(&sc),
            "--out",
            s(&fmu),
            "--fmi-version",
            version,
        ]);
        assert_eq!(code, 0, "{err}");
        let (code, out, err) = run(&["inspect", s(&fmu), "--json"]);
        assert_eq!(code, 0, "{err}");
        let ours: serde_json::Value = serde_json::from_str(&out).unwrap();
        // FMPy's own reader of the description: name, causality and unit of every variable.
        let script = format!(
            "import json\nfrom fmpy import read_model_description\nmd = read_model_description({:?})\nprint(json.dumps([[v.name, v.causality, v.unit, v.valueReference] for v in md.modelVariables]))",
            s(&fmu)
        );
        let (code, out, err) = fmi_tool("python", &["-c", &script]);
        assert_eq!(code, 0, "fmpy: {err}");
        let theirs: Vec<(String, String, Option<String>, u32)> =
            serde_json::from_str(&out).unwrap();
        let vars = ours["variables"].as_array().unwrap();
        assert_eq!(vars.len(), theirs.len(), "{role} FMI {version}");
        for (name, causality, unit, vr) in theirs {
            let v = vars
                .iter()
                .find(|v| v["name"] == name.as_str())
                .unwrap_or_else(|| panic!("{name} not listed"));
            assert_eq!(v["causality"], causality.as_str(), "{name}");
            assert_eq!(v["value_reference"], vr, "{name}");
            assert_eq!(v["unit"].as_str(), unit.as_deref(), "{name}");
        }
        let (code, table, _) = run(&["inspect", s(&fmu)]);
        assert_eq!(code, 0);
        assert!(table.contains(&format!("FMI {version}.0")), "{table}");
    }
    let (code, _, err) = run(&["inspect", s(&sc)]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("paper-mpc.toml") && err.contains("not an FMU"),
        "{err}"
    );
}
