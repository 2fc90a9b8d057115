//! Validation helpers shared by every crate's settings: each problem names the field, the value
//! and what is allowed.

/// One rejected setting.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldError {
    /// Dotted path of the field, as written in the scenario file (`vehicle.m_v`).
    pub field: String,
    /// The offending value.
    pub value: String,
    /// What is allowed.
    pub allowed: String,
}

impl core::fmt::Display for FieldError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "field `{}` = {}: allowed {}",
            self.field, self.value, self.allowed
        )
    }
}

/// Collects field errors under a dotted prefix.
#[derive(Debug, Default)]
pub struct Checker {
    prefix: String,
    /// Errors found so far.
    pub errors: Vec<FieldError>,
}

impl Checker {
    /// A checker whose fields are reported under `prefix` (may be empty).
    pub fn new(prefix: &str) -> Self {
        Checker {
            prefix: prefix.to_string(),
            errors: Vec::new(),
        }
    }

    fn path(&self, field: &str) -> String {
        if self.prefix.is_empty() {
            field.to_string()
        } else {
            format!("{}.{}", self.prefix, field)
        }
    }

    /// Requires `lo <= value <= hi` (and finite); `unit` is shown in the message.
    pub fn range(&mut self, field: &str, value: f64, lo: f64, hi: f64, unit: &str) {
        if !(value.is_finite() && value >= lo && value <= hi) {
            self.errors.push(FieldError {
                field: self.path(field),
                value: format!("{value}"),
                allowed: format!("a number in [{lo}, {hi}] {unit}")
                    .trim_end()
                    .to_string(),
            });
        }
    }

    /// Requires `value > 0` and `value <= hi`.
    pub fn positive(&mut self, field: &str, value: f64, hi: f64, unit: &str) {
        if !(value.is_finite() && value > 0.0 && value <= hi) {
            self.errors.push(FieldError {
                field: self.path(field),
                value: format!("{value}"),
                allowed: format!("a number in (0, {hi}] {unit}")
                    .trim_end()
                    .to_string(),
            });
        }
    }

    /// Records an arbitrary rule.
    pub fn require(
        &mut self,
        ok: bool,
        field: &str,
        value: impl core::fmt::Display,
        allowed: &str,
    ) {
        if !ok {
            self.errors.push(FieldError {
                field: self.path(field),
                value: value.to_string(),
                allowed: allowed.to_string(),
            });
        }
    }

    /// Merges another checker's errors.
    pub fn merge(&mut self, other: Checker) {
        self.errors.extend(other.errors);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_field_value_and_range() {
        let mut c = Checker::new("vehicle");
        c.range("m_v", -1.0, 1.0, 1e6, "kg");
        c.positive("dt_s", f64::NAN, 1.0, "s");
        c.range("ok", 3.0, 1.0, 5.0, "");
        assert_eq!(c.errors.len(), 2);
        assert_eq!(
            c.errors[0].to_string(),
            "field `vehicle.m_v` = -1: allowed a number in [1, 1000000] kg"
        );
        assert!(c.errors[1]
            .to_string()
            .starts_with("field `vehicle.dt_s` = NaN"));
    }
}
