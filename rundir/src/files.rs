//! Output files written whole or not at all: into a temporary file beside the target, then
//! renamed over it, so a crash or a full disk never leaves a truncated JSON or table behind.

use std::io::Write as _;
use std::path::Path;

/// Writes `bytes` to `path` atomically (temporary file in the same directory, synced, renamed).
/// On error the temporary file is removed and the error names `path`.
pub fn write_atomic(path: &Path, bytes: impl AsRef<[u8]>) -> std::io::Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes.as_ref())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_replaced_whole_and_a_failed_write_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("tiltsim-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("summary.json");
        write_atomic(&p, "{\"a\": 1}\n").unwrap();
        write_atomic(&p, "{\"a\": 2}\n").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "{\"a\": 2}\n");
        // A directory that does not exist: an error naming the file, no temporary left.
        let bad = dir.join("missing").join("x.json");
        let e = write_atomic(&bad, "x").unwrap_err();
        assert!(e.to_string().contains("x.json"), "{e}");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert_eq!(left.len(), 1, "{left:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
