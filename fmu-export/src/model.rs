//! One FMU instance's model: the participant of its role built from its settings, with the
//! request it is fed and the reply it gave.

use actuator_proc::{Actuator, ActuatorInit};
use controller_proc::{Controller, ControllerInit};
use cosim::msg::{Header, Kind, Message, ScalarValue, Scalars};
use cosim::{Participant, Role};
use plant_proc::{Plant, PlantSettings};
use serde_json::Value;

/// A participant behind scalar inputs and outputs.
pub trait Model: Send {
    /// Sets request scalar `i`.
    fn set_input(&mut self, i: usize, v: ScalarValue) -> bool;
    /// Reply scalar `i` of the latest reply (the outputs at t₀ before any step).
    fn output(&self, i: usize) -> Option<ScalarValue>;
    /// Request scalar `i` as last set.
    fn input(&self, i: usize) -> Option<ScalarValue>;
    /// Steps from tick `k`; the error names a non-finite input.
    fn step(&mut self, k: u64) -> Result<(), String>;
}

struct Run<P: Participant> {
    p: P,
    input: P::Input,
    output: P::Output,
}

impl<P> Model for Run<P>
where
    P: Participant,
    P::Input: Scalars,
    P::Output: Scalars,
{
    fn set_input(&mut self, i: usize, v: ScalarValue) -> bool {
        self.input.set_scalar(i, v)
    }
    fn output(&self, i: usize) -> Option<ScalarValue> {
        self.output.scalar(i)
    }
    fn input(&self, i: usize) -> Option<ScalarValue> {
        self.input.scalar(i)
    }
    fn step(&mut self, k: u64) -> Result<(), String> {
        if let Some(i) = self.input.first_non_finite() {
            return Err(format!(
                "input `{}` is not finite; the model was not stepped",
                P::Input::FIELDS[i]
            ));
        }
        *self.input.header_mut() = Header::new(k, Kind::Step);
        self.output = self.p.step(&self.input);
        Ok(())
    }
}

fn run<P>(mut p: P) -> Box<dyn Model>
where
    P: Participant,
    P::Input: Scalars,
    P::Output: Scalars,
{
    let output = p.initial_output();
    Box::new(Run {
        p,
        input: P::Input::default(),
        output,
    })
}

/// Builds the participant of `role` from its settings, exactly as its process does.
pub fn build(role: Role, settings: &Value) -> Result<Box<dyn Model>, String> {
    fn parse<T: serde::de::DeserializeOwned>(v: &Value) -> Result<T, String> {
        serde_json::from_value(v.clone()).map_err(|e| format!("settings: {e}"))
    }
    Ok(match role {
        Role::Plant => run(Plant::new(&parse::<PlantSettings>(settings)?)),
        Role::Actuator => run(Actuator::new(&parse::<ActuatorInit>(settings)?)),
        Role::Controller => run(Controller::new(&parse::<ControllerInit>(settings)?)?),
    })
}
