use super::*;
use crate::description::{write_fmi2, write_fmi3, ExportInfo, ModelDescription};
use crate::layout::Layout;
use crate::units::{param_unit, UNIT_DEFS};

#[test]
fn every_parameter_is_listed_once_with_a_defined_unit_and_a_description() {
    let rows: Vec<&Row> = TABLES.iter().flat_map(|t| t.iter()).collect();
    for (i, (n, u, d)) in rows.iter().enumerate() {
        assert!(rows[..i].iter().all(|r| r.0 != *n), "{n} twice");
        assert!(!n.contains('['), "{n}: a name without indices");
        assert!(
            u.is_empty() || UNIT_DEFS.iter().any(|(m, _)| m == u),
            "{n}: unit {u} is not in UNIT_DEFS"
        );
        assert!(!d.trim().is_empty() && !d.ends_with('.'), "{n}: `{d}`");
    }
    for (i, (n, d)) in ELEMENTS.iter().enumerate() {
        assert!(ELEMENTS[..i].iter().all(|e| e.0 != *n), "{n} twice");
        assert!(row(n).is_some() && n.ends_with(']'), "{n}");
        assert!(!d.trim().is_empty() && !d.ends_with('.'), "{n}: `{d}`");
    }
    assert_eq!(
        param_description("controller.lqg.q_diag[1]"),
        Some("LQI weight Q_w on the carbody roll θ_v (eq 24)")
    );
    // An entry past those with a meaning of their own has the array's description.
    assert_eq!(
        param_description("controller.lqg.q_diag[12]"),
        param_description("controller.lqg.q_diag")
    );
    assert_eq!(param_description("vehicle.nothing"), None);
}

#[test]
fn parameters_are_written_with_their_description_and_unit_in_both_versions() {
    let settings = serde_json::json!({
        "vehicle": {"m_v": 19000.0, "h1": 0.9},
        "controller": {
            "mode": "lqg",
            "kalman": {"w_n": [2.1e-7, 2.23e-3], "v_n": 0.1, "disturbance_var": 0.05},
            "mpc": {"horizon_p": 5},
        },
        "seed": 7,
    });
    let layout = Layout::new(tiltsim_protocol::Role::Controller, &settings).unwrap();
    let info = ExportInfo {
        model_name: "m".into(),
        model_identifier: "tiltsim_controller".into(),
        token: "{t}".into(),
        description: "d".into(),
        step_s: 1e-3,
        variable_step: true,
        stop_s: 1.0,
    };
    for xml in [
        write_fmi3(&layout, &info),
        write_fmi2(&layout, &info).unwrap(),
    ] {
        let md = ModelDescription::parse(&xml).unwrap();
        for p in &layout.params {
            let v = md.var(&p.name).unwrap();
            assert_eq!(
                v.description.as_deref(),
                param_description(&p.name),
                "{}",
                p.name
            );
            let unit = param_unit(&p.name).filter(|u| !u.is_empty());
            assert_eq!(v.unit.as_deref(), unit, "{}", p.name);
        }
        let m_v = md.var("vehicle.m_v").unwrap();
        assert_eq!(m_v.description.as_deref(), Some("Half carbody mass m_v"));
        let w1 = md.var("controller.kalman.w_n[1]").unwrap();
        assert_eq!(
            w1.description.as_deref(),
            Some("Kalman process noise intensity W_n on the cant θ_o (eq 17)")
        );
        assert!(xml.contains(r#"<Unit name="rad2"><BaseUnit rad="2"/></Unit>"#));
    }
}
