//! `timeseries.csv` read back into rows: whole lines only (a partial last row is never read),
//! one row in memory at a time, or thinned for plots.

use std::fs::File;
use std::path::{Path, PathBuf};

use super::{Row, COLUMNS};

/// Where a run's rows are: its directory's `timeseries.csv`, or kept in memory (a sweep's
/// samples, `tiltsim_master::engine::outputs::Outputs::rows_in_memory`).
#[derive(Debug, Clone, Copy)]
pub enum Rows<'a> {
    /// `timeseries.csv` of this directory.
    File(&'a Path),
    /// The rows themselves.
    Kept(&'a [Row]),
}

impl Rows<'_> {
    /// Hands each row to `visit` in order until it returns false; returns the rows visited
    /// ([`each_row`] for a file).
    pub fn each(&self, mut visit: impl FnMut(&Row) -> bool) -> std::io::Result<u64> {
        match self {
            Rows::File(dir) => each_row(dir, visit),
            Rows::Kept(rows) => {
                let mut n = 0;
                for r in rows.iter() {
                    n += 1;
                    if !visit(r) {
                        break;
                    }
                }
                Ok(n)
            }
        }
    }
}

/// The length of the file's whole lines: the offset just past its last newline. What follows
/// it is a partial row (a run killed in the middle of a write), never read as a row.
pub(super) fn whole_lines_len(file: &mut File) -> std::io::Result<u64> {
    use std::io::{Read as _, Seek as _, SeekFrom};
    let len = file.metadata()?.len();
    let mut end = len;
    let mut buf = vec![0u8; 1 << 16];
    while end > 0 {
        let from = end.saturating_sub(buf.len() as u64);
        file.seek(SeekFrom::Start(from))?;
        let chunk = &mut buf[..(end - from) as usize];
        file.read_exact(chunk)?;
        if let Some(i) = chunk.iter().rposition(|&b| b == b'\n') {
            file.seek(SeekFrom::Start(0))?;
            return Ok(from + i as u64 + 1);
        }
        end = from;
    }
    file.seek(SeekFrom::Start(0))?;
    Ok(0)
}

/// Files whose partial last row was already reported (the analysis reads a file several
/// times: once is enough to say so).
pub(super) static PARTIAL_TOLD: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// A csv reader over the whole lines of the file at `path`: a last line without its newline
/// (a partial row, as a process killed while writing leaves it) is dropped with a warning
/// that gives its size, once per file. Errors name the file.
pub fn whole_lines(path: &Path) -> std::io::Result<csv::Reader<std::io::Take<File>>> {
    use std::io::Read as _;
    let named =
        |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let mut file = File::open(path).map_err(named)?;
    let whole = whole_lines_len(&mut file).map_err(named)?;
    let len = file.metadata().map_err(named)?.len();
    if len > whole {
        let mut told = PARTIAL_TOLD.lock().unwrap_or_else(|p| p.into_inner());
        if !told.iter().any(|p| p == path) {
            told.push(path.to_path_buf());
            tracing::warn!(
                "{}: the last line ({} bytes) has no newline: a partial row, as a run killed while writing leaves it; dropped",
                path.display(),
                len - whole
            );
        }
    }
    Ok(csv::ReaderBuilder::new().from_reader(file.take(whole)))
}

/// Reads `dir/timeseries.csv` back, handing each row to `visit` in order, one row in memory
/// at a time, until `visit` returns false; returns the number of rows read.
///
/// A damaged file is an error naming the file and the line: a row that is not one of this
/// version's (wrong field count, a field that is not a number), or whose step does not follow
/// the one before (rows lost or repeated). The one thing read past is a last line without its
/// newline, as a run killed in the middle of a write leaves it: it is dropped, with a warning
/// that gives its size, since the row it began cannot be known whole.
pub fn each_row(dir: &Path, mut visit: impl FnMut(&Row) -> bool) -> std::io::Result<u64> {
    let path = dir.join("timeseries.csv");
    let named = |what: String| std::io::Error::other(format!("{}: {what}", path.display()));
    let mut rd = whole_lines(&path)?;
    let header = rd.byte_headers().map_err(|e| named(e.to_string()))?;
    if header.iter().ne(COLUMNS.iter().map(|c| c.as_bytes())) {
        return Err(named(format!(
            "the header is not that of this tiltsim version (columns {})",
            COLUMNS.join(",")
        )));
    }
    let mut record = csv::ByteRecord::new();
    let mut n = 0u64;
    let mut previous: Option<u64> = None;
    loop {
        match rd.read_byte_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => {
                let line = e.position().map_or(n + 2, |p| p.line());
                return Err(named(format!("line {line}: {e}")));
            }
        }
        let line = record.position().map_or(n + 2, |p| p.line());
        let Some(row) = Row::read_from(&record) else {
            let what = if record.len() != COLUMNS.len() {
                format!(
                    "{} fields, not the {} of this version",
                    record.len(),
                    COLUMNS.len()
                )
            } else {
                let bad = record
                    .iter()
                    .position(|f| {
                        std::str::from_utf8(f)
                            .ok()
                            .and_then(|t| t.parse::<f64>().ok())
                            .is_none()
                    })
                    .map_or("a field", |i| COLUMNS[i]);
                format!("`{bad}` does not hold a number of its column's type")
            };
            return Err(named(format!("line {line}: {what}")));
        };
        if let Some(p) = previous {
            if p.checked_add(1) != Some(row.step) {
                return Err(named(format!(
                    "line {line}: step {} follows step {p} (rows lost, repeated or out of order)",
                    row.step
                )));
            }
        }
        previous = Some(row.step);
        n += 1;
        if !visit(&row) {
            break;
        }
    }
    Ok(n)
}

/// The rows of `dir/timeseries.csv` to draw, at most about `points` of them: every row when
/// there are few enough, otherwise the field-wise minimum and maximum of each of `points / 2`
/// consecutive blocks (a min/max envelope, so a peak is never lost to the decimation). Memory
/// stays bounded for runs of any length.
pub fn rows_to_plot(dir: &Path, points: usize) -> std::io::Result<Vec<Row>> {
    // The block size comes from the complete lines (a partial last line has no newline), so
    // the rows are parsed once; a file cut short by a bad row still gets its last block.
    let n = complete_lines(&dir.join("timeseries.csv"))?.saturating_sub(1) as usize;
    if n <= points {
        return read_rows(dir);
    }
    let block = n.div_ceil((points / 2).max(1));
    let mut out = Vec::with_capacity(2 * n.div_ceil(block));
    let mut k = 0usize;
    let (mut lo, mut hi) = (Row::default(), Row::default());
    each_row(dir, |r| {
        if k.is_multiple_of(block) {
            (lo, hi) = (*r, *r);
        }
        r.widen(&mut lo, &mut hi);
        k += 1;
        if k.is_multiple_of(block) {
            // Each pair keeps its block's time span in order.
            out.push(lo);
            out.push(hi);
        }
        !tiltsim_rundir::signals::received()
    })?;
    if !k.is_multiple_of(block) {
        out.push(lo);
        out.push(hi);
    }
    Ok(out)
}

/// The newlines in the file at `path`: its complete lines, counted without parsing them.
pub(super) fn complete_lines(path: &Path) -> std::io::Result<u64> {
    use std::io::Read as _;
    let named =
        |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let mut file = File::open(path).map_err(named)?;
    let mut buf = vec![0u8; 1 << 16];
    let mut lines = 0u64;
    loop {
        match file.read(&mut buf) {
            Ok(0) => return Ok(lines),
            Ok(got) => lines += buf[..got].iter().filter(|&&b| b == b'\n').count() as u64,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(named(e)),
        }
    }
}

/// Reads `dir/timeseries.csv` back into rows (for short runs; [`each_row`] for any length).
pub fn read_rows(dir: &Path) -> std::io::Result<Vec<Row>> {
    let mut rows = Vec::new();
    each_row(dir, |r| {
        rows.push(*r);
        true
    })?;
    Ok(rows)
}
