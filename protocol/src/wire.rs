//! The samples as bytes on a network: every field little-endian at the offset the layout tests
//! pin, padding zero, so a sample crosses between hosts of any byte order and is read back
//! equal, field for field.
//!
//! Shared memory carries the `#[repr(C)]` value itself; a network transport carries
//! [`Message::to_wire`](crate::msg::Message::to_wire) and reads it back with
//! [`Message::from_wire`](crate::msg::Message::from_wire), which checks the length and the
//! protocol version before anything else is trusted.

use crate::msg::{FreeClock, Header};

/// A value written into and read from its place in a sample's bytes.
pub trait Wire: Sized {
    /// Writes `self` little-endian at the start of `out`.
    fn put(&self, out: &mut [u8]);
    /// Reads a value from the start of `b`.
    fn get(b: &[u8]) -> Self;
}

macro_rules! wire_number {
    ($($t:ty),*) => {$(
        impl Wire for $t {
            #[inline]
            fn put(&self, out: &mut [u8]) {
                out[..core::mem::size_of::<$t>()].copy_from_slice(&self.to_le_bytes());
            }
            #[inline]
            fn get(b: &[u8]) -> Self {
                let mut a = [0u8; core::mem::size_of::<$t>()];
                a.copy_from_slice(&b[..core::mem::size_of::<$t>()]);
                <$t>::from_le_bytes(a)
            }
        }
    )*};
}
wire_number!(u32, u64, f64);

impl<const N: usize> Wire for [f64; N] {
    fn put(&self, out: &mut [u8]) {
        for (i, v) in self.iter().enumerate() {
            v.put(&mut out[8 * i..]);
        }
    }
    fn get(b: &[u8]) -> Self {
        core::array::from_fn(|i| f64::get(&b[8 * i..]))
    }
}

/// Writes or reads each named field of a `#[repr(C)]` struct at its own offset.
macro_rules! wire_fields {
    ($ty:ty { $($f:ident),* }) => {
        impl crate::wire::Wire for $ty {
            fn put(&self, out: &mut [u8]) {
                $(crate::wire::Wire::put(&self.$f, &mut out[core::mem::offset_of!($ty, $f)..]);)*
            }
            fn get(b: &[u8]) -> Self {
                Self { $($f: crate::wire::Wire::get(&b[core::mem::offset_of!($ty, $f)..]),)* }
            }
        }
    };
}
wire_fields!(FreeClock {
    start_ns,
    period_ns,
    period_ticks,
    busy_us
});
wire_fields!(Header {
    step,
    kind,
    version,
    size,
    flags,
    field,
    attempt,
    sent_ns,
    recv_ns,
    compute_ns,
    relay,
    clock
});
pub(crate) use wire_fields;

/// Why bytes are not a sample.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// Fewer or more bytes than the sample has.
    #[error("{sample}: {got} bytes, expected {expected}")]
    Length {
        /// The sample expected.
        sample: &'static str,
        /// Its size.
        expected: usize,
        /// The bytes received.
        got: usize,
    },
    /// The sender speaks another protocol version.
    #[error("{sample}: protocol version {got}, expected {expected}")]
    Version {
        /// The sample expected.
        sample: &'static str,
        /// This side's version.
        expected: u32,
        /// The sender's.
        got: u32,
    },
}

#[cfg(test)]
mod tests {
    use crate::msg::*;

    fn round_trip<T: Message + PartialEq>(v: T) {
        let b = v.to_wire();
        assert_eq!(b.len(), core::mem::size_of::<T>());
        assert_eq!(T::from_wire(&b).unwrap(), v, "{}", T::NAME);
    }

    #[test]
    fn every_sample_crosses_field_for_field_with_its_padding_zero() {
        let h = Header {
            step: 0x0102_0304_0506_0708,
            attempt: 3,
            sent_ns: 11,
            recv_ns: 12,
            compute_ns: 13,
            relay: 14,
            clock: FreeClock {
                start_ns: 15,
                period_ns: 16,
                period_ticks: 17,
                busy_us: 18,
            },
            ..Header::new(0, Kind::Step)
        };
        let a = FromActuator {
            header: h,
            delta_a: -0.125,
            v_dc: 750.5,
            limits: 0xdead_beef,
            ..Default::default()
        };
        round_trip(a);
        // FromActuator is 168 bytes with `limits` at 160: the four bytes after it are padding.
        let b = a.to_wire();
        assert_eq!(&b[164..168], &[0, 0, 0, 0]);
        assert_eq!(&b[160..164], &0xdead_beef_u32.to_le_bytes());
        // The step leads, little-endian, whatever the host's byte order.
        assert_eq!(&b[..8], &[8, 7, 6, 5, 4, 3, 2, 1]);
        round_trip(FromPlant {
            header: h,
            x: core::array::from_fn(|i| i as f64 - 4.5),
            theta_v_meas: f64::MIN_POSITIVE,
            ..Default::default()
        });
        round_trip(ToPlant {
            header: h,
            delta_a: 1e-300,
        });
        round_trip(ToActuator {
            header: h,
            delta_a_cmd: -0.0,
            psi: 2.0,
        });
        round_trip(ToController {
            header: h,
            t: 1.5,
            s: 7.0,
            theta_v_meas: 0.01,
        });
        round_trip(FromController {
            header: h,
            solver_iterations: 7,
            solver_status: 2,
            ..Default::default()
        });
    }

    #[test]
    fn a_short_sample_or_another_version_is_refused_by_name() {
        let v = ToPlant {
            header: Header::new(3, Kind::Step),
            delta_a: 0.5,
        };
        let b = v.to_wire();
        let e = ToPlant::from_wire(&b[..40]).unwrap_err();
        assert_eq!(e.to_string(), "to_plant: 40 bytes, expected 96");
        let mut other = v;
        other.header.version = PROTOCOL_VERSION + 1;
        let e = ToPlant::from_wire(&other.to_wire()).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "to_plant: protocol version {}, expected {PROTOCOL_VERSION}",
                PROTOCOL_VERSION + 1
            )
        );
    }
}
