//! The transport's own floor, measured the way iceoryx2's benchmark measures it: two processes,
//! each pinned to its own CPU and busy-waiting, pass a sample back and forth; the one-way
//! latency is half the round trip. Payloads of 64 B to 4 KB, each written whole into loaned
//! memory and sent (`loan_uninit`, `write_payload`, `send`), read in place on the other side.
//! `tiltsim bench --ping-pong` runs it, so a user can put their machine next to the published
//! figures. With `--same-cpu` both processes share one CPU and yield it while they wait: the
//! one-way latency is then the cost of handing a CPU from one process to another, the floor
//! of every exchange with a participant that shares its CPU with another process.

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use std::sync::atomic::{AtomicBool, Ordering};

use super::{config, iox, node, IpcError};

macro_rules! payload {
    ($name:ident, $bytes:literal) => {
        /// A ping-pong payload of this many bytes: a sequence number and filler.
        #[repr(C)]
        #[derive(Debug, Clone, Copy, ZeroCopySend)]
        pub struct $name {
            /// Sequence number.
            pub seq: u64,
            /// Filler up to the size.
            pub data: [u8; $bytes - 8],
        }
        impl Sized_ for $name {
            const BYTES: usize = $bytes;
            fn new(seq: u64) -> Self {
                $name {
                    seq,
                    data: [0; $bytes - 8],
                }
            }
            fn seq(&self) -> u64 {
                self.seq
            }
        }
    };
}

/// A payload type of a fixed size.
pub trait Sized_: ZeroCopySend + Copy + core::fmt::Debug + 'static {
    /// Its size.
    const BYTES: usize;
    /// A payload carrying `seq`.
    fn new(seq: u64) -> Self;
    /// Its sequence number.
    fn seq(&self) -> u64;
}

payload!(P64, 64);
payload!(P256, 256);
payload!(P1024, 1024);
payload!(P4096, 4096);

/// The payload sizes measured (bytes).
pub const SIZES: [usize; 4] = [64, 256, 1024, 4096];

/// The sequence number that tells the echo side to move to the next size.
const DONE: u64 = u64::MAX;

pub(super) type Ports<T> = (
    Publisher<ipc::Service, T, ()>,
    Subscriber<ipc::Service, T, ()>,
);

fn ports<T: Sized_>(node: &Node<ipc::Service>, out: &str, inp: &str) -> Result<Ports<T>, IpcError> {
    let name = |dir: &str| format!("tiltsim/pingpong/{}/{dir}", T::BYTES);
    pair(node, &name(out), &name(inp))
}

/// A publisher on service `out` and a subscriber on service `inp`, each one-to-one with room
/// for two samples and no history: the ports of a floor measurement (here and
/// [`super::pattern`]).
pub(super) fn pair<T: ZeroCopySend + core::fmt::Debug + 'static>(
    node: &Node<ipc::Service>,
    out: &str,
    inp: &str,
) -> Result<Ports<T>, IpcError> {
    let open = |name: &str| -> Result<_, IpcError> {
        let name: ServiceName = name.try_into().map_err(iox("service name"))?;
        node.service_builder(&name)
            .publish_subscribe::<T>()
            .max_publishers(1)
            .max_subscribers(1)
            .history_size(0)
            .subscriber_max_buffer_size(2)
            .open_or_create()
            .map_err(iox("open or create service"))
    };
    let p = open(out)?
        .publisher_builder()
        .create()
        .map_err(iox("create publisher"))?;
    let s = open(inp)?
        .subscriber_builder()
        .create()
        .map_err(iox("create subscriber"))?;
    Ok((p, s))
}

fn send<T: Sized_>(p: &Publisher<ipc::Service, T, ()>, seq: u64) -> Result<(), IpcError> {
    let sample = p.loan_uninit().map_err(iox("loan"))?;
    sample
        .write_payload(T::new(seq))
        .send()
        .map_err(iox("send"))?;
    Ok(())
}

/// How a side waits for the other's sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Waiting {
    /// Busy-wait (each process on its own CPU), as iceoryx2's benchmark.
    Spin,
    /// `sched_yield` between polls (both processes on one CPU).
    Yield,
}

/// Polls until a sample arrives; returns its sequence number. With `stop`, gives up once it
/// is set (looked at every [`LOOK_EVERY`] polls, so the measured path stays a poll).
fn receive<T: Sized_>(
    s: &Subscriber<ipc::Service, T, ()>,
    w: Waiting,
    stop: Option<&AtomicBool>,
) -> Result<u64, IpcError> {
    let mut polls = 0u32;
    loop {
        if let Some(sample) = s.receive().map_err(iox("receive"))? {
            return Ok(sample.payload().seq());
        }
        polls = polls.wrapping_add(1);
        if polls.is_multiple_of(LOOK_EVERY) && stop.is_some_and(|f| f.load(Ordering::Relaxed)) {
            return Err(IpcError::Stopped);
        }
        match w {
            Waiting::Spin => core::hint::spin_loop(),
            Waiting::Yield => std::thread::yield_now(),
        }
    }
}

/// Polls between two looks at the caller's stop flag.
const LOOK_EVERY: u32 = 1024;

fn echo_one<T: Sized_>(node: &Node<ipc::Service>, w: Waiting) -> Result<(), IpcError> {
    let (publisher, subscriber) = ports::<T>(node, "pong", "ping")?;
    loop {
        let seq = receive(&subscriber, w, None)?;
        send(&publisher, seq)?;
        if seq == DONE {
            return Ok(());
        }
    }
}

/// The echo side (`tiltsim bench-echo`): answers every ping of every size with a pong.
pub fn echo(prefix: &str, w: Waiting) -> Result<(), IpcError> {
    let cfg = config(prefix)?;
    let node = node(&cfg, "pingpong-echo")?;
    echo_one::<P64>(&node, w)?;
    echo_one::<P256>(&node, w)?;
    echo_one::<P1024>(&node, w)?;
    echo_one::<P4096>(&node, w)
}

/// One-way latencies (ns) of `rounds` round trips of `T`, after a handshake and warm-up.
fn measure_one<T: Sized_>(
    node: &Node<ipc::Service>,
    rounds: usize,
    w: Waiting,
    stop: &AtomicBool,
) -> Result<Vec<f64>, IpcError> {
    let (publisher, subscriber) = ports::<T>(node, "ping", "pong")?;
    // Handshake: samples sent before the echo subscribes are lost; ping until a pong comes.
    let started = std::time::Instant::now();
    'hand: loop {
        send(&publisher, 0)?;
        let t = std::time::Instant::now();
        while t.elapsed() < std::time::Duration::from_millis(1) {
            if let Some(s) = subscriber.receive().map_err(iox("receive"))? {
                if s.payload().seq() == 0 {
                    break 'hand;
                }
            }
            if w == Waiting::Yield {
                std::thread::yield_now();
            }
        }
        if stop.load(Ordering::Relaxed) {
            return Err(IpcError::Stopped);
        }
        if started.elapsed() > std::time::Duration::from_secs(10) {
            return Err(IpcError::Iceoryx(
                "ping-pong: the echo process does not answer".into(),
            ));
        }
    }
    // Late pongs of the handshake (one for each ping 0 the echo had queued) may come at any
    // time, on a busy machine long after this: those at hand are dropped now, the others when
    // they come (a pong 0 is never an answer to a measured ping).
    while subscriber.receive().map_err(iox("receive"))?.is_some() {}
    let mut out = Vec::with_capacity(rounds);
    for i in 1..=(rounds + rounds / 10) as u64 {
        let t0 = std::time::Instant::now();
        send(&publisher, i)?;
        let mut got = receive(&subscriber, w, Some(stop))?;
        while got == 0 {
            got = receive(&subscriber, w, Some(stop))?;
        }
        let rtt = t0.elapsed().as_nanos() as f64;
        if got != i {
            return Err(IpcError::Iceoryx(format!(
                "ping-pong: pong {got} for ping {i}"
            )));
        }
        // The first tenth warms caches and pages up.
        if i as usize > rounds / 10 {
            out.push(rtt / 2.0);
        }
    }
    send(&publisher, DONE)?;
    let _ = receive(&subscriber, w, Some(stop));
    Ok(out)
}

/// The measuring side: one-way latencies (ns) per size in [`SIZES`], `rounds` each; the echo
/// process must be running with the same `prefix` and waiting `w`. Ends with
/// [`IpcError::Stopped`] once `stop` is set (Ctrl-C), whether or not the echo still answers.
pub fn measure(
    prefix: &str,
    rounds: usize,
    w: Waiting,
    stop: &AtomicBool,
) -> Result<Vec<Vec<f64>>, IpcError> {
    let cfg = config(prefix)?;
    let node = node(&cfg, "pingpong")?;
    Ok(vec![
        measure_one::<P64>(&node, rounds, w, stop)?,
        measure_one::<P256>(&node, rounds, w, stop)?,
        measure_one::<P1024>(&node, rounds, w, stop)?,
        measure_one::<P4096>(&node, rounds, w, stop)?,
    ])
}
