//! `tiltsim falsify`: the admissible timing that hurts the ride most, found by a search guided
//! by the objective and replayable exactly.
//!
//! * [`bounds`]: the admissible timing of each link (a bounds file, or the envelope of
//!   recorded free runs' `timing.csv`);
//! * [`history`]: a timing history (each sample's delay, or its loss or stall), its
//!   projection onto the bounds, and the coordinates CMA-ES searches mapped to histories;
//! * [`timing`]: the trace (`timing.csv`) of a history, causal by construction, and the check
//!   of any trace against bounds;
//! * [`adversaries`]: the obvious adversaries, tried before the search and seeding it;
//! * [`mutation`]: the search's evolution of the histories themselves;
//! * [`objective`]: a summary metric to maximise, or requirements whose margin is minimised;
//! * [`requirement`]: requirements on comfort metrics, on validity, and on signals over time
//!   (a small signal temporal logic with its robustness as the margin);
//! * [`margin`]: each bound's share of the worst timing, and the timing margin of
//!   requirements (the largest scale of the bounds not falsified, by bisection);
//! * [`evidence`]: what the random sampling says about a requirement (a 95 % upper bound);
//! * [`cmaes`]: the search, CMA-ES (Hansen's tutorial);
//! * [`search`]: the evaluations (the in-process lock-step replay of each candidate trace, a
//!   generation in parallel), the search (adversaries, CMA-ES, evolution of the histories)
//!   against uniform random sampling with the same budget, resumable;
//! * [`outputs`]: the worst trace and its run directory, the progress table and figure, the
//!   result.

pub mod adversaries;
pub mod bounds;
pub mod cmaes;
pub mod evidence;
pub mod history;
mod kept;
pub mod margin;
pub mod mutation;
pub mod objective;
pub mod outputs;
pub mod requirement;
pub mod search;
pub mod shards;
pub mod timing;

pub use bounds::{Bounds, LinkBound};
pub use objective::Objective;
pub use outputs::{falsify, falsify_part, Outcome};
pub use search::{run, Exec, Falsified, Spec};

/// Makes `s` the system a search replays (lock-step, in process, as a timing replay) and
/// checks it (`file` names it in errors): valid, and without timing effects on its links, whose
/// place the searched timing takes.
pub fn prepare(
    s: &mut tiltsim_scenario::scenario::Scenario,
    file: &str,
) -> Result<(), FalsifyError> {
    tiltsim_runner::pipeline::as_timing_replay(s);
    s.run.transport = tiltsim_scenario::scenario::Transport::InProcess;
    let errors = s.validate();
    if !errors.is_empty() {
        let lines: Vec<String> = errors.iter().map(|e| format!("{file}: {e}")).collect();
        return Err(FalsifyError::Invalid(lines.join("\nerror: ")));
    }
    for (name, l) in tiltsim_scenario::links::LINK_NAMES
        .iter()
        .zip(s.links.all())
    {
        let timing = [
            ("delay_ticks", l.delay_ticks > 0),
            ("jitter", l.jitter != Default::default()),
            ("drop_probability", l.drop_probability > 0.0),
            ("drop_window", l.drop_window.is_some()),
        ];
        if let Some((field, _)) = timing.iter().find(|(_, set)| *set) {
            return Err(FalsifyError::Invalid(format!(
                "{file}: links.{name}.{field}: the search sets the links' timing; allowed: none of delay_ticks, jitter, drop_probability, drop_window"
            )));
        }
    }
    Ok(())
}

/// Why a search could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum FalsifyError {
    /// Bad input: the message names the file or flag, the field and what is allowed.
    #[error("{0}")]
    Invalid(String),
    /// A file could not be written or read.
    #[error("{0}")]
    Files(String),
    /// A run failed where it must not (the worst trace's replay).
    #[error("{0}")]
    Run(String),
}

#[cfg(test)]
mod beats_tests;
#[cfg(test)]
mod reach_tests;
#[cfg(test)]
mod tests;
