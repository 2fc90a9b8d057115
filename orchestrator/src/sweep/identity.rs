//! What a sweep's kept and written files are checked against: the build of the program that
//! computed them, the plan's fingerprint and each file's checksum.
//!
//! **Build identity**: the package version and the SHA-256 of the running executable's bytes
//! (`/proc/self/exe`, the file this process was started from even if it has been replaced
//! since). Any change that can change a result (source, dependencies, compiler, flags) changes
//! the bytes; a rebuild that changes nothing keeps them. It is computed once per sweep, with
//! the CPU's SHA extensions where it has them (`sha2`), in tens of milliseconds for the
//! ~100 MB release executable (debug information included): nothing next to a sweep's runs.
//! A build-time id (`build.rs`) would cost nothing at run time but only know the sources it is
//! told to watch; the executable's bytes miss nothing.
//!
//! **Fingerprint**: SHA-256 of the base scenario (TOML as written to `scenario.toml`), the
//! plan (JSON) and the build identity. It does not depend on the shard, so every shard of a
//! sweep and the whole sweep share it.

use std::io::Read as _;
use std::sync::OnceLock;

use sha2::{Digest as _, Sha256};

use super::Plan;

/// Lower-case hex of a digest.
fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    bytes.iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// SHA-256 of `bytes` in hex.
pub fn sha256(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hash_file(path: &str) -> std::io::Result<String> {
    let mut f = std::fs::File::open(path)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(hex(&h.finalize()))
}

/// This program's build identity, `tiltsim VERSION sha256:HEX` (computed once).
pub fn build() -> &'static str {
    static BUILD: OnceLock<String> = OnceLock::new();
    BUILD.get_or_init(|| {
        let version = env!("CARGO_PKG_VERSION");
        let t0 = std::time::Instant::now();
        match hash_file("/proc/self/exe") {
            Ok(h) => {
                tracing::debug!(
                    "build identity: sha256 of the executable in {:.1} ms",
                    t0.elapsed().as_secs_f64() * 1e3
                );
                format!("tiltsim {version} sha256:{h}")
            }
            // Without its bytes the identity cannot tell builds apart: it then never equals a
            // recorded one, so nothing is resumed from an unknown build.
            Err(e) => {
                tracing::warn!("the executable could not be read for its build identity ({e}); kept samples are not reused");
                format!("tiltsim {version} unreadable:{}", std::process::id())
            }
        }
    })
}

/// The fingerprint of a sweep: its base scenario's TOML text, plan and build.
pub fn fingerprint(scenario_toml: &str, plan: &Plan, build: &str) -> String {
    let mut h = Sha256::new();
    h.update(b"tiltsim sweep fingerprint 1\n");
    h.update(build.as_bytes());
    h.update(b"\n");
    h.update(serde_json::to_string(plan).unwrap_or_default().as_bytes());
    h.update(b"\n");
    h.update(scenario_toml.as_bytes());
    hex(&h.finalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_digest_is_sha256_and_the_fingerprint_depends_on_every_part() {
        // FIPS 180-2 test vector "abc".
        assert_eq!(
            sha256(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let plan = Plan::Grid {
            key: "vehicle.m_v".into(),
            values: vec![1.0, 2.0],
        };
        let other = Plan::Grid {
            key: "vehicle.m_v".into(),
            values: vec![1.0, 3.0],
        };
        let f = fingerprint("a = 1", &plan, "b1");
        assert_eq!(f, fingerprint("a = 1", &plan, "b1"));
        assert_ne!(f, fingerprint("a = 2", &plan, "b1"));
        assert_ne!(f, fingerprint("a = 1", &other, "b1"));
        assert_ne!(f, fingerprint("a = 1", &plan, "b2"));
        assert!(build().starts_with("tiltsim ") && build().contains("sha256:"));
    }
}
