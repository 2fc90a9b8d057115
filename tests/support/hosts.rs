//! Hosts for tests of participants on other machines: network namespaces joined by a veth
//! link, made by the test and removed when it ends. Each pair has addresses of its own inside
//! its namespaces only, so no test ever addresses anything but its own hosts. Needs root and
//! `ip` (iproute2); without them the test fails saying what to install.

use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

/// The `ip` program (iproute2), or a failure that says how to get it.
pub fn ip() -> PathBuf {
    for dir in ["/usr/sbin", "/sbin", "/usr/bin", "/bin"] {
        let p = PathBuf::from(dir).join("ip");
        if p.exists() {
            return p;
        }
    }
    panic!(
        "the network tests need `ip` from iproute2 to make their own hosts: install it \
         (Debian/Ubuntu: apt-get install iproute2) and run the tests as root"
    );
}

fn ip_run(args: &[&str]) -> Result<(), String> {
    let out = Command::new(ip())
        .args(args)
        .output()
        .map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// Removes the hosts of test processes that were killed before they could remove their own
/// (`tiltsim-<pid>-...` where no process `pid` runs).
fn remove_dead_hosts() {
    let Ok(out) = Command::new(ip()).args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let name = line.split_whitespace().next().unwrap_or("");
        let Some(pid) = name
            .strip_prefix("tiltsim-")
            .and_then(|r| r.split('-').next())
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if !std::path::Path::new(&format!("/proc/{pid}")).exists() {
            let _ = ip_run(&["netns", "del", name]);
        }
    }
}

/// One host: a network namespace with one end of the pair's link.
#[derive(Debug)]
pub struct Host {
    netns: String,
    link: String,
    address: String,
}

impl Host {
    /// The namespace's name (`ip netns exec NAME ...`).
    pub fn netns(&self) -> &str {
        &self.netns
    }

    /// Its address on the link.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// An address on this host, `HOST:PORT`.
    pub fn endpoint(&self, port: u16) -> String {
        format!("{}:{port}", self.address)
    }

    /// Takes its end of the link down (a cut cable) or up again.
    pub fn set_link(&self, up: bool) {
        ip_run(&[
            "netns",
            "exec",
            &self.netns,
            "ip",
            "link",
            "set",
            &self.link,
            if up { "up" } else { "down" },
        ])
        .unwrap_or_else(|e| panic!("{e}"));
    }
}

/// Two hosts joined by one link: `a` (10.201.N.1) and `b` (10.201.N.2).
#[derive(Debug)]
pub struct Pair {
    /// The first host (the orchestrator's, in the tests).
    pub a: Host,
    /// The second host.
    pub b: Host,
}

impl Pair {
    /// Makes the two namespaces and the link between them; `tag` names them in `ip netns`.
    pub fn new(tag: &str) -> Pair {
        static N: AtomicU32 = AtomicU32::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        remove_dead_hosts();
        let pid = std::process::id();
        let id = format!("{}{n}", pid % 100_000);
        let ns = |side: &str| format!("tiltsim-{pid}-{n}-{tag}{side}");
        // Interface names are at most 15 bytes.
        let link = |side: &str| format!("ts{id}{side}");
        let pair = Pair {
            a: Host {
                netns: ns("a"),
                link: link("a"),
                address: format!("10.201.{}.1", n % 250),
            },
            b: Host {
                netns: ns("b"),
                link: link("b"),
                address: format!("10.201.{}.2", n % 250),
            },
        };
        if let Err(e) = pair.make() {
            panic!(
                "cannot make the test's hosts ({e}): the network tests make network \
                 namespaces and must run as root (or with CAP_NET_ADMIN and CAP_SYS_ADMIN)"
            );
        }
        pair
    }

    fn make(&self) -> Result<(), String> {
        for h in [&self.a, &self.b] {
            ip_run(&["netns", "add", &h.netns])?;
            ip_run(&["netns", "exec", &h.netns, "ip", "link", "set", "lo", "up"])?;
        }
        ip_run(&[
            "link",
            "add",
            &self.a.link,
            "netns",
            &self.a.netns,
            "type",
            "veth",
            "peer",
            "name",
            &self.b.link,
            "netns",
            &self.b.netns,
        ])?;
        for h in [&self.a, &self.b] {
            let cidr = format!("{}/24", h.address);
            ip_run(&[
                "netns", "exec", &h.netns, "ip", "addr", "add", &cidr, "dev", &h.link,
            ])?;
            ip_run(&[
                "netns", "exec", &h.netns, "ip", "link", "set", &h.link, "up",
            ])?;
        }
        Ok(())
    }
}

impl Drop for Pair {
    fn drop(&mut self) {
        // Deleting a namespace deletes its end of the link, and the link with it.
        for h in [&self.a, &self.b] {
            let _ = ip_run(&["netns", "del", &h.netns]);
        }
    }
}
