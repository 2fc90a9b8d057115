//! Helpers shared by tiltsim's integration tests (`tests/{models,cli,faults,outside}/`).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The workspace root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A scenario shipped in `scenarios/`.
pub fn scenario(name: &str) -> PathBuf {
    root().join("scenarios").join(name)
}

/// The `tiltsim` executable built by the same `cargo test` invocation (the orchestrator's own
/// integration tests make cargo build it next to the test executables).
pub fn tiltsim() -> PathBuf {
    if let Some(p) = option_env!("CARGO_BIN_EXE_tiltsim") {
        return PathBuf::from(p);
    }
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>");
    let p = dir.join("tiltsim");
    assert!(
        p.exists(),
        "{} not built: run the README's test command (cargo test --release --workspace)",
        p.display()
    );
    p
}

/// A fresh, empty directory for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    static SWEPT: std::sync::Once = std::sync::Once::new();
    let all = std::env::temp_dir().join("tiltsim-tests");
    SWEPT.call_once(|| remove_dirs_of_ended_runs(&all));
    let d = all.join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}

/// Removes the directories under `all` that test processes no longer running made (each name
/// ends in `-<pid>`): a test's directory stays after it for a look at what it wrote, until the
/// next run of the tests, so repeated runs do not fill the disk.
fn remove_dirs_of_ended_runs(all: &std::path::Path) {
    let Ok(entries) = std::fs::read_dir(all) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = name.rsplit('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if !std::path::Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// A unique iceoryx2 prefix for one test.
pub fn prefix(name: &str) -> String {
    format!("tiltsim_test_{}_{}_", name, std::process::id())
}

/// Starts `tiltsim ARGS`, capturing its output.
pub fn spawn(args: &[&str]) -> Child {
    Tiltsim::command(args).spawn()
}

/// Runs `tiltsim ARGS` to completion: (exit code, stdout, stderr).
pub fn run(args: &[&str]) -> (i32, String, String) {
    Tiltsim::command(args).result()
}

/// A `tiltsim` command line, mostly `tiltsim run`, built with a typed method for each common
/// flag of `tiltsim run` (see `tiltsim run --help`) and [`Tiltsim::arg`] for any other:
///
/// ```no_run
/// # use tiltsim_suite::Tiltsim;
/// # let dir = std::path::Path::new("/tmp/out");
/// let out = Tiltsim::run("paper-lqg.toml")
///     .out(dir)
///     .set("controller.mode", "lqg")
///     .transport_in_process()
///     .quiet()
///     .success();
/// ```
///
/// The command starts when one of [`output`](Tiltsim::output), [`result`](Tiltsim::result),
/// [`success`](Tiltsim::success), [`failure`](Tiltsim::failure) or [`spawn`](Tiltsim::spawn)
/// is called; the builder can be run again.
#[derive(Debug, Clone)]
pub struct Tiltsim {
    args: Vec<std::ffi::OsString>,
    envs: Vec<(std::ffi::OsString, std::ffi::OsString)>,
    /// The network namespace the command runs in ([`hosts::Host`]), if not this host's.
    netns: Option<String>,
}

impl Tiltsim {
    /// `tiltsim run SCENARIO`: a shipped scenario by its file name (`paper-lqg.toml`, looked up
    /// in `scenarios/`), or any other path (a relative one with a folder is taken as it is).
    pub fn run(scenario: impl AsRef<Path>) -> Tiltsim {
        let s = scenario.as_ref();
        let s = if s.is_relative() && s.parent() == Some(Path::new("")) {
            self::scenario(&s.to_string_lossy())
        } else {
            s.to_path_buf()
        };
        Tiltsim::command(["run"]).arg(s)
    }

    /// Any other command: `tiltsim ARGS`.
    pub fn command<I, S>(args: I) -> Tiltsim
    where
        I: IntoIterator<Item = S>,
        S: AsRef<std::ffi::OsStr>,
    {
        Tiltsim {
            args: args.into_iter().map(|a| a.as_ref().to_owned()).collect(),
            envs: Vec::new(),
            netns: None,
        }
    }

    /// One more argument as it is.
    pub fn arg(mut self, a: impl AsRef<std::ffi::OsStr>) -> Tiltsim {
        self.args.push(a.as_ref().to_owned());
        self
    }

    /// More arguments as they are.
    pub fn args<I, S>(mut self, args: I) -> Tiltsim
    where
        I: IntoIterator<Item = S>,
        S: AsRef<std::ffi::OsStr>,
    {
        self.args
            .extend(args.into_iter().map(|a| a.as_ref().to_owned()));
        self
    }

    /// An environment variable of the command.
    pub fn env(mut self, key: &str, value: impl AsRef<std::ffi::OsStr>) -> Tiltsim {
        self.envs.push((key.into(), value.as_ref().to_owned()));
        self
    }

    /// `--out DIR`.
    pub fn out(self, dir: impl AsRef<Path>) -> Tiltsim {
        self.arg("--out").arg(dir.as_ref())
    }

    /// `--transport NAME` (`in-process` or `ipc`).
    pub fn transport(self, name: &str) -> Tiltsim {
        self.arg("--transport").arg(name)
    }

    /// `--transport in-process`.
    pub fn transport_in_process(self) -> Tiltsim {
        self.transport("in-process")
    }

    /// `--transport ipc`.
    pub fn transport_ipc(self) -> Tiltsim {
        self.transport("ipc")
    }

    /// `--ipc-prefix PREFIX`: the iceoryx2 file prefix of the run (see [`prefix`]).
    pub fn ipc_prefix(self, prefix: &str) -> Tiltsim {
        self.arg("--ipc-prefix").arg(prefix)
    }

    /// `--master NAME` (`gauss-seidel` or `jacobi`).
    pub fn master(self, name: &str) -> Tiltsim {
        self.arg("--master").arg(name)
    }

    /// `--seed N`.
    pub fn seed(self, seed: impl std::fmt::Display) -> Tiltsim {
        self.arg("--seed").arg(seed.to_string())
    }

    /// `--wait NAME` (`spin`, `adaptive`, `sleep`, `paced`).
    pub fn wait(self, name: &str) -> Tiltsim {
        self.arg("--wait").arg(name)
    }

    /// `--deadline-ms MS`.
    pub fn deadline_ms(self, ms: impl std::fmt::Display) -> Tiltsim {
        self.arg("--deadline-ms").arg(ms.to_string())
    }

    /// `--duration SECONDS` (simulated).
    pub fn duration(self, s: impl std::fmt::Display) -> Tiltsim {
        self.arg("--duration").arg(s.to_string())
    }

    /// `--set KEY=VALUE`: a scenario value by its dotted path.
    pub fn set(self, key: &str, value: impl std::fmt::Display) -> Tiltsim {
        self.arg("--set").arg(format!("{key}={value}"))
    }

    /// `--trace`.
    pub fn trace(self) -> Tiltsim {
        self.arg("--trace")
    }

    /// `--pace FACTOR`.
    pub fn pace(self, factor: impl std::fmt::Display) -> Tiltsim {
        self.arg("--pace").arg(factor.to_string())
    }

    /// `--realtime` (with `--pace`).
    pub fn realtime(self) -> Tiltsim {
        self.arg("--realtime")
    }

    /// `--progress machine`: a JSON line per percent on standard error.
    pub fn progress_machine(self) -> Tiltsim {
        self.arg("--progress").arg("machine")
    }

    /// `--record`.
    pub fn record(self) -> Tiltsim {
        self.arg("--record")
    }

    /// `--free-run`.
    pub fn free_run(self) -> Tiltsim {
        self.arg("--free-run")
    }

    /// `--participant-exe ROLE=PATH`: ROLE served by another executable.
    pub fn participant_exe(self, role: &str, exe: impl AsRef<Path>) -> Tiltsim {
        self.arg("--participant-exe")
            .arg(format!("{role}={}", exe.as_ref().display()))
    }

    /// `-q`: nothing printed but errors.
    pub fn quiet(self) -> Tiltsim {
        self.arg("-q")
    }

    /// The command line, for messages.
    pub fn line(&self) -> String {
        let mut s = String::from("tiltsim");
        for a in &self.args {
            s.push(' ');
            s.push_str(&a.to_string_lossy());
        }
        s
    }

    /// Runs the command on a test host of its own ([`hosts::Host`]).
    pub fn on(mut self, host: &hosts::Host) -> Tiltsim {
        self.netns = Some(host.netns().to_string());
        self
    }

    /// The command, not started: standard input closed, output captured.
    pub fn to_command(&self) -> Command {
        let mut c = match &self.netns {
            Some(ns) => {
                let mut c = Command::new(hosts::ip());
                c.args(["netns", "exec", ns]).arg(tiltsim());
                c
            }
            None => Command::new(tiltsim()),
        };
        c.args(&self.args)
            .envs(self.envs.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        c
    }

    /// Starts the command.
    pub fn spawn(&self) -> Child {
        self.to_command()
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", self.line()))
    }

    /// Runs the command to its end.
    pub fn output(&self) -> std::process::Output {
        self.to_command()
            .output()
            .unwrap_or_else(|e| panic!("{}: {e}", self.line()))
    }

    /// Runs the command to its end: (exit code, stdout, stderr).
    pub fn result(&self) -> (i32, String, String) {
        let out = self.output();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }

    /// Runs the command, which must succeed (the command line and its standard error
    /// otherwise); its output.
    pub fn success(&self) -> std::process::Output {
        let out = self.output();
        assert!(
            out.status.success(),
            "{} ended with {}:\n{}",
            self.line(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }

    /// Runs the command, which must end with exit `code` (the command line and its standard
    /// error otherwise); its standard error.
    pub fn failure(&self, code: i32) -> String {
        let (got, _, err) = self.result();
        assert_eq!(
            got,
            code,
            "{} ended with exit {got}, not {code}:\n{err}",
            self.line()
        );
        err
    }
}

/// Child processes of `pid` as (pid, comm), read from /proc.
pub fn children_of(pid: u32) -> Vec<(u32, String)> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return out;
    };
    for e in entries.flatten() {
        let Ok(p) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{p}/stat")) else {
            continue;
        };
        // pid (comm) state ppid ...
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let comm = stat[open + 1..close].to_string();
        let ppid = stat[close + 2..]
            .split_whitespace()
            .nth(1)
            .and_then(|v| v.parse::<u32>().ok());
        if ppid == Some(pid) {
            out.push((p, comm));
        }
    }
    out
}

/// Waits until `f` returns `Some`, at most `limit`.
pub fn wait_for<T>(limit: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        if let Some(v) = f() {
            return Some(v);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    None
}

/// Waits for a child with a time limit; kills it and panics past the limit (a test must never hang).
pub fn wait_with_limit(mut child: Child, limit: Duration) -> (i32, String, String) {
    let t0 = Instant::now();
    loop {
        if let Ok(Some(_)) = child.try_wait() {
            let out = child.wait_with_output().expect("output");
            return (
                out.status.code().unwrap_or(-1),
                String::from_utf8_lossy(&out.stdout).into_owned(),
                String::from_utf8_lossy(&out.stderr).into_owned(),
            );
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("tiltsim did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The records of a CSV text, the header first, read with the `csv` crate (fields quoted
/// where they hold commas are read whole).
pub fn csv_table(text: &str) -> Vec<Vec<String>> {
    let mut rd = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(text.as_bytes());
    rd.records()
        .map(|r| {
            r.expect("a CSV record")
                .iter()
                .map(str::to_string)
                .collect()
        })
        .collect()
}

/// A recorded time series.
pub struct Series {
    /// Column names.
    pub header: Vec<String>,
    /// Rows of numbers.
    pub rows: Vec<Vec<f64>>,
}

impl Series {
    /// Reads `timeseries.csv` (with the `csv` crate).
    pub fn read(path: &Path) -> Series {
        let text =
            std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut t = csv_table(&text);
        let header = t.remove(0);
        let rows = t
            .iter()
            .map(|r| r.iter().map(|v| v.parse().expect("number")).collect())
            .collect();
        Series { header, rows }
    }
    /// One column.
    pub fn col(&self, name: &str) -> Vec<f64> {
        let i = self
            .header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name}"));
        self.rows.iter().map(|r| r[i]).collect()
    }
}

/// A copy of the shipped scenario `file` with `from` replaced by `to` (which must occur),
/// written to a fresh directory named after `name`.
pub fn scenario_with(file: &str, from: &str, to: &str, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(scenario(file)).expect("scenario file");
    assert!(text.contains(from), "{file} has no `{from}`");
    let p = temp_dir(&format!("{name}-scenario")).join(file);
    std::fs::write(&p, text.replace(from, to)).expect("write scenario");
    p
}

/// Runs scenario file `path` in-process into a fresh directory named after `name` and returns
/// the run directory; the run must complete.
pub fn run_in_process(name: &str, path: &Path) -> PathBuf {
    let out = temp_dir(name).join("out");
    Tiltsim::run(path)
        .out(&out)
        .transport_in_process()
        .quiet()
        .success();
    out
}

/// Reads `summary.json`.
pub fn summary(dir: &Path) -> serde_json::Value {
    let p = dir.join("summary.json");
    serde_json::from_str(
        &std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())),
    )
    .expect("json")
}

/// Files the run with `prefix` left in shared memory or the iceoryx2 directories.
pub fn leftovers(prefix: &str) -> Vec<PathBuf> {
    cosim::ipc::leftover_files(prefix)
}

/// The Python of the outside checks' environment (FMPy, libcosimpy, pythonfmu, mcap, rerun-sdk from PyPI), made by
/// `scripts/fmi-venv.sh` in `target/fmi-venv` the first time a test needs it. Concurrent
/// tests wait for one another (a lock file); a failure to make it fails the test, never skips.
pub fn fmi_python() -> PathBuf {
    static MADE: std::sync::Mutex<Option<PathBuf>> = std::sync::Mutex::new(None);
    let mut made = MADE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = made.as_ref() {
        return p.clone();
    }
    let target = tiltsim()
        .parent()
        .and_then(Path::parent)
        .expect("target/")
        .to_path_buf();
    let venv = target.join("fmi-venv");
    let lock = std::fs::File::create(target.join("fmi-venv.lock")).expect("lock file");
    // SAFETY: flock on an open file descriptor.
    unsafe { libc::flock(std::os::fd::AsRawFd::as_raw_fd(&lock), libc::LOCK_EX) };
    let out = Command::new("bash")
        .arg(root().join("scripts/fmi-venv.sh"))
        .arg(&venv)
        .output()
        .expect("run scripts/fmi-venv.sh");
    assert!(
        out.status.success(),
        "scripts/fmi-venv.sh could not make the outside checks' environment {} (the tools of \
         scripts/fmi-requirements.txt from PyPI; it needs python3 with venv and pip):\n{}",
        venv.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let py = venv.join("bin/python");
    *made = Some(py.clone());
    py
}

/// Runs a program of the outside checks' environment (`python`, `pythonfmu`, `rerun`) with
/// `args`: (exit code, stdout, stderr). A program or a Python module that is not there fails
/// the test naming it and how to install it (`scripts/fmi-requirements.txt`,
/// `scripts/fmi-venv.sh`), never skips it.
pub fn fmi_tool(tool: &str, args: &[&str]) -> (i32, String, String) {
    let py = fmi_python();
    let bin = py.with_file_name(tool);
    let venv = py.parent().and_then(Path::parent).expect("the environment");
    let install = format!(
        "install the outside tools of scripts/fmi-requirements.txt with `bash scripts/fmi-venv.sh {}`",
        venv.display()
    );
    assert!(
        bin.exists(),
        "`{tool}` is missing from {}: {install}",
        venv.display()
    );
    let out = Command::new(&bin)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{} does not start ({e}): {install}", bin.display()));
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    if let Some(line) = err.lines().find(|l| l.starts_with("ModuleNotFoundError")) {
        panic!("`{tool}` lacks a Python module ({line}): {install}");
    }
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        err,
    )
}

/// Arguments of a small Monte Carlo sweep (seed 3, one job) of scenario `sc` into `out`,
/// of `samples` samples, the shard `shard` of them if given.
pub fn mc_args(sc: &str, out: &Path, samples: &str, shard: Option<&str>) -> Vec<String> {
    let mut a: Vec<String> = [
        "sweep",
        sc,
        "--samples",
        samples,
        "--seed",
        "3",
        "--jobs",
        "1",
        "--out",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.push(out.display().to_string());
    a.push("--quiet".into());
    if let Some(s) = shard {
        a.extend(["--shard".into(), s.into()]);
    }
    a
}

/// [`run`] with owned arguments.
pub fn run_strings(a: &[String]) -> (i32, String, String) {
    let refs: Vec<&str> = a.iter().map(String::as_str).collect();
    run(&refs)
}

/// Copies the directory tree `from` to `to`.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

/// CPU hogs (`yes` processes) running for as long as the value lives: load for tests that
/// must pass on a busy machine.
pub struct Hogs(Vec<Child>);

impl Hogs {
    /// Starts `n` hogs.
    pub fn start(n: usize) -> Hogs {
        Hogs(
            (0..n)
                .map(|_| {
                    Command::new("yes")
                        .stdin(Stdio::null())
                        .stdout(Stdio::null())
                        .stderr(Stdio::null())
                        .spawn()
                        .expect("start a CPU hog (yes)")
                })
                .collect(),
        )
    }
}

impl Drop for Hogs {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

pub mod hosts;
/// The house rule on the size of files and functions, kept by a test.
#[cfg(test)]
mod shape;
