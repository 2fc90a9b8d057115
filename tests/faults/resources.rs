//! Bounded resources and honest outputs: rows that stay short over any run length,
//! a full disk named as such with the summary's counts equal to what is on disk and nothing
//! left in shared memory, and runs whose outputs cannot fit refused before they start.

use std::path::Path;
use std::time::Duration;

use tiltsim_suite::{leftovers, prefix, scenario, scenario_with, temp_dir, wait_for, Tiltsim};

/// Longest field `put_f64` writes: sign, 17 significant digits, point, `e-` and 3 digits.
const LONGEST_FIELD: usize = 24;

#[test]
fn a_long_passive_run_reaches_tiny_values_and_its_rows_stay_short() {
    // The passive body's transients decay without end: by 326 s a state is below 1e-100,
    // which the positional form would print with more than 100 characters.
    let out = temp_dir("long-passive").join("out");
    Tiltsim::run("paper-passive.toml")
        .out(&out)
        .transport_in_process()
        .duration(340)
        .quiet()
        .success();
    let text = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let columns = header.split(',').count();
    let (mut tiniest, mut rows) = (0i32, 0usize);
    let (mut early, mut late) = ((0usize, 0usize), (0usize, 0usize));
    for (k, line) in lines.enumerate() {
        rows += 1;
        for f in line.split(',') {
            assert!(f.len() <= LONGEST_FIELD, "row {k}: field {f}");
            if let Some((_, e)) = f.split_once('e') {
                tiniest = tiniest.min(e.parse().unwrap());
            }
        }
        // Widths over the 30th second and over the last 10 s.
        if (30_000..31_000).contains(&k) {
            early = (early.0 + line.len(), early.1 + 1);
        }
        if k >= 330_000 {
            late = (late.0 + line.len(), late.1 + 1);
        }
    }
    // The start time and 340 000 ticks.
    assert_eq!(rows, 340_001);
    assert!(
        tiniest <= -100,
        "the run never reached the tiny-value regime ({tiniest})"
    );
    let (early, late) = (
        early.0 as f64 / early.1 as f64,
        late.0 as f64 / late.1 as f64,
    );
    // Once every state has its 17 digits the width no longer depends on the exponent: the
    // last 10 s are within 10 % of the 30th second (measured 381 and 398 B).
    assert!(
        late <= 1.1 * early,
        "row width grew from {early} to {late} B"
    );
    assert!(late <= (columns * (LONGEST_FIELD + 1)) as f64);
    let _ = std::fs::remove_dir_all(out);
}

/// A file system of `bytes` at `dir`: a tmpfs mounted there. `None` where mounting is not
/// allowed (not root); the caller then uses a file-size limit instead.
struct SmallDisk(std::path::PathBuf);

impl SmallDisk {
    fn mount(dir: &Path, bytes: u64) -> Option<SmallDisk> {
        std::fs::create_dir_all(dir).ok()?;
        let ok = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={bytes}")])
            .arg("tmpfs")
            .arg(dir)
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then(|| SmallDisk(dir.to_path_buf()))
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(&self.0).status();
    }
}

/// Complete rows of a `timeseries.csv`: every line ends with a newline and has the header's
/// number of fields.
fn complete_rows(path: &Path) -> u64 {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.is_empty() || text.ends_with('\n'),
        "a partial row is on disk"
    );
    let mut lines = text.lines();
    let n = lines.next().map_or(0, |h| h.split(',').count());
    lines
        .inspect(|l| assert_eq!(l.split(',').count(), n, "incomplete row {l}"))
        .count() as u64
}

#[test]
fn a_full_disk_is_named_the_summary_counts_what_is_on_disk_and_nothing_leaks() {
    let root = temp_dir("full-disk");
    let mnt = root.join("disk");
    let pfx = prefix("full-disk");
    let sc = scenario("paper-passive.toml");
    // A 16 MB disk: a 30 s run's outputs are estimated at 12.7 MB, which fits (with a
    // warning); paced at 5x real time so that the disk can be filled while it runs.
    let Some(disk) = SmallDisk::mount(&mnt, 16 << 20) else {
        return full_disk_by_file_size_limit(&root);
    };
    let out = mnt.join("out");
    let mut child = Tiltsim::run(&sc)
        .out(&out)
        .transport_ipc()
        .ipc_prefix(&pfx)
        .duration(30)
        .pace(5)
        .quiet()
        .spawn();
    let csv = out.join("timeseries.csv");
    let started = wait_for(Duration::from_secs(30), || {
        (std::fs::metadata(&csv).ok()?.len() > 100_000).then_some(())
    });
    if started.is_none() {
        let _ = child.kill();
        let _ = child.wait();
        panic!("the run did not start writing within 30 s");
    }
    // Another writer fills the disk, leaving 64 kB.
    let free = tiltsim_rundir::budget::free_bytes(&mnt).unwrap();
    let filler = vec![0u8; (free - (64 << 10)) as usize];
    let _ = std::fs::write(mnt.join("filler"), &filler);
    let (code, _, err) = tiltsim_suite::wait_with_limit(child, Duration::from_secs(120));
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("timeseries.csv") && err.contains("No space left on device"),
        "the error must name the file and the system's error: {err}"
    );
    // The recorder cut the file back to whole rows; the summary was written in the space that
    // freed, and counts exactly the ticks on disk (the rows after the start time's).
    let on_disk = complete_rows(&csv);
    let s = tiltsim_suite::summary(&out);
    assert_eq!(s["status"], "failed");
    assert_eq!(s["steps_completed"].as_u64().unwrap() + 1, on_disk);
    assert!(on_disk >= 1000, "{on_disk}");
    assert!(
        s["error"].as_str().unwrap().contains("timeseries.csv"),
        "{}",
        s["error"]
    );
    assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
    // No temporary file of an atomic write is left behind.
    let stray: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(stray.is_empty(), "{stray:?}");
    drop(disk);
}

/// Where no tmpfs can be mounted: the same run under a file-size limit (SIGXFSZ ignored, so a
/// write past the limit fails with EFBIG), in-process so that shared memory is not limited.
fn full_disk_by_file_size_limit(root: &Path) {
    use std::os::unix::process::CommandExt;
    eprintln!("no tmpfs could be mounted: using a 1 MB file-size limit");
    let out = root.join("out");
    let mut cmd = Tiltsim::run("paper-passive.toml")
        .out(&out)
        .transport_in_process()
        .quiet()
        .to_command();
    // SAFETY: setrlimit and signal are async-signal-safe; nothing else runs in the child.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: 1 << 20,
                rlim_max: 1 << 20,
            };
            libc::setrlimit(libc::RLIMIT_FSIZE, &lim);
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let o = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("timeseries.csv") && err.contains("too large"),
        "{err}"
    );
    let on_disk = complete_rows(&out.join("timeseries.csv"));
    let s = tiltsim_suite::summary(&out);
    assert_eq!(s["steps_completed"].as_u64().unwrap(), on_disk);
}

#[test]
fn a_run_whose_outputs_cannot_fit_is_refused_with_its_estimate() {
    // 10 µs steps for an hour: 3.6e8 rows of about 410 B (the ideal actuator), 147.6 GB.
    // `validate` reads a file and takes no `--set`: the file itself is edited.
    let p = scenario_with(
        "paper-passive.toml",
        "dt_s = 0.001          # base tick = plant step (s)",
        "dt_s = 0.00001\nduration_s = 3600.0",
        "huge",
    );
    let (code, out, err) = tiltsim_suite::run(&["validate", p.to_str().unwrap()]);
    assert!(
        out.contains("147.6 GB") && out.contains("360000000 rows"),
        "{out}"
    );
    let free = tiltsim_rundir::budget::free_bytes(Path::new("out")).unwrap();
    if free < 147_600_000_000 {
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains("paper-passive.toml")
                && err.contains("360000000 steps")
                && err.contains("147.6 GB")
                && err.contains("run.dt_s"),
            "{err}"
        );
    } else {
        // A disk this large takes it, with a warning above a quarter of its free space.
        assert_eq!(code, 0, "{err}");
        assert_eq!(err.contains("warning"), free < 4 * 147_600_000_000, "{err}");
    }
}

/// Bytes of every file under `dir`.
fn bytes_under(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| {
            let m = e.metadata().unwrap();
            if m.is_dir() {
                bytes_under(&e.path())
            } else {
                m.len()
            }
        })
        .sum()
}

#[test]
fn the_output_estimate_covers_what_a_switched_drive_run_with_record_and_trace_writes() {
    // paper-lqg drives the bar with the switched BLDC model, whose rows are the widest
    // (about 600 B); --record and --trace add run.mcap and trace.csv.
    let sc = scenario("paper-lqg.toml");
    let out = temp_dir("estimate").join("out");
    Tiltsim::run(&sc)
        .out(&out)
        .transport_in_process()
        .record()
        .trace()
        .quiet()
        .success();
    let s = tiltsim_scenario::scenario::Scenario::load(&sc).unwrap();
    let e = tiltsim_rundir::budget::estimate(
        &s,
        tiltsim_rundir::budget::Extras {
            trace: true,
            record: true,
        },
    );
    let written = bytes_under(&out);
    // Never below what is written (a run it lets start must fit), and not so far above that
    // it refuses runs that would fit: the per-row figures are 10 % above the widest
    // measured, the fixed part rounds the figures up, so within 25 % (measured 13 %).
    assert!(
        e.bytes >= written && (e.bytes as f64) <= 1.25 * written as f64,
        "estimate {} B, written {written} B",
        e.bytes
    );
    let _ = std::fs::remove_dir_all(out);
}
