//! `timing.csv` as the tests read it, and the checks every whole trace passes.

use std::collections::HashMap;
use std::path::Path;

/// One line of `timing.csv`.
#[derive(Debug, Clone)]
pub struct Step {
    pub role: String,
    pub step: i64,
    /// Producer step read, by producer name.
    pub from: HashMap<String, i64>,
    pub due: u64,
    pub read: u64,
    pub compute_end: u64,
    pub publish: u64,
}

/// The steps of the trace in `dir`, in the order of the file.
pub fn read_trace(dir: &Path) -> Vec<Step> {
    let text = std::fs::read_to_string(dir.join("timing.csv")).expect("timing.csv");
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("# tiltsim timing trace:"));
    let cols: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let at = |n: &str| c[cols.iter().position(|x| *x == n).unwrap()];
            let mut from = HashMap::new();
            for p in ["plant", "actuator", "controller"] {
                let v = at(&format!("from_{p}"));
                if !v.is_empty() {
                    from.insert(p.to_string(), v.parse().unwrap());
                }
            }
            Step {
                role: at("role").to_string(),
                step: at("step").parse().unwrap(),
                from,
                due: at("due_ns").parse().unwrap(),
                read: at("read_ns").parse().unwrap(),
                compute_end: at("compute_end_ns").parse().unwrap(),
                publish: at("publish_ns").parse().unwrap(),
            }
        })
        .collect()
}

/// Every step of every consumer is in the trace once, started no earlier than it was due, and
/// read only outputs that had been published before its read instant (causality of the relay:
/// a producer's output reaches the hub, then the consumer, after it was published).
pub fn check_trace(t: &[Step], steps: i64, controller_ticks: i64) {
    let mut by: HashMap<(String, i64), &Step> = HashMap::new();
    for x in t {
        assert!(
            by.insert((x.role.clone(), x.step), x).is_none(),
            "{} step {} twice",
            x.role,
            x.step
        );
        assert!(
            x.read >= x.due,
            "{} step {} read before it was due",
            x.role,
            x.step
        );
        assert!(x.read <= x.compute_end && x.compute_end <= x.publish);
    }
    for k in 0..steps {
        assert!(by.contains_key(&("plant".into(), k)));
        assert!(by.contains_key(&("actuator".into(), k)));
        if k % controller_ticks == 0 {
            assert!(by.contains_key(&("controller".into(), k)));
        }
    }
    for x in t {
        for (p, &q) in &x.from {
            if q >= 0 {
                let src = by[&(p.clone(), q)];
                assert!(
                    src.publish <= x.read,
                    "{} step {} read {p} step {q} before it was published",
                    x.role,
                    x.step
                );
            }
        }
    }
}
