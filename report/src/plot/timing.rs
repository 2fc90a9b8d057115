//! The figures of a free run's timing trace (`timing.csv`): each consumer's input age and each
//! participant's start lateness over simulated time.

use std::path::{Path, PathBuf};

use cosim::Role;
use tiltsim_master::free::trace::{age, col, StepTrace};

use super::{write_chart, Chart, Line};

/// The points of one line drawn over the ticks of a run, gathered tick by tick in order:
/// every tick's value when `block` is 1, otherwise the minimum and maximum of each block of
/// `block` ticks (a min/max envelope, as the run figures draw long series, so the memory
/// needed does not grow with the run).
struct Envelope {
    block: u64,
    k: u64,
    lo: f64,
    hi: f64,
    y: Vec<f64>,
}

impl Envelope {
    fn new(block: u64) -> Self {
        Envelope {
            block,
            k: 0,
            lo: f64::NAN,
            hi: f64::NAN,
            y: Vec::new(),
        }
    }

    /// The next tick's value (NaN: none).
    fn push(&mut self, v: f64) {
        if self.block == 1 {
            self.y.push(v);
            return;
        }
        if self.k.is_multiple_of(self.block) {
            (self.lo, self.hi) = (v, v);
        } else {
            // `f64::min` and `max` skip a NaN: a block is NaN only where every tick is.
            (self.lo, self.hi) = (self.lo.min(v), self.hi.max(v));
        }
        self.k += 1;
        if self.k.is_multiple_of(self.block) {
            self.y.extend([self.lo, self.hi]);
        }
    }

    fn finish(mut self) -> Vec<f64> {
        if self.block > 1 && !self.k.is_multiple_of(self.block) {
            self.y.extend([self.lo, self.hi]);
        }
        self.y
    }
}

/// The simulated times (s) of an [`Envelope`]'s points over `steps` ticks of `dt_s`: each
/// tick's, or the first and last tick of each block.
fn axis(steps: u64, block: u64, dt_s: f64) -> Vec<f64> {
    if block == 1 {
        return (0..steps).map(|k| k as f64 * dt_s).collect();
    }
    (0..steps.div_ceil(block))
        .flat_map(|b| [b * block, ((b + 1) * block).min(steps) - 1])
        .map(|k| k as f64 * dt_s)
        .collect()
}

/// Per tick, the value a role's steps give it, held between the steps of a role slower than
/// the tick (NaN before its first step); the role's steps come in ascending order.
struct Held {
    next: u64,
    held: f64,
    line: Envelope,
}

impl Held {
    fn new(block: u64) -> Self {
        Held {
            next: 0,
            held: f64::NAN,
            line: Envelope::new(block),
        }
    }

    /// The role's step at tick `step` gives `v`.
    fn at(&mut self, step: u64, v: f64) {
        self.until(step);
        self.held = v;
    }

    /// Every tick before `end` not yet drawn.
    fn until(&mut self, end: u64) {
        while self.next < end {
            self.line.push(self.held);
            self.next += 1;
        }
    }

    fn finish(mut self, steps: u64) -> Vec<f64> {
        self.until(steps);
        self.line.finish()
    }
}

/// Per tick, how many ticks after the controller's step its new command was first read by
/// the actuator, held over the controller's `period`. The held command's age grows by a tick
/// every tick by design: what timing changes is when each new command takes effect, the
/// first actuator step that read it, less its own step (lock-step Gauss-Seidel: 0). A
/// consumer never reads an older sample after a newer one ([`tiltsim_master::free::trace`]),
/// so over the actuator's steps, in order, each command is first read in the order of the
/// controller's steps, and that first read is the quickest.
struct CommandEffect {
    period: u64,
    next: u64,
    held: f64,
    last: i64,
    line: Envelope,
}

impl CommandEffect {
    fn new(period: u64, block: u64) -> Self {
        CommandEffect {
            period: period.max(1),
            next: 0,
            held: f64::NAN,
            last: -1,
            line: Envelope::new(block),
        }
    }

    /// An actuator step: its tick, and the controller step it read.
    fn actuator(&mut self, step: u64, read: Option<i64>) {
        let Some(c) = read.filter(|&c| c > self.last) else {
            return;
        };
        self.until(c as u64);
        self.held = step as f64 - c as f64;
        if c as u64 == self.next && (c as u64).is_multiple_of(self.period) {
            self.line.push(self.held);
            self.next += 1;
        }
        self.last = c;
    }

    /// Every tick before `end` not yet drawn: a controller step no actuator step read is NaN.
    fn until(&mut self, end: u64) {
        while self.next < end {
            if self.next.is_multiple_of(self.period) {
                self.held = f64::NAN;
            }
            self.line.push(self.held);
            self.next += 1;
        }
    }

    fn finish(mut self, steps: u64) -> Vec<f64> {
        self.until(steps);
        self.line.finish()
    }
}

/// Most points per line of a timing figure, as for the run figures.
const PLOT_POINTS: u64 = 40_000;

/// Every line of the timing figures, gathered in one pass over the trace.
struct Lines {
    effect: CommandEffect,
    /// Input ages: controller ← plant, actuator ← plant, plant ← actuator.
    ages: [Held; 3],
    /// Start lateness (ms) of the plant, the actuator and the controller.
    late: [Held; 3],
}

impl Lines {
    fn new(period: u64, block: u64) -> Self {
        Lines {
            effect: CommandEffect::new(period, block),
            ages: std::array::from_fn(|_| Held::new(block)),
            late: std::array::from_fn(|_| Held::new(block)),
        }
    }

    fn step(&mut self, s: &StepTrace) {
        let input_age = |p: Role| s.from[col(p)].map_or(f64::NAN, |f| age(p, s.step, f) as f64);
        let (age_line, producer) = match s.role {
            Role::Controller => (0, Role::Plant),
            Role::Actuator => (1, Role::Plant),
            Role::Plant => (2, Role::Actuator),
        };
        self.ages[age_line].at(s.step, input_age(producer));
        let lateness = s.read_ns.saturating_sub(s.due_ns) as f64 * 1e-6;
        self.late[col(s.role)].at(s.step, lateness);
        if s.role == Role::Actuator {
            self.effect.actuator(s.step, s.from[col(Role::Controller)]);
        }
    }
}

/// The timing figures of a free run, gathered from its trace one step at a time
/// ([`TimingFigures::step`], each role's steps in order) and drawn by
/// [`TimingFigures::write`]: at most about 40 000 points per line whatever the run's length.
pub struct TimingFigures {
    steps: u64,
    block: u64,
    lines: Lines,
}

impl TimingFigures {
    /// For a run of `steps` ticks with a controller of `period` ticks.
    pub fn new(steps: u64, period: u64) -> Self {
        let block = if steps <= PLOT_POINTS {
            1
        } else {
            steps.div_ceil(PLOT_POINTS / 2)
        };
        TimingFigures {
            steps,
            block,
            lines: Lines::new(period, block),
        }
    }

    /// The trace's next step.
    pub fn step(&mut self, s: &StepTrace) {
        self.lines.step(s);
    }

    /// Writes `dir/plots/timing_input_age.{svg,png}` and `timing_lateness.{svg,png}` for a
    /// run of ticks of `dt_s`; `title` names the run. Every line is 0 where lock-step
    /// Gauss-Seidel would have read the same output. Returns the files written.
    pub fn write(self, dir: &Path, title: &str, dt_s: f64) -> std::io::Result<Vec<PathBuf>> {
        let out = dir.join("plots");
        std::fs::create_dir_all(&out)
            .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", out.display())))?;
        let t = axis(self.steps, self.block, dt_s);
        let steps = self.steps;
        let Lines { effect, ages, late } = self.lines;
        let [age_controller, age_actuator, age_plant] = ages.map(|h| h.finish(steps));
        let [late_plant, late_actuator, late_controller] = late.map(|h| h.finish(steps));
        let effect = effect.finish(steps);
        let age_title = format!("{title}: age of the inputs each step read (free run)");
        let age_chart = Chart {
        title: &age_title,
        x_label: "simulated time (s)",
        y_label: "input age (ticks)",
        lines: vec![
            Line {
                label: "actuator ← controller (new δ_{a,cmd})",
                y: effect,
                colour: "#ff7f0e",
                ..Default::default()
            },
            Line {
                label: "controller ← plant (θ_{v} measured)",
                y: age_controller,
                colour: "#2ca02c",
                ..Default::default()
            },
            Line {
                label: "actuator ← plant (ψ)",
                y: age_actuator,
                colour: "#9467bd",
                ..Default::default()
            },
            Line {
                label: "plant ← actuator (δ_{a})",
                y: age_plant,
                colour: "#1f77b4",
                ..Default::default()
            },
        ],
        note: "0: as lock-step Gauss-Seidel reads; −1: a newer output; δ_{a,cmd}: ticks until a new one is first read",
        ..Default::default()
    };
        let late_title = format!("{title}: how late each step started (free run)");
        let late_chart = Chart {
            title: &late_title,
            x_label: "simulated time (s)",
            y_label: "start lateness (ms)",
            lines: vec![
                Line {
                    label: "plant",
                    y: late_plant,
                    colour: "#1f77b4",
                    ..Default::default()
                },
                Line {
                    label: "actuator",
                    y: late_actuator,
                    colour: "#9467bd",
                    ..Default::default()
                },
                Line {
                    label: "controller",
                    y: late_controller,
                    colour: "#2ca02c",
                    ..Default::default()
                },
            ],
            note: "lateness: wall-clock time from the instant a step was due to its start",
            ..Default::default()
        };
        let mut files = Vec::new();
        files.extend(write_chart(&out, "timing_input_age", &age_chart, &t)?);
        files.extend(write_chart(&out, "timing_lateness", &late_chart, &t)?);
        Ok(files)
    }
}
