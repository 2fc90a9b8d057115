//! The cells of a row as they are written: floats in shortest round-trip form
//! ([`crate::float_text`]), integers by `itoa`.

use crate::float_text::put_f64;

/// A value of a row as it is written.
pub(super) trait Cell: Copy {
    fn put(&self, out: &mut String);
    /// The value a field holds, if it holds one of this type.
    fn read(field: &[u8]) -> Option<Self>;
    fn lo(self, other: Self) -> Self;
    fn hi(self, other: Self) -> Self;
    /// The value as a float (integers below 2^53 exactly).
    fn number(self) -> f64;
}
impl Cell for f64 {
    fn number(self) -> f64 {
        self
    }
    fn read(field: &[u8]) -> Option<Self> {
        std::str::from_utf8(field).ok()?.parse().ok()
    }
    fn put(&self, out: &mut String) {
        put_f64(*self, out);
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
    }
}

impl Cell for u64 {
    fn number(self) -> f64 {
        self as f64
    }
    fn read(field: &[u8]) -> Option<Self> {
        std::str::from_utf8(field).ok()?.parse().ok()
    }
    fn put(&self, out: &mut String) {
        out.push_str(itoa::Buffer::new().format(*self));
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
    }
}
impl Cell for u32 {
    fn number(self) -> f64 {
        f64::from(self)
    }
    fn read(field: &[u8]) -> Option<Self> {
        std::str::from_utf8(field).ok()?.parse().ok()
    }
    fn put(&self, out: &mut String) {
        out.push_str(itoa::Buffer::new().format(*self));
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
    }
}
