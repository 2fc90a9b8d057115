//! The library observed from outside its model: which outputs move when an input is set.

use std::path::{Path, PathBuf};

use cosim::msg::ScalarValue;
use cosim::Role;
use tiltsim_fmi::layout::{token, FmuConfig, Stepping};
use tiltsim_master::engine::Inits;
use tiltsim_scenario::scenario::Scenario;

use crate::{instantiate, Instance, State};

/// The shipped scenario `file`.
fn shipped(file: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(file);
    Scenario::load(&path).unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// An instance of `role` of the shipped scenario `file`, its resources written under `dir`.
fn instance(file: &str, role: Role, dir: &Path) -> Instance {
    instance_of(&shipped(file), file, role, dir)
}

/// An instance of `role` of scenario `s` (named `file` in its resources' directory), its
/// resources written under `dir`.
fn instance_of(s: &Scenario, file: &str, role: Role, dir: &Path) -> Instance {
    let inits = Inits::from(s);
    let settings = match role {
        Role::Plant => serde_json::to_value(&inits.plant),
        Role::Actuator => serde_json::to_value(&inits.actuator),
        Role::Controller => serde_json::to_value(&inits.controller),
    }
    .unwrap();
    let cfg = FmuConfig {
        role,
        dt_s: s.run.dt_s,
        stepping: Stepping::Tick,
        settings,
    };
    let res = dir.join(format!(
        "{}-{}",
        file.trim_end_matches(".toml"),
        role.name()
    ));
    std::fs::create_dir_all(&res).unwrap();
    let bytes = serde_json::to_vec(&cfg).unwrap();
    std::fs::write(res.join("tiltsim.json"), &bytes).unwrap();
    instantiate(
        role.name(),
        &token(&bytes),
        res.to_str().unwrap(),
        None,
        std::ptr::null_mut(),
    )
    .unwrap()
}

fn outputs(i: &mut Instance) -> Vec<u64> {
    (0..i.layout.outputs.len())
        .map(|k| match i.output(k).unwrap() {
            ScalarValue::F64(v) => v.to_bits(),
            ScalarValue::U32(v) => u64::from(v),
        })
        .collect()
}

/// A value of input `k` other than its present one.
fn other(v: ScalarValue, k: usize) -> ScalarValue {
    match v {
        ScalarValue::F64(x) => ScalarValue::F64(x + 0.01 * (k + 1) as f64),
        ScalarValue::U32(x) => ScalarValue::U32(x + 1),
    }
}

/// For each output, the inputs whose change moved it without a step, at the present
/// communication point; every input is put back afterwards.
fn observed(i: &mut Instance, deps: &mut [Vec<usize>]) {
    let before = outputs(i);
    for k in 0..i.inputs.len() {
        let old = i.inputs[k];
        i.inputs[k] = other(old, k);
        let after = outputs(i);
        i.inputs[k] = old;
        for (o, (a, b)) in before.iter().zip(&after).enumerate() {
            if a != b && !deps[o].contains(&k) {
                deps[o].push(k);
            }
        }
    }
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tiltsim-fmu-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_declared_direct_dependencies_are_those_observed_on_every_role() {
    let dir = scratch("feedthrough");
    for file in ["paper-mpc.toml", "paper-lqg.toml", "paper-pi.toml"] {
        for role in Role::ALL {
            let mut i = instance(file, role, &dir);
            let mut deps = vec![Vec::new(); i.layout.outputs.len()];
            i.state = State::Initialization;
            observed(&mut i, &mut deps);
            i.model().unwrap();
            i.state = State::Step;
            // Inputs that move the participant (a bar angle, a twist, a measurement on the
            // curve), then communication points of one tick, on and off the controller's
            // ticks, each probed.
            for (k, v) in i.inputs.iter_mut().enumerate() {
                *v = other(*v, k);
            }
            let mut at = 0.0f64;
            for tick in 0..120u64 {
                i.do_step(at, 1e-3).unwrap();
                at = cosim::time::tick_time(tick + 1, 1e-3);
                if tick % 7 == 0 || tick % 50 == 49 || tick % 50 == 0 {
                    observed(&mut i, &mut deps);
                }
            }
            for (o, d) in deps.iter().enumerate() {
                assert_eq!(
                    d.as_slice(),
                    i.layout.direct_inputs(o),
                    "{file}, {role}: output `{}`",
                    i.layout.outputs[o].name
                );
            }
            // The probe is not blind: a step with the changed inputs moved some output.
            let before = outputs(&mut i);
            for (k, v) in i.inputs.iter_mut().enumerate() {
                *v = other(*v, k);
            }
            let t = i.time();
            i.do_step(t, 0.05).unwrap();
            assert_ne!(before, outputs(&mut i), "{file}, {role}: no output moved");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The plant exported with `vehicle.model = "full"` steps the whole car, not the half vehicle:
/// after 1 s at rest on the straight before the curve (no bar angle, no irregularity) each of
/// its eight wheels carries an eighth of the car's weight, Q = M g / 8 with M the body's, the
/// two bogie frames' and the four wheelsets' masses, on the outputs `car[5j+3]`, `car[5j+4]`,
/// which the half vehicle's plant leaves at zero. Within 1e-6 of Q: the straight's rest is
/// the model's static solution (plant-proc's test finds it to rounding).
#[test]
fn an_exported_plant_of_the_whole_car_carries_the_cars_weight_on_its_wheels() {
    let dir = scratch("full-car");
    let mut s = shipped("paper-passive.toml");
    s.vehicle.model = vehicle_model::VehicleModel::Full;
    let p = vehicle_model::full_car::FullCarParams::from_half(&s.vehicle);
    let q0 = (p.m_c + 2.0 * p.m_b + 4.0 * p.m_w) * vehicle_model::G / 8.0;
    let half = shipped("paper-passive.toml");
    for (scenario, tag, full) in [(&s, "full", true), (&half, "half", false)] {
        let mut i = instance_of(scenario, tag, Role::Plant, &dir);
        i.state = State::Initialization;
        i.model().unwrap();
        i.state = State::Step;
        let mut at = 0.0f64;
        for tick in 0..1000u64 {
            i.do_step(at, 1e-3).unwrap();
            at = cosim::time::tick_time(tick + 1, 1e-3);
        }
        let names: Vec<String> = i.layout.outputs.iter().map(|o| o.name.clone()).collect();
        let value = |i: &mut Instance, name: &str| {
            let k = names
                .iter()
                .position(|n| n == name)
                .unwrap_or_else(|| panic!("{name}"));
            match i.output(k).unwrap() {
                ScalarValue::F64(v) => v,
                other => panic!("{name}: {other:?}"),
            }
        };
        for j in 0..4 {
            for side in [3, 4] {
                let q = value(&mut i, &format!("car[{}]", 5 * j + side));
                if full {
                    assert!(
                        (q - q0).abs() < 1e-6 * q0,
                        "wheelset {j}: Q {q} N, Q0 {q0} N"
                    );
                } else {
                    assert_eq!(q, 0.0, "the half vehicle has no wheelsets");
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
