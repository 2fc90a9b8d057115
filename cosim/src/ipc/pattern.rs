//! The floor of a lock-step tick's exchanges on this machine: iceoryx2 alone, in the pattern,
//! placement and wait of an IPC run, with nothing of tiltsim's in between.
//!
//! One measuring process stands in for the orchestrator and one echo process for each
//! participant. The measurer sits on one CPU and the echoes share another, as an adaptive run
//! with a pair of CPUs of its own pins them; the measurer spins [`SPIN_POLLS`](crate::wait::SPIN_POLLS) polls
//! and then yields, the echoes yield at once and sleep through three quarters of the gap
//! between requests that come far apart, exactly as the run's waits do
//! ([`Backoff`], [`Cadence`]). A tick sends each due echo a 256-byte sample written whole
//! into loaned memory and waits for its answer: one after the other ([`Order::InTurn`], a
//! Gauss-Seidel tick) or all requests first, then every answer ([`Order::AllAtOnce`], a
//! Jacobi tick). What an IPC run's coordination costs per tick beyond this is tiltsim's own:
//! its bookkeeping, its relay and its checks.

use std::sync::atomic::{AtomicBool, Ordering};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use super::{config, iox, node, IpcError};
use crate::msg::now_ns;
use crate::wait::{sleep_until_ns, Backoff, Cadence, WaitStrategy};

/// The order of a tick's exchanges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Each request after the previous answer (Gauss-Seidel).
    InTurn,
    /// Every request, then every answer (Jacobi).
    AllAtOnce,
}

/// A sample of an exchange: sequence number, send time and filler to 256 bytes (about the
/// size of tiltsim's requests and replies).
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
pub struct Exchange {
    /// Sequence number (0: a handshake, [`DONE`]: the end).
    pub seq: u64,
    /// Monotonic send time (ns), for the echo's [`Cadence`].
    pub sent_ns: u64,
    /// Filler.
    pub data: [u8; 240],
}

/// The sequence number that ends an echo.
const DONE: u64 = u64::MAX;

/// How long an echo waits for a request before it checks whether its parent is still there.
const IDLE: std::time::Duration = std::time::Duration::from_secs(2);

type Ports = super::pingpong::Ports<Exchange>;

fn ports(node: &Node<ipc::Service>, index: usize, echo: bool) -> Result<Ports, IpcError> {
    let name = |dir: &str| format!("tiltsim/pattern/{index}/{dir}");
    let (out, inp) = if echo {
        ("reply", "request")
    } else {
        ("request", "reply")
    };
    super::pingpong::pair(node, &name(out), &name(inp))
}

fn send(p: &Publisher<ipc::Service, Exchange, ()>, seq: u64) -> Result<(), IpcError> {
    let sample = p.loan_uninit().map_err(iox("loan"))?;
    sample
        .write_payload(Exchange {
            seq,
            sent_ns: now_ns(),
            data: [0; 240],
        })
        .send()
        .map_err(iox("send"))?;
    Ok(())
}

/// The echo of participant `index` (`tiltsim bench-echo --pattern INDEX`): answers every
/// request with its sequence number until [`DONE`], or until its parent has gone.
pub fn echo(prefix: &str, index: usize) -> Result<(), IpcError> {
    let cfg = config(prefix)?;
    let node = node(&cfg, &format!("pattern-echo-{index}"))?;
    let (publisher, subscriber) = ports(&node, index, true)?;
    // SAFETY: getppid has no preconditions.
    let parent = unsafe { libc::getppid() };
    let mut cadence = Cadence::default();
    loop {
        let mut backoff = Backoff::with_spin(WaitStrategy::Adaptive, 0);
        let mut sleep = cadence.sleep_until();
        let (seq, sent_ns) = loop {
            if let Some(s) = subscriber.receive().map_err(iox("receive"))? {
                break (s.payload().seq, s.payload().sent_ns);
            }
            if let Some(until) = sleep.take() {
                sleep_until_ns(until);
                continue;
            }
            // SAFETY: as above.
            if backoff.elapsed() > IDLE && unsafe { libc::getppid() } != parent {
                return Ok(());
            }
            backoff.pause();
        };
        if seq != 0 && seq != DONE {
            cadence.observe(sent_ns);
        }
        send(&publisher, seq)?;
        if seq == DONE {
            return Ok(());
        }
    }
}

/// How long the measurer waits for one answer before it takes the echo for dead.
const SILENCE: std::time::Duration = std::time::Duration::from_secs(30);

/// Waits for the answer `seq` on `s`, dropping late handshake answers (0);
/// [`IpcError::Stopped`] once `stop` is set.
fn answer(
    s: &Subscriber<ipc::Service, Exchange, ()>,
    seq: u64,
    stop: &AtomicBool,
) -> Result<(), IpcError> {
    let mut backoff = Backoff::new(WaitStrategy::Adaptive);
    loop {
        if stop.load(Ordering::Relaxed) {
            return Err(IpcError::Stopped);
        }
        if backoff.elapsed() > SILENCE {
            return Err(IpcError::Iceoryx(format!(
                "exchange floor: no answer to request {seq} in {} s",
                SILENCE.as_secs()
            )));
        }
        if let Some(got) = s.receive().map_err(iox("receive"))? {
            let got = got.payload().seq;
            if got == seq {
                return Ok(());
            }
            if got != 0 {
                return Err(IpcError::Iceoryx(format!(
                    "exchange floor: answer {got} to request {seq}"
                )));
            }
            continue;
        }
        backoff.pause();
    }
}

/// Sends handshakes on every port until each echo has answered one (samples sent before an
/// echo subscribes are lost), then drops the answers at hand; [`IpcError::Stopped`] once
/// `stop` is set.
fn handshake(ports: &[Ports], stop: &AtomicBool) -> Result<(), IpcError> {
    let started = std::time::Instant::now();
    for (p, s) in ports {
        'hand: loop {
            if stop.load(Ordering::Relaxed) {
                return Err(IpcError::Stopped);
            }
            send(p, 0)?;
            let t = std::time::Instant::now();
            while t.elapsed() < std::time::Duration::from_millis(1) {
                if let Some(a) = s.receive().map_err(iox("receive"))? {
                    if a.payload().seq == 0 {
                        break 'hand;
                    }
                }
                std::thread::yield_now();
            }
            if started.elapsed() > std::time::Duration::from_secs(10) {
                return Err(IpcError::Iceoryx(
                    "exchange floor: an echo process does not answer".into(),
                ));
            }
        }
    }
    for (_, s) in ports {
        while s.receive().map_err(iox("receive"))?.is_some() {}
    }
    Ok(())
}

/// The wall time (ns) of each of `ticks` ticks in `order`, after a tenth more to warm up;
/// echo `i` is asked on the ticks that are multiples of `every[i]`. The echo processes must be
/// running with the same `prefix`, one per entry of `every`. [`IpcError::Stopped`] once `stop`
/// is set (Ctrl-C), whether or not the echoes still answer.
pub fn measure(
    prefix: &str,
    every: &[u64],
    order: Order,
    ticks: usize,
    stop: &AtomicBool,
) -> Result<Vec<f64>, IpcError> {
    let cfg = config(prefix)?;
    let node = node(&cfg, "pattern")?;
    let ports = (0..every.len())
        .map(|i| ports(&node, i, false))
        .collect::<Result<Vec<_>, _>>()?;
    handshake(&ports, stop)?;
    let warm = ticks / 10;
    let mut out = Vec::with_capacity(ticks);
    for k in 0..(ticks + warm) as u64 {
        let seq = k + 1;
        let due = |i: &usize| k % every[*i].max(1) == 0;
        let t0 = std::time::Instant::now();
        match order {
            Order::InTurn => {
                for i in (0..ports.len()).filter(due) {
                    send(&ports[i].0, seq)?;
                    answer(&ports[i].1, seq, stop)?;
                }
            }
            Order::AllAtOnce => {
                for i in (0..ports.len()).filter(due) {
                    send(&ports[i].0, seq)?;
                }
                for i in (0..ports.len()).filter(due) {
                    answer(&ports[i].1, seq, stop)?;
                }
            }
        }
        if k as usize >= warm {
            out.push(t0.elapsed().as_nanos() as f64);
        }
    }
    for (p, s) in &ports {
        send(p, DONE)?;
        answer(s, DONE, stop)?;
    }
    Ok(out)
}
