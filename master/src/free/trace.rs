//! The timing trace of a free run, `timing.csv`: one line per consumer step.
//!
//! ```text
//! # tiltsim timing trace: dt_s=0.001 steps=3000 controller_period_ticks=10 start_ns=...
//! role,step,from_plant,from_actuator,from_controller,age_plant,age_actuator,age_controller,due_ns,read_ns,compute_end_ns,publish_ns,late_start,late_finish
//! ```
//!
//! `step` is the consumer's step (a tick index); `from_<producer>` the producer step whose
//! output the step read (`-1` = the output at t₀, empty = not an input of this role);
//! `age_<producer>` that input's age in ticks (see [`age`]); the instants are
//! CLOCK_MONOTONIC ns since the common start instant (`due_ns` = when the step was due).
//! `late_start`: the step started after the next was due (for the plant: a step it had to
//! catch up on); `late_finish`: it was published after the next step was due.

use std::io::Write;
use std::path::Path;

use cosim::Role;

/// The trace's file name beside the results.
pub const TIMING_CSV: &str = "timing.csv";

const COLUMNS: &str = "role,step,from_plant,from_actuator,from_controller,age_plant,age_actuator,age_controller,due_ns,read_ns,compute_end_ns,publish_ns,late_start,late_finish";

/// The inputs each role reads, by producer.
pub fn inputs_of(role: Role) -> &'static [Role] {
    match role {
        Role::Plant => &[Role::Actuator],
        Role::Actuator => &[Role::Controller, Role::Plant],
        Role::Controller => &[Role::Plant],
    }
}

/// Index of a role in the trace's per-producer columns.
pub fn col(role: Role) -> usize {
    match role {
        Role::Plant => 0,
        Role::Actuator => 1,
        Role::Controller => 2,
    }
}

/// The age in ticks of producer step `from` read by consumer step `step`, measured against
/// the lock-step Gauss-Seidel coupling (where it is 0, and `k mod period` for the held
/// controller command): the plant's output of step q
/// holds at t_{q+1}, so its age is `step − (q + 1)`; the actuator's and controller's outputs
/// of step q are used from t_q on, so theirs is `step − q`. The output at t₀ is step −1.
pub fn age(producer: Role, step: u64, from: i64) -> i64 {
    let step = step as i64;
    match producer {
        Role::Plant => step - (from + 1),
        Role::Actuator | Role::Controller => step - from,
    }
}

/// One consumer step of a free run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepTrace {
    /// The consumer.
    pub role: Role,
    /// Its step (tick index).
    pub step: u64,
    /// Producer step read, per producer column ([`col`]); `None` = not an input.
    pub from: [Option<i64>; 3],
    /// When the step was due (ns since the start instant).
    pub due_ns: u64,
    /// When it read its inputs (ns since the start instant).
    pub read_ns: u64,
    /// When its computation ended.
    pub compute_end_ns: u64,
    /// When it published its output.
    pub publish_ns: u64,
}

impl StepTrace {
    /// Started after the next step was due.
    pub fn late_start(&self, period_ns: u64) -> bool {
        self.read_ns >= self.due_ns + period_ns
    }
    /// Published after the next step was due.
    pub fn late_finish(&self, period_ns: u64) -> bool {
        self.publish_ns >= self.due_ns + period_ns
    }
}

/// What a trace was recorded for: checked against the scenario of a replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceHead {
    /// Base tick (s).
    pub dt_s: f64,
    /// Plant steps.
    pub steps: u64,
    /// Controller period in ticks.
    pub controller_period_ticks: u64,
    /// The common start instant (CLOCK_MONOTONIC ns).
    pub start_ns: u64,
}

/// Bytes of whole lines gathered before they are handed to the system in one write.
const TRACE_BATCH: usize = 1 << 16;

/// Writes `timing.csv`, streamed as the orchestrator records the steps: whole lines gathered in
/// memory and written in batches of about [`TRACE_BATCH`] bytes, so the file only ever ends
/// with a complete line (a process killed in the middle of one write may leave part of a last
/// line, which [`read`] drops) and a run killed at any point leaves a prefix of its trace.
pub struct TraceWriter {
    out: std::fs::File,
    buf: Vec<u8>,
    dt_ns: f64,
    period_ticks: u64,
}

fn opt(v: Option<i64>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

impl TraceWriter {
    /// Creates the file with its head line and column names, and holds its lock while it
    /// writes (released when the writer is dropped, or the process ends however it ends):
    /// [`read`] refuses a trace a live run is still writing.
    pub fn create(path: &Path, head: &TraceHead) -> std::io::Result<Self> {
        let mut out = std::fs::File::create(path)?;
        out.try_lock().map_err(|e| match e {
            std::fs::TryLockError::WouldBlock => {
                std::io::Error::other("another process is writing this trace")
            }
            std::fs::TryLockError::Error(e) => e,
        })?;
        writeln!(
            out,
            "# tiltsim timing trace: dt_s={} steps={} controller_period_ticks={} start_ns={}",
            head.dt_s, head.steps, head.controller_period_ticks, head.start_ns
        )?;
        writeln!(out, "{COLUMNS}")?;
        Ok(TraceWriter {
            out,
            buf: Vec::with_capacity(TRACE_BATCH + 256),
            dt_ns: head.dt_s * 1e9,
            period_ticks: head.controller_period_ticks,
        })
    }

    /// Appends one step.
    pub fn push(&mut self, t: &StepTrace) -> std::io::Result<()> {
        let ticks = if t.role == Role::Controller {
            self.period_ticks
        } else {
            1
        };
        let period_ns = (self.dt_ns * ticks as f64).round() as u64;
        let ages: Vec<String> = Role::ALL
            .iter()
            .map(|&p| opt(t.from[col(p)].map(|f| age(p, t.step, f))))
            .collect();
        writeln!(
            self.buf,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            t.role.name(),
            t.step,
            opt(t.from[0]),
            opt(t.from[1]),
            opt(t.from[2]),
            ages[0],
            ages[1],
            ages[2],
            t.due_ns,
            t.read_ns,
            t.compute_end_ns,
            t.publish_ns,
            u8::from(t.late_start(period_ns)),
            u8::from(t.late_finish(period_ns)),
        )?;
        if self.buf.len() >= TRACE_BATCH {
            self.commit()?;
        }
        Ok(())
    }

    fn commit(&mut self) -> std::io::Result<()> {
        self.out.write_all(&self.buf)?;
        self.buf.clear();
        Ok(())
    }

    /// Writes the lines still held.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.commit()
    }
}

/// Why a trace cannot be replayed: the file, the field and what was expected.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {field}: {what}")]
pub struct TraceError {
    /// The trace file.
    pub file: String,
    /// The field (head key, or `line N: column`).
    pub field: String,
    /// What is wrong and what is allowed.
    pub what: String,
}

/// A trace as read: its head, its steps, and, when it holds only the first steps of some
/// role (a free run that failed, was interrupted or killed), what it lacks.
#[derive(Debug, Clone)]
pub struct Trace {
    /// The head line.
    pub head: TraceHead,
    /// The steps, in the order of the file.
    pub steps: Vec<StepTrace>,
    /// `None` for a whole trace; else what is missing, in words.
    pub partial: Option<String>,
}

/// Reads a trace and checks it against the steps a scenario of `dt_s`, `steps` and
/// `controller_period_ticks` has: the head must match, every consumer step may appear at most
/// once, each role's steps must be its first ones without a gap, and every input must name a
/// producer step that exists. A last line cut short (the writer killed in the middle of a
/// write) is dropped; a trace with fewer steps than the scenario is partial.
pub fn read(
    path: &Path,
    dt_s: f64,
    steps: u64,
    controller_period_ticks: u64,
) -> Result<Trace, TraceError> {
    let file = path.display().to_string();
    let text = read_unlocked(path).map_err(|what| trace_error(&file, "file".into(), what))?;
    // A last line without its newline was cut short by a kill: it is not part of the trace.
    let whole = match text.rfind('\n') {
        Some(i) if i + 1 < text.len() => &text[..=i],
        _ => &text[..],
    };
    let cut_short = whole.len() < text.len();
    let mut lines = whole.lines();
    let head_line = lines.next().unwrap_or_default();
    let head = read_head(&file, head_line, dt_s, steps, controller_period_ticks)?;
    if lines.next() != Some(COLUMNS) {
        return Err(no_columns(&file));
    }
    let mut body = Body::new(&file, steps, controller_period_ticks);
    let mut out = Vec::new();
    for (i, line) in lines.enumerate() {
        out.push(body.step(i + 3, line)?);
    }
    let partial = body.partial(cut_short)?;
    check_never_older(&file, &out)?;
    Ok(Trace {
        head,
        steps: out,
        partial,
    })
}

/// Reads a trace as [`read`] does, checks it the same way, and hands each step to `visit` in
/// the order of the file without keeping the steps: the memory needed does not grow with the
/// trace (the figures of an hour-long free run). It also requires each role's steps in
/// ascending order, as [`TraceWriter`] writes them. Returns what a partial trace lacks.
pub fn each_step(
    path: &Path,
    dt_s: f64,
    steps: u64,
    controller_period_ticks: u64,
    mut visit: impl FnMut(&StepTrace),
) -> Result<Option<String>, TraceError> {
    each_step_until(path, dt_s, steps, controller_period_ticks, |t| {
        visit(t);
        std::ops::ControlFlow::Continue(())
    })
}

/// [`each_step`] whose `visit` may stop the reading (`Break`): the steps after are neither
/// read nor checked, and the result is then `None`.
pub fn each_step_until(
    path: &Path,
    dt_s: f64,
    steps: u64,
    controller_period_ticks: u64,
    mut visit: impl FnMut(&StepTrace) -> std::ops::ControlFlow<()>,
) -> Result<Option<String>, TraceError> {
    use std::io::BufRead;
    let file = path.display().to_string();
    let failed = |what: String| trace_error(&file, "file".into(), what);
    let f = std::fs::File::open(path).map_err(|e| failed(e.to_string()))?;
    unlocked(&f).map_err(failed)?;
    let mut input = std::io::BufReader::with_capacity(1 << 16, f);
    let mut line = String::new();
    let mut n = 0usize;
    let mut body = Body::ordered(&file, steps, controller_period_ticks);
    // The last step of each role, for the check that no consumer reads an older sample.
    let mut last: [Option<(usize, StepTrace)>; 3] = [None; 3];
    let mut cut_short = false;
    loop {
        line.clear();
        if input
            .read_line(&mut line)
            .map_err(|e| failed(e.to_string()))?
            == 0
        {
            break;
        }
        let Some(text) = line.strip_suffix('\n') else {
            // A last line without its newline was cut short by a kill.
            cut_short = true;
            break;
        };
        n += 1;
        match n {
            1 => {
                read_head(&file, text, dt_s, steps, controller_period_ticks)?;
            }
            2 if text != COLUMNS => return Err(no_columns(&file)),
            2 => {}
            _ => {
                let t = body.step(n, text)?;
                let slot = &mut last[col(t.role)];
                if let Some((at, before)) = slot {
                    never_older(&file, (*at, before), (n, &t))?;
                }
                *slot = Some((n, t));
                if visit(&t).is_break() {
                    return Ok(None);
                }
            }
        }
    }
    match n {
        0 => read_head(&file, "", dt_s, steps, controller_period_ticks).map(|_| None),
        1 => Err(no_columns(&file)),
        _ => body.partial(cut_short),
    }
}

/// The error of trace `file` whose second line is not the column names.
fn no_columns(file: &str) -> TraceError {
    trace_error(
        file,
        "line 2".into(),
        format!("expected the columns `{COLUMNS}`"),
    )
}

/// A consumer holds the newest sample of each producer that has reached it (samples of a link
/// arrive in order and an older one is never taken after a newer one), so over a consumer's
/// steps the producer step it reads never falls. A trace in which it does (edited, or of
/// another run) cannot have happened: refused, naming the line (the `n`-th step line is line
/// `n + 3`) and the field.
fn check_never_older(file: &str, steps: &[StepTrace]) -> Result<(), TraceError> {
    let mut by_role: [Vec<(u64, usize)>; 3] = Default::default();
    for (i, t) in steps.iter().enumerate() {
        by_role[col(t.role)].push((t.step, i));
    }
    for order in &mut by_role {
        order.sort_unstable();
        for w in order.windows(2) {
            let (before, now) = (&steps[w[0].1], &steps[w[1].1]);
            never_older(file, (w[0].1 + 3, before), (w[1].1 + 3, now))?;
        }
    }
    Ok(())
}

/// Refuses step `now` (on line `now.0`) of a consumer when it read its inputs before its step
/// `before` did, or reads a producer step older than `before` did ([`check_never_older`]).
fn never_older(
    file: &str,
    before: (usize, &StepTrace),
    now: (usize, &StepTrace),
) -> Result<(), TraceError> {
    let ((_, before), (line, now)) = (before, now);
    if now.read_ns < before.read_ns {
        return Err(trace_error(
            file,
            format!("line {line}: read_ns"),
            format!(
                "{} step {} read at {} ns, before its step {} read (at {} ns): a participant \
                 reads its steps' inputs in turn",
                now.role, now.step, now.read_ns, before.step, before.read_ns
            ),
        ));
    }
    for &p in inputs_of(now.role) {
        if let (Some(a), Some(b)) = (before.from[col(p)], now.from[col(p)]) {
            if b < a {
                return Err(trace_error(
                    file,
                    format!("line {line}: from_{}", p.name()),
                    format!(
                        "{} step {} reads {p} step {b}, older than step {a} its step {} \
                         read: a consumer never takes an older sample after a newer one",
                        now.role, now.step, before.step
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Refuses a trace a live run is still writing (its writer holds the file's lock for the
/// run's life, [`TraceWriter::create`]); a trace that cannot be opened is left to [`read`].
pub fn refuse_if_live(path: &Path) -> Result<(), TraceError> {
    match std::fs::File::open(path) {
        Ok(f) => unlocked(&f)
            .map_err(|what| trace_error(&path.display().to_string(), "file".into(), what)),
        Err(_) => Ok(()),
    }
}

/// Takes a shared lock on the open trace `f`, or says why not.
fn unlocked(f: &std::fs::File) -> Result<(), String> {
    match f.try_lock_shared() {
        Ok(()) => Ok(()),
        Err(std::fs::TryLockError::WouldBlock) => Err("the free run that writes it is still \
                                                       running: replay it once the run has ended"
            .into()),
        Err(std::fs::TryLockError::Error(e)) => Err(e.to_string()),
    }
}

/// The text of a trace no live run is writing.
fn read_unlocked(path: &Path) -> Result<String, String> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    unlocked(&f)?;
    let mut text = String::new();
    f.read_to_string(&mut text).map_err(|e| e.to_string())?;
    Ok(text)
}

/// The error of a trace `file`: `field` and what is wrong with it.
fn trace_error(file: &str, field: String, what: String) -> TraceError {
    TraceError {
        file: file.to_string(),
        field,
        what,
    }
}

/// Reads the head line of trace `file` and checks it against the scenario's `dt_s`, `steps`
/// and `controller_period_ticks`.
fn read_head(
    file: &str,
    line: &str,
    dt_s: f64,
    steps: u64,
    controller_period_ticks: u64,
) -> Result<TraceHead, TraceError> {
    let err = |field: &str, what: String| trace_error(file, field.into(), what);
    let head = parse_head(line).ok_or_else(|| {
        err(
            "line 1",
            "expected `# tiltsim timing trace: dt_s=.. steps=.. controller_period_ticks=.. start_ns=..`"
                .into(),
        )
    })?;
    if head.dt_s != dt_s {
        return Err(err(
            "dt_s",
            format!(
                "{} in the trace; the scenario has run.dt_s = {dt_s}",
                head.dt_s
            ),
        ));
    }
    if head.steps != steps {
        return Err(err(
            "steps",
            format!(
                "{} in the trace; the scenario has {steps} steps (run.duration_s / run.dt_s)",
                head.steps
            ),
        ));
    }
    if head.controller_period_ticks != controller_period_ticks {
        return Err(err(
            "controller_period_ticks",
            format!(
                "{} in the trace; the scenario's controller.period_s is {controller_period_ticks} ticks",
                head.controller_period_ticks
            ),
        ));
    }
    Ok(head)
}

/// The step lines of a trace as they are read: the steps each role has in the scenario and
/// those seen so far.
struct Body<'a> {
    file: &'a str,
    controller_period_ticks: u64,
    /// Steps per role in the scenario, by [`col`].
    counts: [u64; 3],
    /// Per role, by [`col`], which of its steps have been read (empty when `ordered`).
    seen: [Vec<bool>; 3],
    /// Each role's steps must come in ascending order: `next` then counts them, and `seen`
    /// is not kept.
    ordered: bool,
    /// Per role, by [`col`], the steps read so far (when `ordered`).
    next: [u64; 3],
}

impl<'a> Body<'a> {
    fn new(file: &'a str, steps: u64, controller_period_ticks: u64) -> Self {
        let counts = [steps, steps, steps.div_ceil(controller_period_ticks)];
        Body {
            file,
            controller_period_ticks,
            counts,
            seen: [
                vec![false; counts[0] as usize],
                vec![false; counts[1] as usize],
                vec![false; counts[2] as usize],
            ],
            ordered: false,
            next: [0; 3],
        }
    }

    /// A body whose roles' steps must each come in ascending order, checked without a
    /// record of every step.
    fn ordered(file: &'a str, steps: u64, controller_period_ticks: u64) -> Self {
        let counts = [steps, steps, steps.div_ceil(controller_period_ticks)];
        Body {
            file,
            controller_period_ticks,
            counts,
            seen: Default::default(),
            ordered: true,
            next: [0; 3],
        }
    }

    /// Notes step `idx` of `role` (on line `n`) as read; refuses one read twice, or, when
    /// `ordered`, one out of order.
    fn note(&mut self, n: usize, role: Role, idx: u64, step: u64) -> Result<(), TraceError> {
        if self.ordered {
            let next = self.next[col(role)];
            if idx != next {
                let expected = next * self.ticks(role);
                let what = if idx > next {
                    format!("{role} step {step} comes where step {expected} was expected: {role} step {expected} is missing or out of order (each role's steps in order, once each)")
                } else {
                    format!("{role} step {step} where step {expected} was expected: each role's steps in order, once each")
                };
                return Err(self.err(format!("line {n}: step"), what));
            }
            self.next[col(role)] += 1;
        } else if std::mem::replace(&mut self.seen[col(role)][idx as usize], true) {
            return Err(self.err(
                format!("line {n}: step"),
                format!("{role} step {step} appears twice"),
            ));
        }
        Ok(())
    }

    fn err(&self, field: String, what: String) -> TraceError {
        trace_error(self.file, field, what)
    }

    /// Ticks per step of `role`.
    fn ticks(&self, role: Role) -> u64 {
        if role == Role::Controller {
            self.controller_period_ticks
        } else {
            1
        }
    }

    /// Reads line `n`, one consumer step, and notes the step as seen.
    fn step(&mut self, n: usize, line: &str) -> Result<StepTrace, TraceError> {
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != 14 {
            return Err(self.err(format!("line {n}"), "expected 14 columns".into()));
        }
        let role = Role::parse(cells[0]).ok_or_else(|| {
            self.err(
                format!("line {n}: role"),
                "plant, actuator or controller".into(),
            )
        })?;
        let file = self.file;
        let int = |c: usize, name: &str| -> Result<u64, TraceError> {
            cells[c].parse::<u64>().map_err(|_| {
                trace_error(file, format!("line {n}: {name}"), "a whole number".into())
            })
        };
        let step = int(1, "step")?;
        let ticks = self.ticks(role);
        let idx = step / ticks;
        if !step.is_multiple_of(ticks) || idx >= self.counts[col(role)] {
            return Err(self.err(
                format!("line {n}: step"),
                format!("{step} is not a step of the {role} in this scenario"),
            ));
        }
        self.note(n, role, idx, step)?;
        Ok(StepTrace {
            role,
            step,
            from: self.from(n, &cells, role)?,
            due_ns: int(8, "due_ns")?,
            read_ns: int(9, "read_ns")?,
            compute_end_ns: int(10, "compute_end_ns")?,
            publish_ns: int(11, "publish_ns")?,
        })
    }

    /// The producer steps line `n` (its `cells`) says a step of `role` read.
    fn from(&self, n: usize, cells: &[&str], role: Role) -> Result<[Option<i64>; 3], TraceError> {
        let mut from = [None; 3];
        for &p in inputs_of(role) {
            let c = 2 + col(p);
            let name = format!("from_{}", p.name());
            let v: i64 = cells[c]
                .parse()
                .map_err(|_| self.err(format!("line {n}: {name}"), "a step number or -1".into()))?;
            let pticks = self.ticks(p);
            let ok = v == -1
                || (v >= 0
                    && (v as u64).is_multiple_of(pticks)
                    && (v as u64) / pticks < self.counts[col(p)]);
            if !ok {
                return Err(self.err(
                    format!("line {n}: {name}"),
                    format!("{v} is not a step of the {p} in this scenario"),
                ));
            }
            from[col(p)] = Some(v);
        }
        Ok(from)
    }

    /// Once every line is read: each role's steps must be its first ones without a gap;
    /// returns what a partial trace lacks (also when a last line `cut_short` was dropped).
    fn partial(&self, cut_short: bool) -> Result<Option<String>, TraceError> {
        let mut lacking = Vec::new();
        for r in Role::ALL {
            if self.ordered {
                let (present, total) = (self.next[col(r)], self.counts[col(r)]);
                if present < total {
                    lacking.push(format!("{r} {present} of {total} steps"));
                }
                continue;
            }
            let ticks = self.ticks(r);
            let seen = &self.seen[col(r)];
            let present = seen.iter().filter(|s| **s).count();
            if let Some(missing) = seen[..present].iter().position(|s| !s) {
                return Err(self.err(
                    "step".into(),
                    format!(
                        "{r} step {} is missing, though later steps of the {r} are there",
                        missing as u64 * ticks
                    ),
                ));
            }
            if present < seen.len() {
                lacking.push(format!("{r} {} of {} steps", present, seen.len()));
            }
        }
        Ok((!lacking.is_empty() || cut_short).then(|| {
            let mut what = if lacking.is_empty() {
                "every step".to_string()
            } else {
                lacking.join(", ")
            };
            if cut_short {
                what.push_str("; a last line cut short was dropped");
            }
            format!("the trace holds {what} (the free run ended early or was killed)")
        }))
    }
}

fn parse_head(line: &str) -> Option<TraceHead> {
    let rest = line.strip_prefix("# tiltsim timing trace:")?;
    let mut dt_s = None;
    let mut steps = None;
    let mut period = None;
    let mut start = None;
    for kv in rest.split_whitespace() {
        let (k, v) = kv.split_once('=')?;
        match k {
            "dt_s" => dt_s = v.parse().ok(),
            "steps" => steps = v.parse().ok(),
            "controller_period_ticks" => period = v.parse().ok(),
            "start_ns" => start = v.parse().ok(),
            _ => return None,
        }
    }
    Some(TraceHead {
        dt_s: dt_s?,
        steps: steps?,
        controller_period_ticks: period?,
        start_ns: start?,
    })
}
