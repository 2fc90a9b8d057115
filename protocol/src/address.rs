//! Where a participant on another host reaches the run: `HOST:PORT`.
//!
//! Users write an address as `10.0.0.1:7447`, `[fd00::1]:7447` or `host.example:7447`; a
//! leading `quic/`, `tls/` or `tcp/` (Zenoh's endpoint syntax, and what earlier versions asked
//! for) is accepted and means the same: every run's link is QUIC (TLS 1.3) on that port. An address is checked here,
//! before any transport sees it, so that a typo is refused naming what is allowed.

use std::fmt;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};

/// A host and a port.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Address {
    /// An IPv4 or IPv6 address, or a host name.
    pub host: Host,
    /// 1-65535.
    pub port: u16,
}

/// The host part of an [`Address`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Host {
    /// A numeric address.
    Ip(IpAddr),
    /// A DNS name (letters, digits, `-` and `.`, at most 253 characters).
    Name(String),
}

/// What an address may look like, for error messages.
pub const ADDRESS_FORM: &str =
    "HOST:PORT, for example 10.0.0.1:7447, [fd00::1]:7447 or host.example:7447 (port 1-65535; a leading quic/, tls/ or tcp/ is allowed)";

impl Address {
    /// Parses what a user wrote, or says what is wrong with it.
    pub fn parse(text: &str) -> Result<Address, String> {
        let t = text.trim();
        let rest = ["quic/", "tls/", "tcp/"]
            .iter()
            .find_map(|p| t.strip_prefix(p))
            .unwrap_or(t);
        if let Some((scheme, _)) = rest.split_once('/') {
            return Err(format!(
                "`{scheme}/` is not a transport of tiltsim (its links are QUIC)"
            ));
        }
        let (host, port) = split_host_port(rest)?;
        let port = parse_port(port)?;
        Ok(Address {
            host: parse_host(host)?,
            port,
        })
    }

    /// Zenoh's endpoint for this address over QUIC (TLS 1.3 on UDP): a run's link.
    pub fn quic_endpoint(&self) -> String {
        format!("quic/{self}")
    }

    /// Zenoh's endpoint for this address over plain TCP (measurements only: a run's link is
    /// always QUIC).
    pub fn tcp_endpoint(&self) -> String {
        format!("tcp/{self}")
    }

    /// The socket address when the host is numeric.
    pub fn socket_addr(&self) -> Option<std::net::SocketAddr> {
        match &self.host {
            Host::Ip(ip) => Some(std::net::SocketAddr::new(*ip, self.port)),
            Host::Name(_) => None,
        }
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.host {
            Host::Ip(IpAddr::V6(a)) => write!(f, "[{a}]:{}", self.port),
            Host::Ip(IpAddr::V4(a)) => write!(f, "{a}:{}", self.port),
            Host::Name(n) => write!(f, "{n}:{}", self.port),
        }
    }
}

fn split_host_port(s: &str) -> Result<(&str, &str), String> {
    if let Some(v6) = s.strip_prefix('[') {
        let (host, after) = v6
            .split_once(']')
            .ok_or_else(|| format!("`{s}`: an IPv6 address in brackets needs its `]`"))?;
        let port = after
            .strip_prefix(':')
            .ok_or_else(|| format!("`{s}`: no port after the address"))?;
        return Ok((host, port));
    }
    match s.rsplit_once(':') {
        Some((host, _)) if host.contains(':') => Err(format!(
            "`{s}`: an IPv6 address goes in brackets, [ADDRESS]:PORT"
        )),
        Some((host, port)) => Ok((host, port)),
        None => Err(format!("`{s}`: no port (HOST:PORT)")),
    }
}

fn parse_port(p: &str) -> Result<u16, String> {
    match p.parse::<u32>() {
        Ok(n) if (1..=65_535).contains(&n) => Ok(n as u16),
        Ok(n) => Err(format!("port {n} is outside 1-65535")),
        Err(_) => Err(format!("port `{p}` is not a number in 1-65535")),
    }
}

fn parse_host(h: &str) -> Result<Host, String> {
    if h.is_empty() {
        return Err("no host before the port".into());
    }
    if let Ok(a) = h.parse::<Ipv6Addr>() {
        return Ok(Host::Ip(IpAddr::V6(a)));
    }
    let numeric = h.chars().all(|c| c.is_ascii_digit() || c == '.');
    if numeric {
        return h
            .parse::<Ipv4Addr>()
            .map(|a| Host::Ip(IpAddr::V4(a)))
            .map_err(|_| format!("`{h}` is not an IPv4 address (four numbers 0-255)"));
    }
    let label_ok = |l: &str| {
        !l.is_empty()
            && l.len() <= 63
            && !l.starts_with('-')
            && !l.ends_with('-')
            && l.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
    };
    if h.len() <= 253 && h.split('.').all(label_ok) {
        Ok(Host::Name(h.to_string()))
    } else {
        Err(format!(
            "`{h}` is not a host name (letters, digits and `-` between dots)"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_are_read_with_or_without_a_scheme() {
        for (text, shown) in [
            ("10.0.0.1:7447", "10.0.0.1:7447"),
            ("tcp/10.0.0.1:7447", "10.0.0.1:7447"),
            ("tls/10.0.0.1:7447", "10.0.0.1:7447"),
            ("quic/10.0.0.1:7447", "10.0.0.1:7447"),
            ("[::1]:7447", "[::1]:7447"),
            ("tcp/[fd00::1]:1", "[fd00::1]:1"),
            ("host.example:65535", "host.example:65535"),
        ] {
            let a = Address::parse(text).unwrap_or_else(|e| panic!("{text}: {e}"));
            assert_eq!(a.to_string(), shown);
            assert_eq!(a.quic_endpoint(), format!("quic/{shown}"));
        }
    }

    #[test]
    fn bad_addresses_say_what_is_wrong() {
        for (text, says) in [
            ("10.0.0.1", "no port"),
            ("10.0.0.1:0", "port 0 is outside 1-65535"),
            ("10.0.0.1:99999", "port 99999 is outside 1-65535"),
            ("10.0.0.1:http", "port `http` is not a number"),
            ("999.1.1.1:7447", "`999.1.1.1` is not an IPv4 address"),
            ("1.2.3:7447", "`1.2.3` is not an IPv4 address"),
            (":7447", "no host"),
            ("::1:7447", "IPv6 address goes in brackets"),
            ("[::1:7447", "needs its `]`"),
            ("udp/10.0.0.1:7447", "`udp/` is not a transport"),
            ("bad_host:7447", "not a host name"),
        ] {
            let e = Address::parse(text).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }
}
