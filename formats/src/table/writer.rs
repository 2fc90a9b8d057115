//! [`Recorder`]: the rows streamed to `timeseries.csv` as the run goes, in batches of whole
//! rows, or kept in memory for a sweep's sample.

use std::fs::File;
use std::path::{Path, PathBuf};

use super::{Row, COLUMNS};

/// Rows per batch: each batch is one `write` of whole rows ending on a newline.
pub(super) const BATCH_ROWS: u64 = 1000;

/// The batch being formatted, in memory under the csv writer (which hands it over in pieces as
/// its own buffer fills; the file gets it whole at [`Recorder::commit`]).
pub(super) struct Batch(std::cell::RefCell<Vec<u8>>);

impl std::io::Write for Batch {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.get_mut().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Streams rows to `timeseries.csv`: the header at once, then rows in batches of
/// [`BATCH_ROWS`] (and at [`Recorder::finish`]), each batch formatted in memory and handed to
/// the system in one write that ends on a newline. The file only ever holds the header and
/// complete rows (a process killed in the middle of that one write may leave part of it: a
/// last line without its newline, which the readers drop with a warning), and
/// [`Recorder::rows_on_disk`] counts exactly those: a write that fails (a full disk, a
/// file-size limit) cuts the file back to the end of the last batch that was written whole,
/// and every error names the file and what the system said.
pub struct Recorder {
    out: csv::Writer<Batch>,
    file: File,
    path: PathBuf,
    rows: u64,
    on_disk_rows: u64,
    on_disk_bytes: u64,
    failed: Option<(std::io::ErrorKind, String)>,
    record: csv::ByteRecord,
    buf: String,
}

impl Recorder {
    /// Creates `path` and writes the header (written at once: a run killed at any point
    /// leaves a valid header).
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let named =
            |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
        let file = File::create(path).map_err(named)?;
        let out = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Batch(std::cell::RefCell::new(Vec::with_capacity(1 << 20))));
        let mut r = Recorder {
            out,
            file,
            path: path.to_path_buf(),
            rows: 0,
            on_disk_rows: 0,
            on_disk_bytes: 0,
            failed: None,
            record: csv::ByteRecord::new(),
            buf: String::with_capacity(32),
        };
        let header = r.out.write_record(COLUMNS).map_err(std::io::Error::other);
        header.and_then(|_| r.commit()).map_err(|e| r.fail(e))?;
        Ok(r)
    }

    /// Appends one row.
    pub fn write(&mut self, row: &Row) -> std::io::Result<()> {
        if let Some((kind, msg)) = &self.failed {
            return Err(std::io::Error::new(*kind, msg.clone()));
        }
        row.write_into(&mut self.record, &mut self.buf);
        if let Err(e) = self.out.write_byte_record(&self.record) {
            return Err(self.fail(csv_io(e)));
        }
        self.rows += 1;
        if self.rows.is_multiple_of(BATCH_ROWS) {
            self.commit().map_err(|e| self.fail(e))?;
        }
        Ok(())
    }

    /// Writes the batch held in memory in one write; the file then ends with the last row.
    pub(super) fn commit(&mut self) -> std::io::Result<()> {
        use std::io::Write as _;
        // Into the batch buffer (memory: cannot fail short), then to the file at once.
        self.out.flush()?;
        let mut batch = self.out.get_ref().0.borrow_mut();
        self.file.write_all(&batch)?;
        self.on_disk_bytes += batch.len() as u64;
        batch.clear();
        drop(batch);
        self.on_disk_rows = self.rows;
        Ok(())
    }

    /// After a failed write: cuts the file back to its last complete row, refuses every later
    /// write and returns the error, naming the file.
    pub(super) fn fail(&mut self, e: std::io::Error) -> std::io::Error {
        if self.failed.is_none() {
            self.out.get_ref().0.borrow_mut().clear();
            let _ = self.file.set_len(self.on_disk_bytes);
            self.failed = Some((e.kind(), format!("{}: {e}", self.path.display())));
        }
        let (kind, msg) = self.failed.clone().unwrap_or((e.kind(), e.to_string()));
        std::io::Error::new(kind, msg)
    }

    /// Complete rows in the file (all of them after a successful [`Recorder::finish`]).
    pub fn rows_on_disk(&self) -> u64 {
        self.on_disk_rows
    }

    /// Writes the rows still held. On error the file keeps its header and every complete
    /// row of the batches written before, and the error names the file.
    pub fn finish(&mut self) -> std::io::Result<()> {
        if let Some((kind, msg)) = &self.failed {
            return Err(std::io::Error::new(*kind, msg.clone()));
        }
        self.commit().map_err(|e| self.fail(e))
    }
}

/// The I/O error inside a csv error (the csv writer's errors on writing are I/O errors).
pub(super) fn csv_io(e: csv::Error) -> std::io::Error {
    match e.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => std::io::Error::other(format!("{other:?}")),
    }
}
