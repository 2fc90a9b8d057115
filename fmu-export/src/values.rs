//! Values of each FMI type read and written through the layout: the types a sample's fields
//! have and those only parameters have, one value or arrays of them.

use cosim::msg::ScalarValue;
use tiltsim_fmi::layout::{ParamValue, Slot};

use crate::{settable, Instance, Vr};

/// Gets/sets values of one FMI type through the layout.
pub(crate) trait FmiValue: Copy {
    const NAME: &'static str;
    fn from_scalar(v: ScalarValue) -> Option<Self>;
    fn to_scalar(self, like: ScalarValue) -> Option<ScalarValue>;
    fn from_param(v: &ParamValue) -> Option<Self>;
    fn to_param(self, like: &ParamValue) -> Option<ParamValue>;
    fn from_time(_t: f64) -> Option<Self> {
        None
    }
}

impl FmiValue for f64 {
    const NAME: &'static str = "Float64";
    fn from_scalar(v: ScalarValue) -> Option<Self> {
        match v {
            ScalarValue::F64(x) => Some(x),
            ScalarValue::U32(_) => None,
        }
    }
    fn to_scalar(self, like: ScalarValue) -> Option<ScalarValue> {
        matches!(like, ScalarValue::F64(_)).then_some(ScalarValue::F64(self))
    }
    fn from_param(v: &ParamValue) -> Option<Self> {
        match v {
            ParamValue::F64(x) => Some(*x),
            _ => None,
        }
    }
    fn to_param(self, like: &ParamValue) -> Option<ParamValue> {
        matches!(like, ParamValue::F64(_)).then_some(ParamValue::F64(self))
    }
    fn from_time(t: f64) -> Option<Self> {
        Some(t)
    }
}

impl FmiValue for u32 {
    const NAME: &'static str = "UInt32";
    fn from_scalar(v: ScalarValue) -> Option<Self> {
        match v {
            ScalarValue::U32(x) => Some(x),
            ScalarValue::F64(_) => None,
        }
    }
    fn to_scalar(self, like: ScalarValue) -> Option<ScalarValue> {
        matches!(like, ScalarValue::U32(_)).then_some(ScalarValue::U32(self))
    }
    fn from_param(_: &ParamValue) -> Option<Self> {
        None
    }
    fn to_param(self, _: &ParamValue) -> Option<ParamValue> {
        None
    }
}

/// The types only parameters have (no sample field is of them).
macro_rules! parameter_only {
    ($t:ty, $variant:ident, $name:literal) => {
        impl FmiValue for $t {
            const NAME: &'static str = $name;
            fn from_scalar(_: ScalarValue) -> Option<Self> {
                None
            }
            fn to_scalar(self, _: ScalarValue) -> Option<ScalarValue> {
                None
            }
            fn from_param(v: &ParamValue) -> Option<Self> {
                match v {
                    ParamValue::$variant(x) => Some(*x),
                    _ => None,
                }
            }
            fn to_param(self, like: &ParamValue) -> Option<ParamValue> {
                matches!(like, ParamValue::$variant(_)).then_some(ParamValue::$variant(self))
            }
        }
    };
}
parameter_only!(u64, U64, "UInt64");
parameter_only!(i64, I64, "Int64");
parameter_only!(bool, Bool, "Boolean");

pub(crate) fn get_one<T: FmiValue>(i: &mut Instance, vr: Vr) -> Result<T, String> {
    let slot = i
        .layout
        .slot(vr)
        .ok_or_else(|| format!("no variable has value reference {vr}"))?;
    let v = match slot {
        Slot::Time => T::from_time(i.time()),
        Slot::Input(k) => T::from_scalar(i.inputs[k]),
        Slot::Output(k) => T::from_scalar(i.output(k)?),
        Slot::Param(k) => T::from_param(&i.params[k]),
    };
    v.ok_or_else(|| format!("value reference {vr} is not a {}", T::NAME))
}

pub(crate) fn set_one<T: FmiValue>(i: &mut Instance, vr: Vr, v: T) -> Result<(), String> {
    let slot = i
        .layout
        .slot(vr)
        .ok_or_else(|| format!("no variable has value reference {vr}"))?;
    settable(i, slot)?;
    let ok = match slot {
        Slot::Input(k) => v.to_scalar(i.inputs[k]).map(|s| i.inputs[k] = s).is_some(),
        Slot::Param(k) => v
            .to_param(&i.params[k])
            .map(|p| {
                i.params[k] = p;
                i.params_changed = true;
            })
            .is_some(),
        _ => false,
    };
    if ok {
        Ok(())
    } else {
        Err(format!("value reference {vr} is not a {}", T::NAME))
    }
}
