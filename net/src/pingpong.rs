//! The network's own floor, measured with the same session settings and the same channels as
//! a run's exchanges: 256-byte samples go back and forth between this process (listening, as
//! an orchestrator does) and an echo process (connected, as a participant is), each reading
//! from a FIFO channel as a [`NetEndpoint`](crate::NetEndpoint) and a participant do. The
//! round trip of one exchange is the floor of a lock-step exchange with a remote participant.

use std::time::{Duration, Instant};

use zenoh::handlers::FifoChannel;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use cosim::msg::now_ns;

use crate::{session, zenoh_error, NetError};

/// Bytes of each sample (the size of the largest request or reply is 216).
pub const BYTES: usize = 256;

fn ping_key(run: &str) -> String {
    format!("tiltsim/bench/{run}/ping")
}
fn pong_key(run: &str) -> String {
    format!("tiltsim/bench/{run}/pong")
}

/// The echo side: connects to `endpoint` and sends every ping of bench `run` back until a
/// sample of one byte arrives or nothing comes for `idle`.
pub fn echo(endpoint: &str, run: &str, idle: Duration) -> Result<(), NetError> {
    let s = session::open(
        &session::End::Connect(endpoint.into()),
        Duration::from_secs(10),
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
        .declare_token(format!("tiltsim/bench/{run}/echo"))
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

/// The listening side: `rounds` round trips (ns each) with the echo of bench `run`, after
/// waiting up to `startup` for it to connect.
pub fn measure(
    endpoint: &str,
    run: &str,
    rounds: usize,
    startup: Duration,
) -> Result<Vec<u64>, NetError> {
    let s = session::open(
        &session::End::Listen(endpoint.into()),
        Duration::from_secs(10),
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
        let present = s
            .liveliness()
            .get(format!("tiltsim/bench/{run}/echo"))
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
                "bench: the echo did not connect to {endpoint} within {} s",
                startup.as_secs()
            )));
        }
    }
    while pongs.try_recv().ok().flatten().is_some() {}
    let mut out = Vec::with_capacity(rounds);
    let mut buf = vec![0u8; BYTES];
    for i in 0..rounds as u64 {
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
