//! Samples exchanged between the orchestrator and the participants, one type per direction.
//!
//! Every sample starts with a [`Header`] carrying the global step index (tick) it belongs to,
//! its [`Kind`], the protocol version and the attempt (a repeat of a request that went
//! unanswered). The receiving side checks them; a stale, duplicated or foreign sample is an
//! error, never silently reused; only the expected answer to a repeated request is discarded
//! (and counted).
//!
//! Timing semantics (see `docs/architecture.md`): a request for step `k` carries inputs valid
//! over `[t_k, t_{k+1})`; the reply for step `k` carries the participant's outputs at
//! `t_{k+1}`. The reply to [`Kind::Init`] carries the outputs at `t_0`.

#[cfg(feature = "ipc")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Version of the sample layouts below. Bumped whenever a field changes; the layout tests
/// (`layout_tests.rs`) pin every size and offset against it, so a layout change without a new
/// version fails them.
pub const PROTOCOL_VERSION: u32 = 7;

/// [`PROTOCOL_VERSION`] as a literal, for the type names ports are matched by.
macro_rules! protocol_version {
    () => {
        "7"
    };
}

/// What a sample asks for or answers.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Kind {
    /// Request the outputs at `t_0` (no stepping).
    #[default]
    Init = 1,
    /// Request one step from `t_k` to `t_{k+1}`.
    Step = 2,
    /// Ask the participant to exit cleanly.
    Stop = 3,
}

impl Kind {
    /// Decodes the raw value carried in a header.
    pub fn from_raw(v: u32) -> Option<Kind> {
        match v {
            1 => Some(Kind::Init),
            2 => Some(Kind::Step),
            3 => Some(Kind::Stop),
            _ => None,
        }
    }
}

/// Request flag: replace a non-finite input by the last good one instead of rejecting it
/// (`faults.on_bad_data = "hold"`).
pub const FLAG_HOLD_BAD_INPUT: u32 = 1;
/// Request flag: the participant process aborts on receipt (a scheduled `crash` fault).
pub const FLAG_CRASH: u32 = 2;
/// Reply flag: the request carried a non-finite value; the model was not stepped.
/// `Header::field` names it.
pub const FLAG_REJECTED: u32 = 4;
/// Reply flag: the request carried a non-finite value; the last good input was used.
pub const FLAG_HELD: u32 = 8;
/// Request flag: start free running (docs/architecture.md, "Execution modes"). The request
/// carries the first input (relay number 0) and, in [`Header::clock`], the participant's own
/// clock: the common start instant, its period and a busy wait added to each step. Every
/// request of a free run carries its relay number in [`Header::relay`]; a reply's `relay` is
/// the relay number of the input its step read.
pub const FLAG_FREE_START: u32 = 16;

/// A free-running participant's clock, sent once in the request that starts a free run
/// ([`FLAG_FREE_START`]); all zero otherwise.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FreeClock {
    /// The common start instant of every participant (CLOCK_MONOTONIC ns, [`now_ns`]): step 0
    /// is due then, step `j` at `start_ns + j · period_ns`.
    pub start_ns: u64,
    /// The participant's period (ns).
    pub period_ns: u64,
    /// The participant's period in ticks of the base period (its step `j` is tick
    /// `j · period_ticks`).
    pub period_ticks: u32,
    /// A busy wait added to each step (µs), for studies of a slow computation; 0 normally.
    pub busy_us: u32,
}

/// Monotonic clock (CLOCK_MONOTONIC, ns): one clock for every process of the machine, so
/// timestamps taken in different processes can be subtracted.
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the valid timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The order of a request or reply within a run, from its header: `Init` (step 0) first,
/// then step `k` as `2k + 1`; increasing through a run. `None` for `Stop` and unknown kinds.
pub fn exchange_key(h: &Header) -> Option<u64> {
    match Kind::from_raw(h.kind)? {
        Kind::Init => Some(h.step.saturating_mul(2)),
        Kind::Step => Some(h.step.saturating_mul(2).saturating_add(1)),
        Kind::Stop => None,
    }
}

/// [`now_ns`] where wall-clock times are wanted (`timed`), else 0 without reading the clock
/// (runs that report no timing, such as a sweep's discarded samples).
pub fn clock_ns(timed: bool) -> u64 {
    if timed {
        now_ns()
    } else {
        0
    }
}

/// Common prefix of every sample.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Header {
    /// Global step index (tick of the base period) this sample belongs to.
    pub step: u64,
    /// [`Kind`] as raw `u32`.
    pub kind: u32,
    /// [`PROTOCOL_VERSION`] of the sender.
    pub version: u32,
    /// Size in bytes of the whole sample as the sender built it.
    pub size: u32,
    /// `FLAG_*` bits.
    pub flags: u32,
    /// With [`FLAG_REJECTED`] or [`FLAG_HELD`]: 1 + index of the offending request field.
    pub field: u32,
    /// Which sending of this step's request this is: 0 the first, 1 and more a repeat sent
    /// because the exchange went silent (docs/architecture.md, "Lost samples"). A reply
    /// carries the attempt of the request it answers. Lock-step only (0 in free running).
    pub attempt: u32,
    /// Monotonic time the sender published the sample (ns, [`now_ns`]).
    pub sent_ns: u64,
    /// Replies: monotonic time the participant took the request (ns).
    pub recv_ns: u64,
    /// Replies: wall-clock nanoseconds spent inside the model's step (measurement only, never
    /// written to `timeseries.csv`). In free running it includes a study's busy wait.
    pub compute_ns: u64,
    /// Free running: a request's relay number (0 for the starting request, then one more for
    /// each input relayed to this participant); a reply's is the relay number of the input its
    /// step read. 0 in lock-step.
    pub relay: u64,
    /// Free running: the participant's clock, in the starting request only.
    pub clock: FreeClock,
}

// SAFETY: `#[repr(C)]` integers and a `#[repr(C)]` struct of integers: plain data with no
// padding (the layout tests check the offsets), no pointer, no drop.
#[cfg(feature = "ipc")]
unsafe impl ZeroCopySend for FreeClock {}
// SAFETY: as for `FreeClock`.
#[cfg(feature = "ipc")]
unsafe impl ZeroCopySend for Header {}

/// What a transport needs of a sample beyond plain data: with the `ipc` feature, iceoryx2's
/// `ZeroCopySend` (every [`Message`] has it, so a transport can lend samples zero-copy);
/// without it, nothing.
#[cfg(feature = "ipc")]
pub trait Lendable: ZeroCopySend {}
#[cfg(feature = "ipc")]
impl<T: ZeroCopySend> Lendable for T {}
/// What a transport needs of a sample beyond plain data: with the `ipc` feature, iceoryx2's
/// `ZeroCopySend`; without it (this build), nothing.
#[cfg(not(feature = "ipc"))]
pub trait Lendable {}
#[cfg(not(feature = "ipc"))]
impl<T> Lendable for T {}

impl Header {
    /// A header for step `step` of kind `kind` at the current protocol version.
    pub fn new(step: u64, kind: Kind) -> Self {
        Header {
            step,
            kind: kind as u32,
            version: PROTOCOL_VERSION,
            ..Default::default()
        }
    }
}

/// A sample type: plain old data with a [`Header`].
pub trait Message: Copy + Default + core::fmt::Debug + Lendable + Send + 'static {
    /// Name used in error messages and service names.
    const NAME: &'static str;
    /// The type name ports are matched by; it carries the protocol version, so ports of two
    /// versions do not connect.
    const TYPE_NAME: &'static str;
    /// The header.
    fn header(&self) -> &Header;
    /// The header, mutably.
    fn header_mut(&mut self) -> &mut Header;
    /// Names of the data fields, in declaration order.
    const FIELDS: &'static [&'static str];
    /// Index in [`Message::FIELDS`] of the first non-finite value, if any (bad data is caught
    /// where it arrives).
    fn first_non_finite(&self) -> Option<usize>;
    /// Stamps the header for sending: version, size, send time.
    fn stamp(&mut self) {
        self.stamp_at(now_ns());
    }
    /// Stamps the header for sending with send time `sent_ns` (0 where nothing is timed).
    fn stamp_at(&mut self, sent_ns: u64) {
        let h = self.header_mut();
        h.version = PROTOCOL_VERSION;
        h.size = core::mem::size_of::<Self>() as u32;
        h.sent_ns = sent_ns;
    }
    /// Writes every field little-endian at its offset into `out` (`size_of::<Self>()` bytes,
    /// padding left as it is): the network form ([`crate::wire`]).
    fn write_wire(&self, out: &mut [u8]);
    /// Reads the fields back from bytes [`Message::write_wire`] wrote.
    fn read_wire(b: &[u8]) -> Self;
    /// The sample as bytes on a network, padding zero.
    fn to_wire(&self) -> Vec<u8> {
        let mut out = vec![0u8; core::mem::size_of::<Self>()];
        self.write_wire(&mut out);
        out
    }
    /// A sample from bytes on a network: the length and the protocol version are checked
    /// before the rest is read.
    fn from_wire(b: &[u8]) -> Result<Self, crate::wire::WireError> {
        use crate::wire::{Wire, WireError};
        let expected = core::mem::size_of::<Self>();
        if b.len() != expected {
            return Err(WireError::Length {
                sample: Self::NAME,
                expected,
                got: b.len(),
            });
        }
        let version = <u32 as Wire>::get(&b[core::mem::offset_of!(Header, version)..]);
        if version != PROTOCOL_VERSION {
            return Err(WireError::Version {
                sample: Self::NAME,
                expected: PROTOCOL_VERSION,
                got: version,
            });
        }
        Ok(Self::read_wire(b))
    }
}

macro_rules! message {
    ($(#[$m:meta])* $name:ident, $label:literal {
        $($(#[doc = $doc:literal])* $f:ident : $t:ty => [$($unit:literal),*]),* $(,)?
    }) => {
        $(#[$m])*
        #[repr(C)]
        #[derive(Debug, Clone, Copy, Default, PartialEq)]
        pub struct $name {
            /// Step index, kind and version.
            pub header: Header,
            $($(#[doc = $doc])* pub $f: $t,)*
        }
        // SAFETY: `#[repr(C)]` plain data (a `Header` and `f64`, `u32` and `[f64; N]` fields):
        // no pointer, no reference, no drop; its layout is pinned by the layout tests. The
        // type name carries the protocol version, so ports of two versions do not connect.
        #[cfg(feature = "ipc")]
        unsafe impl ZeroCopySend for $name {
            unsafe fn type_name() -> &'static str {
                <Self as Message>::TYPE_NAME
            }
        }
        impl Message for $name {
            const NAME: &'static str = $label;
            const TYPE_NAME: &'static str = concat!("tiltsim/", $label, "/v", protocol_version!());
            fn header(&self) -> &Header { &self.header }
            fn header_mut(&mut self) -> &mut Header { &mut self.header }
            const FIELDS: &'static [&'static str] = &[$(stringify!($f)),*];
            fn first_non_finite(&self) -> Option<usize> {
                let checks = [$(FiniteCheck::all_finite(&self.$f)),*];
                checks.iter().position(|ok| !ok)
            }
            fn write_wire(&self, out: &mut [u8]) {
                use crate::wire::Wire;
                self.put(out);
            }
            fn read_wire(b: &[u8]) -> Self {
                use crate::wire::Wire;
                Self::get(b)
            }
        }
        crate::wire::wire_fields!($name { header $(, $f)* });
        impl Scalars for $name {
            const FIELD_INFO: &'static [FieldInfo] = &[$(FieldInfo {
                name: stringify!($f),
                description: concat!($($doc),*),
                units: &[$($unit),*],
                ty: <$t as FieldValue>::TYPE,
            }),*];
            fn scalar(&self, mut i: usize) -> Option<ScalarValue> {
                $(
                    let n = FieldValue::len(&self.$f);
                    if i < n {
                        return Some(FieldValue::get(&self.$f, i));
                    }
                    i -= n;
                )*
                let _ = i;
                None
            }
            fn set_scalar(&mut self, mut i: usize, v: ScalarValue) -> bool {
                $(
                    let n = FieldValue::len(&self.$f);
                    if i < n {
                        return FieldValue::set(&mut self.$f, i, v);
                    }
                    i -= n;
                )*
                let _ = (i, v);
                false
            }
        }
    };
}

/// Type of one scalar of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    /// IEEE double.
    F64,
    /// Unsigned 32-bit integer (counts, codes, bit sets).
    U32,
}

/// The value of one scalar of a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScalarValue {
    /// A double.
    F64(f64),
    /// An unsigned integer.
    U32(u32),
}

/// A data field of a sample as declared: its name, its documentation, the unit of each element
/// (one for a scalar field) and the element type.
#[derive(Debug, Clone, Copy)]
pub struct FieldInfo {
    /// Field name, as in [`Message::FIELDS`].
    pub name: &'static str,
    /// The field's documentation comment.
    pub description: &'static str,
    /// Unit of each element (`""` where it has none), in the notation of FMI's unit names.
    pub units: &'static [&'static str],
    /// Element type.
    pub ty: ScalarType,
}

/// One scalar of a sample: a scalar field or one element of an array field (`x[3]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarInfo {
    /// `field` or `field[i]`.
    pub name: String,
    /// The field's documentation.
    pub description: &'static str,
    /// Unit (`""` where none).
    pub unit: &'static str,
    /// Type.
    pub ty: ScalarType,
}

/// The data of a sample as a flat list of typed scalars, for bindings that exchange named
/// scalars (FMI): the header is not part of it.
pub trait Scalars: Message {
    /// The declared fields.
    const FIELD_INFO: &'static [FieldInfo];
    /// Scalar `i` of the flat list, `None` past the end.
    fn scalar(&self, i: usize) -> Option<ScalarValue>;
    /// Sets scalar `i`; false past the end or for a value of the wrong type.
    fn set_scalar(&mut self, i: usize, v: ScalarValue) -> bool;
    /// The flat list: arrays element by element, named `field[i]`.
    fn scalar_info() -> Vec<ScalarInfo> {
        let mut out = Vec::new();
        for f in Self::FIELD_INFO {
            if f.units.len() == 1 {
                out.push(ScalarInfo {
                    name: f.name.to_string(),
                    description: f.description.trim(),
                    unit: f.units[0],
                    ty: f.ty,
                });
            } else {
                for (i, u) in f.units.iter().enumerate() {
                    out.push(ScalarInfo {
                        name: format!("{}[{i}]", f.name),
                        description: f.description.trim(),
                        unit: u,
                        ty: f.ty,
                    });
                }
            }
        }
        out
    }
}

trait FieldValue {
    const TYPE: ScalarType;
    fn len(&self) -> usize;
    fn get(&self, i: usize) -> ScalarValue;
    fn set(&mut self, i: usize, v: ScalarValue) -> bool;
}
impl FieldValue for f64 {
    const TYPE: ScalarType = ScalarType::F64;
    fn len(&self) -> usize {
        1
    }
    fn get(&self, _: usize) -> ScalarValue {
        ScalarValue::F64(*self)
    }
    fn set(&mut self, _: usize, v: ScalarValue) -> bool {
        match v {
            ScalarValue::F64(x) => {
                *self = x;
                true
            }
            ScalarValue::U32(_) => false,
        }
    }
}
impl FieldValue for u32 {
    const TYPE: ScalarType = ScalarType::U32;
    fn len(&self) -> usize {
        1
    }
    fn get(&self, _: usize) -> ScalarValue {
        ScalarValue::U32(*self)
    }
    fn set(&mut self, _: usize, v: ScalarValue) -> bool {
        match v {
            ScalarValue::U32(x) => {
                *self = x;
                true
            }
            ScalarValue::F64(_) => false,
        }
    }
}
impl<const N: usize> FieldValue for [f64; N] {
    const TYPE: ScalarType = ScalarType::F64;
    fn len(&self) -> usize {
        N
    }
    fn get(&self, i: usize) -> ScalarValue {
        ScalarValue::F64(self[i])
    }
    fn set(&mut self, i: usize, v: ScalarValue) -> bool {
        match v {
            ScalarValue::F64(x) => {
                self[i] = x;
                true
            }
            ScalarValue::U32(_) => false,
        }
    }
}

trait FiniteCheck {
    fn all_finite(&self) -> bool;
}
impl FiniteCheck for f64 {
    fn all_finite(&self) -> bool {
        self.is_finite()
    }
}
impl FiniteCheck for u32 {
    fn all_finite(&self) -> bool {
        true
    }
}
impl<const N: usize> FiniteCheck for [f64; N] {
    fn all_finite(&self) -> bool {
        self.iter().all(|v| v.is_finite())
    }
}

message!(
    /// Orchestrator → plant: the achieved anti-roll-bar angle held over the step.
    ToPlant, "to_plant" {
        /// Achieved bar angle δ_a (rad), held over `[t_k, t_{k+1})`.
        delta_a: f64 => ["rad"],
    }
);

message!(
    /// Plant → orchestrator: vehicle state, track and sensor values at the sample time.
    FromPlant, "from_plant" {
        /// Simulated time (s).
        t: f64 => ["s"],
        /// Distance along the track (m).
        s: f64 => ["m"],
        /// Track curvature 1/R (1/m), deterministic design value.
        curvature: f64 => ["1/m"],
        /// Total track cant θ_o including irregularity (rad).
        cant: f64 => ["rad"],
        /// State x = [y_v, θ_v, y_b, θ_b, ẏ_v, θ̇_v, ẏ_b, θ̇_b, θ_r] (m, rad, m/s, rad/s), eq 14.
        x: [f64; 9] => ["m", "rad", "m", "rad", "m/s", "rad/s", "m/s", "rad/s", "rad"],
        /// Body-to-bogie roll ψ = θ_v − θ_b (rad), the twist the anti-roll bar sees.
        psi: f64 => ["rad"],
        /// Passenger lateral acceleration, eq 13 (m/s²).
        lat_acc: f64 => ["m/s2"],
        /// Measured body roll θ_v with sensor noise (rad), eq 15.
        theta_v_meas: f64 => ["rad"],
        /// The whole car's wheel-rail forces and passengers (zero for the half vehicle): for
        /// each wheelset j = 0..4, leading first, at 5j..5j+5: ΣY, Y on the +y wheel, Y on the
        /// −y wheel (rails on wheels, towards +y), Q_+y, Q_−y (N); then at 20..23 the body's
        /// lateral acceleration over the leading bogie, at the centre and over the trailing
        /// bogie (m/s²).
        car: [f64; CAR_VALUES] => [
            "N", "N", "N", "N", "N", "N", "N", "N", "N", "N", "N", "N", "N", "N", "N", "N",
            "N", "N", "N", "N", "m/s2", "m/s2", "m/s2"
        ],
    }
);

/// Values in [`FromPlant::car`]: five per wheelset of the whole car's four (ΣY, two Y, two
/// Q), then the body's lateral acceleration at three places along it.
pub const CAR_VALUES: usize = 23;

message!(
    /// Orchestrator → actuator: tilt command and the bar's twist.
    ToActuator, "to_actuator" {
        /// Commanded bar angle δ_a,cmd (rad).
        delta_a_cmd: f64 => ["rad"],
        /// Body-to-bogie roll ψ (rad) at `t_k`, for the bar's reaction torque.
        psi: f64 => ["rad"],
    }
);

message!(
    /// Actuator → orchestrator: achieved bar angle and drive telemetry.
    FromActuator, "from_actuator" {
        /// Achieved bar angle δ_a (rad).
        delta_a: f64 => ["rad"],
        /// The set-point the drive's position loop follows after command shaping (rad).
        delta_a_ref: f64 => ["rad"],
        /// Electromagnetic torque (N·m).
        motor_torque: f64 => ["N.m"],
        /// Rotor speed (rad/s).
        motor_speed: f64 => ["rad/s"],
        /// Motor current (A), see the actuator's docs for its definition.
        motor_current: f64 => ["A"],
        /// Power drawn from the DC link (W).
        dc_power: f64 => ["W"],
        /// Largest |phase current| in any electrical step of the interval (A).
        phase_current_peak: f64 => ["A"],
        /// DC-link voltage (V).
        v_dc: f64 => ["V"],
        /// Power dumped in the braking chopper (W).
        chopper_power: f64 => ["W"],
        /// Bit set of active limits (actuator-specific).
        limits: u32 => [""],
    }
);

message!(
    /// Orchestrator → controller: measurement and the vehicle's position on the track.
    ToController, "to_controller" {
        /// Simulated time (s).
        t: f64 => ["s"],
        /// Vehicle position along the track (m), as odometry would give it.
        s: f64 => ["m"],
        /// Measured body roll θ_v (rad).
        theta_v_meas: f64 => ["rad"],
    }
);

message!(
    /// Controller → orchestrator: bar command, reference and estimate.
    FromController, "from_controller" {
        /// Commanded bar angle δ_a,cmd (rad).
        delta_a_cmd: f64 => ["rad"],
        /// Body roll reference θ_v^d of eq 18 (rad).
        theta_ref: f64 => ["rad"],
        /// Estimated body roll θ̂_v (rad); the measurement where no estimator runs.
        theta_v_hat: f64 => ["rad"],
        /// QP solver iterations of this update (0 where no QP runs).
        solver_iterations: u32 => [""],
        /// QP outcome of this update: 0 no QP, 1 solved, 2 failed (the fallback was applied).
        solver_status: u32 => [""],
    }
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_values_are_named() {
        let mut s = FromPlant::default();
        assert_eq!(s.first_non_finite(), None);
        s.x[3] = f64::NAN;
        assert_eq!(
            s.first_non_finite().map(|i| FromPlant::FIELDS[i]),
            Some("x")
        );
        let c = FromController {
            delta_a_cmd: f64::INFINITY,
            ..Default::default()
        };
        assert_eq!(c.first_non_finite(), Some(0));
        assert_eq!(FromController::FIELDS[0], "delta_a_cmd");
    }

    #[test]
    fn kinds_round_trip() {
        for k in [Kind::Init, Kind::Step, Kind::Stop] {
            assert_eq!(Kind::from_raw(k as u32), Some(k));
        }
        assert_eq!(Kind::from_raw(0), None);
    }
}

#[cfg(test)]
mod scalar_tests {
    use super::*;

    fn count<M: Scalars>() -> usize {
        let m = M::default();
        (0..).take_while(|&i| m.scalar(i).is_some()).count()
    }

    #[test]
    fn every_scalar_has_a_name_a_unit_slot_and_round_trips() {
        fn check<M: Scalars>() {
            let info = M::scalar_info();
            assert_eq!(info.len(), count::<M>(), "{}: units per element", M::NAME);
            let mut m = M::default();
            for (i, s) in info.iter().enumerate() {
                let v = match s.ty {
                    ScalarType::F64 => ScalarValue::F64(i as f64 + 0.5),
                    ScalarType::U32 => ScalarValue::U32(i as u32 + 7),
                };
                assert!(m.set_scalar(i, v), "{}", s.name);
                assert_eq!(m.scalar(i), Some(v), "{}", s.name);
            }
            assert!(!m.set_scalar(info.len(), ScalarValue::F64(0.0)));
        }
        check::<ToPlant>();
        check::<FromPlant>();
        check::<ToActuator>();
        check::<FromActuator>();
        check::<ToController>();
        check::<FromController>();
        let p = FromPlant::scalar_info();
        assert_eq!(p[4].name, "x[0]");
        assert_eq!(p[5].unit, "rad");
        assert_eq!(p[12].name, "x[8]");
        let c = FromController::scalar_info();
        assert_eq!(c[3].ty, ScalarType::U32);
        assert!(c[0].description.contains("Commanded bar angle"));
    }
}
