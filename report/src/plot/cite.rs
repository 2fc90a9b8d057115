//! Which of the paper's figures a chart can be set beside. Only a run of the paper's own set-up
//! shows what the paper's figure shows: its curve at 162 km/h (without or with its ±0.6°
//! random cant), its vehicle, and the passive vehicle or one of its controllers as it tunes
//! them. A chart names such a figure in its caption ("cf. the paper's Fig. 8b"), never in its
//! title.

use controller_proc::Mode;
use tiltsim_scenario::scenario::Scenario;
use vehicle_model::{IrregularityModel, IrregularityParams, TrackParams, VehicleParams};

/// The paper's tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PaperTrack {
    /// The deterministic curve (Figs 8-18).
    Deterministic,
    /// The same curve with ±0.6° of random cant (Figs 19-20).
    Stochastic,
}

/// A quantity drawn over time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Passenger lateral acceleration.
    LateralAcceleration,
    /// Carbody roll.
    Roll,
    /// Anti-roll-bar angle.
    BarAngle,
    /// Motor torque.
    MotorTorque,
    /// Motor current.
    MotorCurrent,
}

/// The paper's track `s` runs on with the paper's vehicle and controller; `None` for any other
/// set-up (another track, speed or vehicle, our own controller tuning or preview).
pub fn paper_setup(s: &Scenario) -> Option<PaperTrack> {
    let geometry = TrackParams {
        irregularity: IrregularityParams::default(),
        ..s.track.clone()
    };
    if geometry != TrackParams::default()
        || s.vehicle != VehicleParams::default()
        || s.design_vehicle.is_some()
    {
        return None;
    }
    let c = &s.controller;
    let papers_controller = match c.mode {
        Mode::Passive | Mode::Lqg => true,
        Mode::Pi => c.pi == controller_proc::PiGains::default(),
        Mode::Mpc => !c.mpc.preview,
    };
    let i = &s.track.irregularity;
    match i.model {
        _ if !papers_controller => None,
        IrregularityModel::Knots if i.amplitude_deg == 0.0 => Some(PaperTrack::Deterministic),
        IrregularityModel::Knots if (i.amplitude_deg - 0.6).abs() < 1e-9 => {
            Some(PaperTrack::Stochastic)
        }
        _ => None,
    }
}

/// The paper's figure that shows `q` of the one run `s` (`None`: none does).
pub fn run_figure(s: &Scenario, q: Quantity) -> Option<&'static str> {
    let passive = s.controller.mode == Mode::Passive;
    match (paper_setup(s)?, q) {
        (PaperTrack::Deterministic, Quantity::LateralAcceleration) if passive => Some("Fig. 8b"),
        (PaperTrack::Deterministic, Quantity::Roll) if passive => Some("Fig. 8a"),
        (PaperTrack::Deterministic, _) if passive => None,
        (PaperTrack::Deterministic, Quantity::LateralAcceleration) => Some("Figs 14-15"),
        (PaperTrack::Deterministic, Quantity::Roll) => Some("Figs 12-13, 16"),
        (PaperTrack::Deterministic, Quantity::BarAngle) => Some("Fig. 17"),
        (PaperTrack::Deterministic, Quantity::MotorTorque) => Some("Fig. 18, upper panel"),
        (PaperTrack::Deterministic, Quantity::MotorCurrent) => Some("Fig. 18, lower panel"),
        _ => compare_figure(s, q),
    }
}

/// The paper's figure that shows `q` of several runs on one axis, for the run `s` among them.
pub fn compare_figure(s: &Scenario, q: Quantity) -> Option<&'static str> {
    match (paper_setup(s)?, q) {
        (PaperTrack::Deterministic, Quantity::LateralAcceleration) => Some("Figs 14-15"),
        (PaperTrack::Deterministic, Quantity::Roll) => Some("Fig. 16"),
        (PaperTrack::Deterministic, Quantity::BarAngle) => Some("Fig. 17"),
        (PaperTrack::Stochastic, Quantity::LateralAcceleration) => Some("Fig. 19"),
        (PaperTrack::Stochastic, Quantity::Roll) => Some("Fig. 20"),
        _ => None,
    }
}

/// The paper's robustness figure (Fig. 21: the LQG's lateral acceleration under ±22 % on
/// masses, inertias and suspension) for a Monte Carlo sweep of `base` with that `spread`.
pub fn robustness_figure(base: &Scenario, spread: f64) -> Option<&'static str> {
    let lqg = base.controller.mode == Mode::Lqg;
    let paper = paper_setup(base) == Some(PaperTrack::Deterministic);
    (lqg && paper && (spread - 0.22).abs() < 1e-9).then_some("Fig. 21")
}

/// A caption naming the paper's figures of the runs (name, figure): "cf. the paper's Fig. 16"
/// when every run has that one, "cf. the paper's Fig. 16 for a, b" when only some do, and
/// each figure with its runs when they differ; empty when no run has one.
pub fn caption(runs: &[(&str, Option<&'static str>)]) -> String {
    let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
    for (name, fig) in runs {
        let Some(fig) = fig else { continue };
        match groups.iter_mut().find(|(f, _)| f == fig) {
            Some((_, names)) => names.push(name),
            None => groups.push((fig, vec![name])),
        }
    }
    match groups.as_slice() {
        [] => String::new(),
        [(fig, names)] if names.len() == runs.len() => format!("cf. the paper's {fig}"),
        _ => {
            let parts: Vec<String> = groups
                .iter()
                .map(|(fig, names)| format!("{fig} for {}", names.join(", ")))
                .collect();
            format!("cf. the paper's {}", parts.join("; "))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario(file: &str) -> Scenario {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenarios")
            .join(file);
        Scenario::load(&path).unwrap_or_else(|e| panic!("{file}: {e}"))
    }

    #[test]
    fn only_the_papers_own_set_ups_name_its_figures() {
        use Quantity::*;
        let passive = scenario("paper-passive.toml");
        assert_eq!(run_figure(&passive, LateralAcceleration), Some("Fig. 8b"));
        assert_eq!(run_figure(&passive, Roll), Some("Fig. 8a"));
        let lqg = scenario("paper-lqg.toml");
        assert_eq!(run_figure(&lqg, BarAngle), Some("Fig. 17"));
        assert_eq!(compare_figure(&lqg, Roll), Some("Fig. 16"));
        assert_eq!(robustness_figure(&lqg, 0.22), Some("Fig. 21"));
        assert_eq!(robustness_figure(&lqg, 0.1), None);
        assert!(run_figure(&scenario("paper-pi.toml"), MotorTorque).is_some());
        let irregular = scenario("lqg-irregular.toml");
        assert_eq!(run_figure(&irregular, LateralAcceleration), Some("Fig. 19"));
        assert_eq!(run_figure(&irregular, BarAngle), None);
        // Our own tuning, preview, speed and track are in none of the paper's figures.
        for file in [
            "pi-drive.toml",
            "paper-mpc-preview.toml",
            "tilting-lqg.toml",
            "straight-lqg.toml",
        ] {
            let s = scenario(file);
            assert_eq!(paper_setup(&s), None, "{file}");
            assert_eq!(run_figure(&s, LateralAcceleration), None, "{file}");
        }
    }

    #[test]
    fn a_caption_names_the_runs_a_figure_holds_when_not_all() {
        assert_eq!(caption(&[("a", None)]), "");
        assert_eq!(
            caption(&[("a", Some("Fig. 16")), ("b", Some("Fig. 16"))]),
            "cf. the paper's Fig. 16"
        );
        assert_eq!(
            caption(&[("a", None), ("b", Some("Fig. 16")), ("c", Some("Fig. 16"))]),
            "cf. the paper's Fig. 16 for b, c"
        );
        assert_eq!(
            caption(&[("a", Some("Fig. 16")), ("b", Some("Fig. 20"))]),
            "cf. the paper's Fig. 16 for a; Fig. 20 for b"
        );
    }
}
