//! The network's own floor, measured with the same session settings and the same channels as
//! a run's exchanges: 256-byte samples go back and forth between this process (listening, as
//! an orchestrator does) and an echo process (connected, as a participant is), each reading
//! from a FIFO channel as a [`NetEndpoint`](crate::NetEndpoint) and a participant do. The
//! round trip of one exchange is the floor of a lock-step exchange with a remote participant.
//!
//! [`Floor`] says how: over QUIC with the run's kind of credentials and access control (what
//! a run uses), or over plain TCP without them (to measure what the security costs), and with
//! which [`Tuning`]. [`raw_tcp_echo`] and [`raw_tcp_measure`] measure the same round trip
//! over a bare TCP socket, the wire's own floor on that path.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use zenoh::handlers::FifoChannel;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use cosim::msg::now_ns;
use cosim::Role;
use tiltsim_protocol::address::Address;

use crate::credentials::{self, Holder};
use crate::session::{self, Security, Tuning};
use crate::{acl, zenoh_error, NetError};

/// Bytes of each sample: 256, the size the floors in docs/performance.md were measured with
/// (the largest request or reply, the plant's, is 400 bytes since it carries the whole car's
/// forces).
pub const BYTES: usize = 256;

/// How the floor is measured.
#[derive(Debug, Clone)]
pub struct Floor {
    /// Where the measuring side listens.
    pub address: Address,
    /// QUIC with credentials from this secret (as a run), or plain TCP when `None`.
    pub secret: Option<String>,
    /// Zenoh's transport settings, the same at both ends.
    pub tuning: Tuning,
}

fn ping_key(run: &str) -> String {
    format!("tiltsim/run/{run}/bench/ping")
}
fn pong_key(run: &str) -> String {
    format!("tiltsim/run/{run}/bench/pong")
}
fn echo_token(run: &str) -> String {
    format!("tiltsim/run/{run}/bench/echo")
}

fn security(f: &Floor, run: &str, holder: Holder) -> Result<Security, NetError> {
    let Some(secret) = &f.secret else {
        return Ok(Security::PlainForMeasurement);
    };
    let credentials = credentials::issue(secret, holder)
        .map_err(|e| NetError::Participant(format!("bench: {e}")))?;
    let id = &credentials.authority_id;
    let acl = match holder {
        Holder::Orchestrator => acl::bench(&ping_key(run), &pong_key(run), &echo_token(run), id),
        Holder::Role(_) => acl::participant(id),
    };
    Ok(Security::Tls { credentials, acl })
}

/// The echo side: connects to the floor's address and sends every ping of bench `run` back
/// until a sample of one byte arrives or nothing comes for `idle`.
pub fn echo(f: &Floor, run: &str, idle: Duration) -> Result<(), NetError> {
    let s = session::open(
        &session::End::Connect(f.address.clone()),
        Duration::from_secs(10),
        &security(f, run, Holder::Role(Role::Plant))?,
        f.tuning,
    )?;
    let pings = s
        .declare_subscriber(ping_key(run))
        .with(FifoChannel::new(64))
        .wait()
        .map_err(zenoh_error("declaring the ping subscriber"))?;
    let pongs = s
        .declare_publisher(pong_key(run))
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(zenoh_error("declaring the pong publisher"))?;
    let _alive = s
        .liveliness()
        .declare_token(echo_token(run))
        .wait()
        .map_err(zenoh_error("declaring the echo's liveliness"))?;
    loop {
        match pings.recv_timeout(idle) {
            Ok(Some(sample)) => {
                let b = sample.payload().to_bytes();
                if b.len() == 1 {
                    break;
                }
                pongs
                    .put(b.into_owned())
                    .wait()
                    .map_err(zenoh_error("sending a pong"))?;
            }
            Ok(None) => break,
            Err(e) => return Err(NetError::Participant(format!("bench echo: {e}"))),
        }
    }
    let _ = s.close().wait();
    Ok(())
}

/// [`NetError::Stopped`] once the caller's `stop` flag is set.
fn check(stop: &AtomicBool) -> Result<(), NetError> {
    if stop.load(Ordering::Relaxed) {
        return Err(NetError::Stopped);
    }
    Ok(())
}

/// The listening side: `rounds` round trips (ns each) with the echo of bench `run`, after
/// waiting up to `startup` for it to connect. Ends with [`NetError::Stopped`] within a round
/// trip (or 0.7 s while connecting) once `stop` is set.
pub fn measure(
    f: &Floor,
    run: &str,
    rounds: usize,
    startup: Duration,
    stop: &AtomicBool,
) -> Result<Vec<u64>, NetError> {
    let s = session::open(
        &session::End::Listen(f.address.clone()),
        Duration::from_secs(10),
        &security(f, run, Holder::Orchestrator)?,
        f.tuning,
    )?;
    let pongs = s
        .declare_subscriber(pong_key(run))
        .with(FifoChannel::new(64))
        .wait()
        .map_err(zenoh_error("declaring the pong subscriber"))?;
    let pings = s
        .declare_publisher(ping_key(run))
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(zenoh_error("declaring the ping publisher"))?;
    let start = Instant::now();
    // Connected once the echo's token shows and a first ping comes back.
    loop {
        check(stop)?;
        let present = s
            .liveliness()
            .get(echo_token(run))
            .timeout(Duration::from_millis(200))
            .wait()
            .map_err(zenoh_error("looking for the echo"))?
            .recv()
            .is_ok();
        if present {
            pings
                .put(vec![0u8; BYTES])
                .wait()
                .map_err(zenoh_error("sending a ping"))?;
            if let Ok(Some(_)) = pongs.recv_timeout(Duration::from_millis(500)) {
                break;
            }
        }
        if start.elapsed() > startup {
            return Err(NetError::Participant(format!(
                "bench: the echo did not connect to {} within {} s",
                f.address,
                startup.as_secs()
            )));
        }
    }
    while pongs.try_recv().ok().flatten().is_some() {}
    let mut out = Vec::with_capacity(rounds);
    let mut buf = vec![0u8; BYTES];
    for i in 0..rounds as u64 {
        check(stop)?;
        buf[..8].copy_from_slice(&i.to_le_bytes());
        let t0 = now_ns();
        pings
            .put(buf.clone())
            .wait()
            .map_err(zenoh_error("sending a ping"))?;
        loop {
            match pongs.recv_timeout(Duration::from_secs(5)) {
                Ok(Some(p)) => {
                    let b = p.payload().to_bytes();
                    if b.len() >= 8 && b[..8] == i.to_le_bytes() {
                        break;
                    }
                }
                _ => {
                    return Err(NetError::Participant(format!(
                        "bench: round trip {i} did not come back within 5 s"
                    )))
                }
            }
        }
        out.push(now_ns() - t0);
    }
    let _ = pings.put(vec![1u8]).wait();
    std::thread::sleep(Duration::from_millis(50));
    let _ = s.close().wait();
    Ok(out)
}

fn io_error(what: &str) -> impl FnOnce(std::io::Error) -> NetError + '_ {
    move |e| NetError::Participant(format!("bench raw TCP: {what}: {e}"))
}

/// The raw TCP echo: connects to `address` (retrying for `startup`), sets TCP_NODELAY and
/// sends back every [`BYTES`]-byte message until the other side closes.
pub fn raw_tcp_echo(address: &Address, startup: Duration) -> Result<(), NetError> {
    let start = Instant::now();
    let target = address.to_string();
    let mut stream = loop {
        match TcpStream::connect(&target) {
            Ok(s) => break s,
            Err(e) if start.elapsed() < startup => {
                let _ = e;
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => return Err(io_error("connecting")(e)),
        }
    };
    stream.set_nodelay(true).map_err(io_error("TCP_NODELAY"))?;
    let mut buf = [0u8; BYTES];
    loop {
        match stream.read_exact(&mut buf) {
            Ok(()) => stream.write_all(&buf).map_err(io_error("writing"))?,
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(io_error("reading")(e)),
        }
    }
}

/// The raw TCP floor: listens on `address`, starts the echo with `start_echo`, waits up to
/// `startup` for it to connect, and measures `rounds` round trips of [`BYTES`] bytes (ns each),
/// TCP_NODELAY at both ends. Ends with [`NetError::Stopped`] within a round trip (or 20 ms
/// while waiting for the echo) once `stop` is set; an echo silent for 5 s is an error.
pub fn raw_tcp_measure(
    address: &Address,
    rounds: usize,
    startup: Duration,
    stop: &AtomicBool,
    start_echo: impl FnOnce() -> Result<(), NetError>,
) -> Result<Vec<u64>, NetError> {
    let listener = TcpListener::bind(address.to_string()).map_err(io_error("listening"))?;
    start_echo()?;
    let mut stream = accept(&listener, address, startup, stop)?;
    stream.set_nodelay(true).map_err(io_error("TCP_NODELAY"))?;
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .map_err(io_error("setting the read timeout"))?;
    let mut buf = [0u8; BYTES];
    let mut back = [0u8; BYTES];
    let mut out = Vec::with_capacity(rounds);
    // A few round trips first, as the Zenoh floor's connection check does.
    for i in 0..(rounds + 16) as u64 {
        check(stop)?;
        buf[..8].copy_from_slice(&i.to_le_bytes());
        let t0 = now_ns();
        stream.write_all(&buf).map_err(io_error("writing"))?;
        stream.read_exact(&mut back).map_err(io_error("reading"))?;
        let t = now_ns() - t0;
        if back[..8] != buf[..8] {
            return Err(NetError::Participant(format!(
                "bench raw TCP: round trip {i} came back with other bytes"
            )));
        }
        if i >= 16 {
            out.push(t);
        }
    }
    Ok(out)
}

/// The echo's connection, polled every 20 ms for up to `startup` so that an echo that never
/// connects (or a stop) does not leave the bench waiting for ever.
fn accept(
    listener: &TcpListener,
    address: &Address,
    startup: Duration,
    stop: &AtomicBool,
) -> Result<TcpStream, NetError> {
    listener
        .set_nonblocking(true)
        .map_err(io_error("listening"))?;
    let start = Instant::now();
    loop {
        check(stop)?;
        match listener.accept() {
            Ok((stream, _)) => {
                stream
                    .set_nonblocking(false)
                    .map_err(io_error("accepting"))?;
                return Ok(stream);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if start.elapsed() > startup {
                    return Err(NetError::Participant(format!(
                        "bench raw TCP: the echo did not connect to {address} within {} s",
                        startup.as_secs()
                    )));
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => return Err(io_error("accepting")(e)),
        }
    }
}
