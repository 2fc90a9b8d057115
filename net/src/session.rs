//! Zenoh configuration of both sides: peers that talk only to the endpoints they are given
//! (no multicast or gossip scouting, so a run never meets a session it was not pointed at),
//! with the run's lease.

use std::time::Duration;

use zenoh::Wait;

use crate::{zenoh_error, NetError};

/// Which end of the run's link this session is.
#[derive(Debug, Clone)]
pub enum End {
    /// The orchestrator: listens on this endpoint.
    Listen(String),
    /// A participant: connects to this endpoint.
    Connect(String),
}

/// The configuration of one session.
pub fn config(end: &End, lease: Duration) -> Result<zenoh::Config, NetError> {
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: String| {
        c.insert_json5(k, &v).map_err(|e| NetError::Zenoh {
            what: format!("setting {k} = {v}"),
            why: e.to_string(),
        })
    };
    set(&mut c, "mode", "\"peer\"".into())?;
    set(&mut c, "scouting/multicast/enabled", "false".into())?;
    set(&mut c, "scouting/gossip/enabled", "false".into())?;
    match end {
        End::Listen(ep) => {
            set(&mut c, "listen/endpoints", json_list(ep))?;
            set(&mut c, "connect/endpoints", "[]".into())?;
        }
        End::Connect(ep) => {
            set(&mut c, "listen/endpoints", "[]".into())?;
            set(&mut c, "connect/endpoints", json_list(ep))?;
        }
    }
    let lease_ms = lease.as_millis().max(100) as u64;
    set(&mut c, "transport/link/tx/lease", lease_ms.to_string())?;
    Ok(c)
}

fn json_list(endpoint: &str) -> String {
    serde_json::to_string(&[endpoint]).unwrap_or_else(|_| "[]".into())
}

/// Opens a session.
pub fn open(end: &End, lease: Duration) -> Result<zenoh::Session, NetError> {
    let what = match end {
        End::Listen(ep) => format!("listening on {ep}"),
        End::Connect(ep) => format!("connecting to {ep}"),
    };
    zenoh::open(config(end, lease)?)
        .wait()
        .map_err(zenoh_error(&what))
}
