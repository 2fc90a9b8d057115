//! The wire layout, pinned: every sample's size and every field's offset, for the protocol
//! version in force. A transport that moves samples as bytes (shared memory, a network)
//! relies on exactly this; a field added, removed, resized or moved fails here until the
//! table below is rewritten for a new [`PROTOCOL_VERSION`].

use core::mem::{offset_of, size_of};

use crate::msg::*;

/// The protocol version the tables below describe.
const PINNED_VERSION: u32 = 7;

/// One sample: its size and its data fields' offsets, in declaration order (the header is
/// at offset 0 of every sample).
struct Sample {
    name: &'static str,
    size: usize,
    fields: &'static [(&'static str, usize)],
    actual_size: usize,
    actual: Vec<usize>,
    declared: &'static [&'static str],
}

macro_rules! sample {
    ($t:ty, $size:literal, [$(($f:ident, $off:literal)),* $(,)?]) => {
        Sample {
            name: <$t as Message>::NAME,
            size: $size,
            fields: &[$((stringify!($f), $off)),*],
            actual_size: size_of::<$t>(),
            actual: vec![$(offset_of!($t, $f)),*],
            declared: <$t as Message>::FIELDS,
        }
    };
}

#[test]
fn the_pinned_layout_is_the_current_versions() {
    assert_eq!(
        PROTOCOL_VERSION, PINNED_VERSION,
        "the protocol version changed: pin its layout in this file"
    );
    // Ports are matched by type name, which carries the version.
    assert_eq!(
        <FromPlant as Message>::TYPE_NAME,
        format!("tiltsim/from_plant/v{PROTOCOL_VERSION}")
    );
}

/// The transport matches ports by the type name the zero-copy marker gives: the versioned one.
#[cfg(feature = "ipc")]
#[test]
fn the_transports_type_name_is_the_versioned_one() {
    use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
    // SAFETY: type_name only returns a string.
    let name = unsafe { <FromPlant as ZeroCopySend>::type_name() };
    assert_eq!(name, format!("tiltsim/from_plant/v{PROTOCOL_VERSION}"));
}

#[test]
fn header_layout_is_pinned_and_has_no_padding() {
    let pinned: [(&str, usize, usize); 12] = [
        ("step", 0, offset_of!(Header, step)),
        ("kind", 8, offset_of!(Header, kind)),
        ("version", 12, offset_of!(Header, version)),
        ("size", 16, offset_of!(Header, size)),
        ("flags", 20, offset_of!(Header, flags)),
        ("field", 24, offset_of!(Header, field)),
        ("attempt", 28, offset_of!(Header, attempt)),
        ("sent_ns", 32, offset_of!(Header, sent_ns)),
        ("recv_ns", 40, offset_of!(Header, recv_ns)),
        ("compute_ns", 48, offset_of!(Header, compute_ns)),
        ("relay", 56, offset_of!(Header, relay)),
        ("clock", 64, offset_of!(Header, clock)),
    ];
    for (name, want, got) in pinned {
        assert_eq!(got, want, "Header::{name}");
    }
    assert_eq!(size_of::<Header>(), 88);
    assert_eq!(core::mem::align_of::<Header>(), 8);
    let clock = [
        ("start_ns", 0, offset_of!(FreeClock, start_ns)),
        ("period_ns", 8, offset_of!(FreeClock, period_ns)),
        ("period_ticks", 16, offset_of!(FreeClock, period_ticks)),
        ("busy_us", 20, offset_of!(FreeClock, busy_us)),
    ];
    for (name, want, got) in clock {
        assert_eq!(got, want, "FreeClock::{name}");
    }
    assert_eq!(size_of::<FreeClock>(), 24);
    // No padding: the fields' own sizes add up to the whole (8 + 6·4 + 4·8 + 24).
    assert_eq!(
        8 + 6 * 4 + 4 * 8 + size_of::<FreeClock>(),
        size_of::<Header>()
    );
}

#[test]
fn every_sample_layout_is_pinned() {
    let samples = [
        sample!(ToPlant, 96, [(delta_a, 88)]),
        sample!(
            FromPlant,
            400,
            [
                (t, 88),
                (s, 96),
                (curvature, 104),
                (cant, 112),
                (x, 120),
                (psi, 192),
                (lat_acc, 200),
                (theta_v_meas, 208),
                (car, 216)
            ]
        ),
        sample!(ToActuator, 104, [(delta_a_cmd, 88), (psi, 96)]),
        sample!(
            FromActuator,
            168,
            [
                (delta_a, 88),
                (delta_a_ref, 96),
                (motor_torque, 104),
                (motor_speed, 112),
                (motor_current, 120),
                (dc_power, 128),
                (phase_current_peak, 136),
                (v_dc, 144),
                (chopper_power, 152),
                (limits, 160)
            ]
        ),
        sample!(ToController, 112, [(t, 88), (s, 96), (theta_v_meas, 104)]),
        sample!(
            FromController,
            120,
            [
                (delta_a_cmd, 88),
                (theta_ref, 96),
                (theta_v_hat, 104),
                (solver_iterations, 112),
                (solver_status, 116)
            ]
        ),
    ];
    for s in samples {
        let names: Vec<&str> = s.fields.iter().map(|(n, _)| *n).collect();
        assert_eq!(
            names, s.declared,
            "{}: a field was added, removed or reordered; pin the new layout under a new version",
            s.name
        );
        assert_eq!(s.actual_size, s.size, "{}: size", s.name);
        for ((name, want), got) in s.fields.iter().zip(&s.actual) {
            assert_eq!(got, want, "{}::{name}: offset", s.name);
        }
    }
}

#[test]
fn stamped_samples_carry_their_size_and_version() {
    let mut m = FromPlant::default();
    m.stamp_at(5);
    assert_eq!(m.header.size as usize, size_of::<FromPlant>());
    assert_eq!(m.header.version, PINNED_VERSION);
    assert_eq!(m.header.sent_ns, 5);
}
