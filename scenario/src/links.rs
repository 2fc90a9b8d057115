//! Link-effect settings (section `[links.<name>]`): what the transport between two processes
//! does to the samples it carries, as a scenario declares it, and the names of the four links.
//!
//! The effects are applied by the master's `LinkSet` (`tiltsim_master::links`), on the value in
//! flight, in this order at tick k: the sender's value v_k is dropped (probability or window)
//! or queued with delay d_k = `delay_ticks` + jitter; the receiver holds the newest (by send
//! tick) value that has arrived; then a freeze window holds what was delivered when it began;
//! then bias and Gaussian noise are added; then a NaN or a fixed (out-of-range) value overrides
//! it inside its window.

use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::Checker;

/// A time window in simulated seconds, `[start, end)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Window {
    /// Start (s).
    pub start_s: f64,
    /// End (s).
    pub end_s: f64,
}

impl Window {
    /// Whether simulated time `t` (s) lies inside the window.
    pub fn contains(&self, t: f64) -> bool {
        t >= self.start_s && t < self.end_s
    }
    fn check(&self, c: &mut Checker, field: &str) {
        c.require(
            self.start_s.is_finite()
                && self.end_s.is_finite()
                && self.start_s >= 0.0
                && self.end_s > self.start_s,
            field,
            format!("[{}, {})", self.start_s, self.end_s),
            "a window with 0 <= start_s < end_s (s)",
        );
    }
}

/// Distribution of the random extra delay.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Jitter {
    /// No jitter.
    #[default]
    None,
    /// Uniform whole ticks in `[0, jitter_ticks]`.
    Uniform,
    /// Exponential with mean `jitter_ticks`, rounded down to whole ticks.
    Exponential,
    /// |Normal(0, jitter_ticks)| rounded to whole ticks (half-normal).
    HalfNormal,
}

/// A fixed value that replaces the sample inside a window (out-of-range injection).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Override {
    /// Start (s).
    pub start_s: f64,
    /// End (s).
    pub end_s: f64,
    /// The value (in the link's unit).
    pub value: f64,
}

/// What one link does to its samples. Every field is optional; the default does nothing.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkEffects {
    /// Fixed transport delay (base ticks).
    pub delay_ticks: u64,
    /// Random extra delay: its distribution.
    pub jitter: Jitter,
    /// Random extra delay: its scale (ticks; see [`Jitter`]).
    pub jitter_ticks: f64,
    /// Probability that a sample is lost.
    pub drop_probability: f64,
    /// Every sample inside this window is lost.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drop_window: Option<Window>,
    /// The receiver sees a frozen (stale) value inside this window.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub freeze_window: Option<Window>,
    /// Added offset (the link's unit).
    pub bias: f64,
    /// Standard deviation of added Gaussian noise (the link's unit).
    pub noise_std: f64,
    /// The sample is NaN inside this window (bad data; see `faults.on_bad_data`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nan_window: Option<Window>,
    /// The sample is replaced by a fixed value inside a window (out-of-range data).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value_window: Option<Override>,
}

impl LinkEffects {
    /// True when the link changes nothing.
    pub fn is_identity(&self) -> bool {
        *self == LinkEffects::default()
    }
    fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        c.require(
            self.delay_ticks <= 100_000,
            "delay_ticks",
            self.delay_ticks,
            "an integer in [0, 100000] ticks",
        );
        c.range("jitter_ticks", self.jitter_ticks, 0.0, 100_000.0, "ticks");
        c.require(
            self.jitter == Jitter::None || self.jitter_ticks > 0.0,
            "jitter_ticks",
            self.jitter_ticks,
            "a positive scale when `jitter` is set",
        );
        c.range("drop_probability", self.drop_probability, 0.0, 1.0, "");
        c.range("bias", self.bias, -1e6, 1e6, "");
        c.range("noise_std", self.noise_std, 0.0, 1e6, "");
        for (f, w) in [
            ("drop_window", self.drop_window),
            ("freeze_window", self.freeze_window),
            ("nan_window", self.nan_window),
        ] {
            if let Some(w) = w {
                w.check(&mut c, f);
            }
        }
        if let Some(o) = self.value_window {
            Window {
                start_s: o.start_s,
                end_s: o.end_s,
            }
            .check(&mut c, "value_window");
            c.range("value_window.value", o.value, -1e9, 1e9, "");
        }
        c
    }
}

/// The links between the participants (section `[links.<name>]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Links {
    /// Controller → actuator: commanded bar angle δ_a,cmd (rad).
    pub actuator_command: LinkEffects,
    /// Actuator → plant: achieved bar angle δ_a (rad).
    pub bar_angle: LinkEffects,
    /// Plant → controller: measured body roll θ_v (rad).
    pub measurement: LinkEffects,
    /// Plant → actuator: body-to-bogie roll ψ the bar's reaction sees (rad).
    pub bar_twist: LinkEffects,
}

/// The four links, in the order of the `rx_*` columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkId {
    /// Controller → actuator: δ_a,cmd.
    ActuatorCommand = 0,
    /// Actuator → plant: δ_a.
    BarAngle = 1,
    /// Plant → controller: θ_v measured.
    Measurement = 2,
    /// Plant → actuator: ψ.
    BarTwist = 3,
}

impl LinkId {
    /// What each link carries from the outputs `p`, `a`, `c`, in [`LinkId`] order.
    pub fn carried(
        p: &tiltsim_protocol::msg::FromPlant,
        a: &tiltsim_protocol::msg::FromActuator,
        c: &tiltsim_protocol::msg::FromController,
    ) -> [f64; 4] {
        [c.delta_a_cmd, a.delta_a, p.theta_v_meas, p.psi]
    }

    /// All links, in column order.
    pub const ALL: [LinkId; 4] = [
        LinkId::ActuatorCommand,
        LinkId::BarAngle,
        LinkId::Measurement,
        LinkId::BarTwist,
    ];
    /// The name in scenario files and `events.csv`.
    pub fn name(self) -> &'static str {
        LINK_NAMES[self as usize]
    }
}

/// Link names in column order.
pub const LINK_NAMES: [&str; 4] = ["actuator_command", "bar_angle", "measurement", "bar_twist"];

impl Links {
    /// Checks every link.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut all = Checker::new(prefix);
        for (name, l) in LINK_NAMES.iter().zip(self.all()) {
            all.merge(l.validate(&format!("{prefix}.{name}")));
        }
        all
    }
    /// The links in [`LINK_NAMES`] order.
    pub fn all(&self) -> [&LinkEffects; 4] {
        [
            &self.actuator_command,
            &self.bar_angle,
            &self.measurement,
            &self.bar_twist,
        ]
    }
}
