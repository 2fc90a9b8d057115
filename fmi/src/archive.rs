//! FMU archives: writing tiltsim's own, opening any (a zip with `modelDescription.xml` and a
//! platform library) into a private directory that is removed when dropped.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use crate::description::{FmiVersion, ModelDescription};

/// The platform directory of this machine's libraries in an FMU of `version`.
pub fn platform_dir(version: FmiVersion) -> &'static str {
    match version {
        FmiVersion::V2 => "linux64",
        FmiVersion::V3 => "x86_64-linux",
    }
}

/// Writes an FMU of `version`: `modelDescription.xml`, the library as
/// `binaries/<platform>/<identifier>.so` and `resources/<name>` files. Written to a
/// temporary name and renamed, so `out` is whole or absent.
pub fn write_fmu(
    version: FmiVersion,
    out: &Path,
    description: &str,
    identifier: &str,
    library: &[u8],
    resources: &[(&str, &[u8])],
) -> std::io::Result<()> {
    let tmp = out.with_extension("fmu.part");
    let result = (|| {
        let f = std::fs::File::create(&tmp)?;
        let mut z = zip::ZipWriter::new(f);
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .last_modified_time(zip::DateTime::default())
            .unix_permissions(0o644);
        let mut put = |name: &str, bytes: &[u8]| -> std::io::Result<()> {
            z.start_file(name, opts).map_err(std::io::Error::other)?;
            z.write_all(bytes)
        };
        put("modelDescription.xml", description.as_bytes())?;
        put(
            &format!("binaries/{}/{identifier}.so", platform_dir(version)),
            library,
        )?;
        for (name, bytes) in resources {
            put(&format!("resources/{name}"), bytes)?;
        }
        z.finish().map_err(std::io::Error::other)?.sync_all()
    })();
    match result {
        Ok(()) => std::fs::rename(&tmp, out),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// The largest `modelDescription.xml` read: a description of 100 000 variables at about
/// 300 B each is 30 MB, so 64 MiB takes any real model, and a larger one (a hostile or
/// damaged archive) is refused before it is read whole, let alone parsed.
pub const MAX_DESCRIPTION_BYTES: u64 = 64 << 20;

/// Reads only the model description of the FMU at `path` (at most
/// [`MAX_DESCRIPTION_BYTES`] of it).
pub fn read_description(path: &Path) -> Result<ModelDescription, String> {
    let f = std::fs::File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    let mut z = zip::ZipArchive::new(f).map_err(|_| "not an FMU: not a zip archive".to_string())?;
    let entry = z
        .by_name("modelDescription.xml")
        .map_err(|_| "not an FMU: no modelDescription.xml in the archive".to_string())?;
    let too_large = || {
        format!(
            "modelDescription.xml: larger than {} MiB, the most tiltsim reads",
            MAX_DESCRIPTION_BYTES >> 20
        )
    };
    // The size the archive declares, then the bytes themselves (a declared size can lie).
    if entry.size() > MAX_DESCRIPTION_BYTES {
        return Err(too_large());
    }
    let mut xml = String::new();
    entry
        .take(MAX_DESCRIPTION_BYTES + 1)
        .read_to_string(&mut xml)
        .map_err(|e| format!("modelDescription.xml: {e}"))?;
    if xml.len() as u64 > MAX_DESCRIPTION_BYTES {
        return Err(too_large());
    }
    ModelDescription::parse(&xml).map_err(|e| format!("modelDescription.xml: {e}"))
}

/// The archive entry of the co-simulation library for this platform; the error lists the
/// libraries the FMU does have.
pub fn library_entry(path: &Path, description: &ModelDescription) -> Result<String, String> {
    let id = description
        .cs_identifier
        .as_deref()
        .ok_or_else(|| "no <CoSimulation> element".to_string())?;
    let f = std::fs::File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    let z = zip::ZipArchive::new(f).map_err(|_| "not an FMU: not a zip archive".to_string())?;
    let want = format!("binaries/{}/{id}.so", platform_dir(description.version));
    if z.index_for_name(&want).is_some() {
        return Ok(want);
    }
    let have: Vec<String> = z
        .file_names()
        .filter_map(|n| n.ok().map(|n| n.to_string()))
        .filter(|n| n.starts_with("binaries/") && !n.ends_with('/'))
        .collect();
    Err(format!(
        "`{want}` is missing; the FMU has {}",
        if have.is_empty() {
            "no binaries".to_string()
        } else {
            have.join(", ")
        }
    ))
}

/// An FMU unpacked into a private directory (removed on drop).
#[derive(Debug)]
pub struct Unpacked {
    /// The directory.
    pub dir: PathBuf,
    /// Its description.
    pub description: ModelDescription,
    /// The co-simulation library for this platform.
    pub library: PathBuf,
}

static UNPACKED: AtomicU64 = AtomicU64::new(0);

/// The flag that stops an unpacking under way (the program's interrupt flag, set by Ctrl-C).
static STOP: OnceLock<Arc<AtomicBool>> = OnceLock::new();

/// What [`Unpacked::open`] says when the flag of [`stop_unpacking_when`] stopped it.
pub const UNPACKING_STOPPED: &str = "unpacking stopped by an interrupt";

/// Makes every unpacking in this process stop, and remove what it unpacked, once `flag` is
/// set (a program's interrupt flag: an FMU with gigabytes of resources otherwise keeps
/// Ctrl-C waiting until it is all written). The first flag given is kept.
pub fn stop_unpacking_when(flag: Arc<AtomicBool>) {
    let _ = STOP.set(flag);
}

fn stopped() -> bool {
    STOP.get().is_some_and(|f| f.load(Ordering::Relaxed))
}

/// Copies `from` into `to` a chunk at a time, giving up between chunks once [`stopped`].
fn copy_until_stopped(
    from: &mut impl Read,
    to: &mut impl Write,
    stop: &dyn Fn() -> bool,
) -> Result<(), String> {
    // 1 MiB: at disk speeds a few milliseconds, so an interrupt is honoured that soon.
    let mut buf = vec![0u8; 1 << 20];
    loop {
        if stop() {
            return Err(UNPACKING_STOPPED.to_string());
        }
        let n = match from.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.to_string()),
        };
        to.write_all(&buf[..n]).map_err(|e| e.to_string())?;
    }
}

impl Unpacked {
    /// Unpacks the FMU at `path`; the error says what is wrong with it (not a zip, no
    /// description, model exchange only, no library for this platform).
    pub fn open(path: &Path) -> Result<Unpacked, String> {
        Self::open_until(path, &stopped)
    }

    /// [`Unpacked::open`], stopping (and removing what it unpacked) once `stop` says so.
    fn open_until(path: &Path, stop: &dyn Fn() -> bool) -> Result<Unpacked, String> {
        let description = read_description(path)?;
        description.cs_identifier.as_ref().ok_or_else(|| {
            if description.has_model_exchange {
                "a model-exchange-only FMU: tiltsim steps co-simulation FMUs (no <CoSimulation> element)".to_string()
            } else {
                "no <CoSimulation> element: not a co-simulation FMU".to_string()
            }
        })?;
        let want = library_entry(path, &description)?;
        let f = std::fs::File::open(path).map_err(|e| format!("cannot open: {e}"))?;
        let mut z =
            zip::ZipArchive::new(f).map_err(|_| "not an FMU: not a zip archive".to_string())?;
        let n = UNPACKED.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!(
            "tiltsim-fmu-{}-{n}-{}",
            std::process::id(),
            description
                .model_name
                .chars()
                .filter(|c| c.is_ascii_alphanumeric())
                .take(40)
                .collect::<String>()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir)
            .map_err(|e| format!("cannot unpack into {}: {e}", dir.display()))?;
        let unpacked = Unpacked {
            library: dir.join(&want),
            dir,
            description,
        };
        for i in 0..z.len() {
            let mut e = z.by_index(i).map_err(|e| format!("damaged archive: {e}"))?;
            let Some(rel) = e.enclosed_name() else {
                return Err(format!(
                    "archive entry `{}` points outside the FMU",
                    e.name().unwrap_or_default()
                ));
            };
            let to = unpacked.dir.join(rel);
            if e.is_dir() {
                std::fs::create_dir_all(&to).map_err(|e| e.to_string())?;
                continue;
            }
            if let Some(p) = to.parent() {
                std::fs::create_dir_all(p).map_err(|e| e.to_string())?;
            }
            let mut out =
                std::fs::File::create(&to).map_err(|e| format!("{}: {e}", to.display()))?;
            copy_until_stopped(&mut e, &mut out, stop).map_err(|why| match why.as_str() {
                UNPACKING_STOPPED => why,
                _ => format!("{}: {why}", to.display()),
            })?;
        }
        Ok(unpacked)
    }

    /// The FMU's `resources` directory.
    pub fn resources(&self) -> PathBuf {
        self.dir.join("resources")
    }
}

/// Removes the unpacked FMUs of processes that no longer exist (a participant process killed
/// before it could remove its own); returns the directories removed.
pub fn remove_dead_unpacked() -> Vec<PathBuf> {
    let mut removed = Vec::new();
    let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) else {
        return removed;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix("tiltsim-fmu-")) else {
            continue;
        };
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if !Path::new(&format!("/proc/{pid}")).exists() && std::fs::remove_dir_all(e.path()).is_ok()
        {
            removed.push(e.path());
        }
    }
    removed
}

impl Drop for Unpacked {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The private directories this process unpacked an FMU named `model` into.
    fn unpacked_dirs(model: &str) -> Vec<PathBuf> {
        let mine = format!("tiltsim-fmu-{}-", std::process::id());
        std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                let n = p.file_name().unwrap().to_string_lossy().into_owned();
                n.starts_with(&mine) && n.ends_with(model)
            })
            .collect()
    }

    #[test]
    fn an_unpacking_stops_between_chunks_and_removes_what_it_wrote() {
        let dir = std::env::temp_dir().join(format!("tiltsim-stop-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fmu = dir.join("stop.fmu");
        let xml = r#"<fmiModelDescription fmiVersion="3.0" modelName="StopTest" instantiationToken="t"><CoSimulation modelIdentifier="stop"/></fmiModelDescription>"#;
        // Five chunks of resource, so a stop after the first leaves work undone.
        let resource = vec![7u8; 5 << 20];
        write_fmu(
            FmiVersion::V3,
            &fmu,
            xml,
            "stop",
            b"lib",
            &[("big.bin", &resource)],
        )
        .unwrap();
        // Unstopped, everything is written.
        let whole = Unpacked::open_until(&fmu, &|| false).unwrap();
        assert_eq!(
            std::fs::read(whole.resources().join("big.bin")).unwrap(),
            resource
        );
        drop(whole);
        // Stopped inside the resource (the description and the library take two looks each,
        // the resource one per chunk read): an error that says why, and nothing left on disk.
        let calls = std::cell::Cell::new(0);
        let stop = || {
            calls.set(calls.get() + 1);
            calls.get() > 6
        };
        let e = Unpacked::open_until(&fmu, &stop).unwrap_err();
        assert_eq!(e, UNPACKING_STOPPED);
        assert!(
            unpacked_dirs("StopTest").is_empty(),
            "{:?}",
            unpacked_dirs("StopTest")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_description_above_the_limit_is_refused_unread_and_one_below_is_parsed() {
        let dir = std::env::temp_dir().join(format!("tiltsim-md-limit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let write = |name: &str, xml: &[u8]| {
            let p = dir.join(name);
            let f = std::fs::File::create(&p).unwrap();
            let mut z = zip::ZipWriter::new(f);
            let o = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Deflated)
                .large_file(true);
            z.start_file("modelDescription.xml", o).unwrap();
            z.write_all(xml).unwrap();
            z.finish().unwrap();
            p
        };
        // One byte over the limit: whitespace after the root element, which any XML
        // parser would accept, so only the limit can refuse it.
        let mut big = b"<fmiModelDescription/>".to_vec();
        big.resize(MAX_DESCRIPTION_BYTES as usize + 1, b' ');
        let e = read_description(&write("big.fmu", &big)).unwrap_err();
        assert!(e.contains("larger than 64 MiB"), "{e}");
        drop(big);
        let small = read_description(&write("small.fmu", b"<fmiModelDescription/>"));
        // Parsed (and refused for what it lacks, not for its size).
        assert!(!small.unwrap_err().contains("larger than"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
