//! The house rule on the size of the sources: no tracked Rust or Python file over
//! [`MAX_FILE_LINES`] lines, no function over [`MAX_FN_LINES`] lines (tests included).
//!
//! A Rust function runs from the line of its `fn NAME` (after `pub`, `pub(..)`, `const`,
//! `async`, `unsafe`, `extern "ABI"`) to its closing brace, the braces counted outside string
//! and character literals and comments; a Python function from its `def` to its last line
//! before the next code line at its indent or less.

use std::path::Path;
use std::process::Command;

/// Lines a source file may have.
const MAX_FILE_LINES: usize = 750;

/// Lines a function may have.
const MAX_FN_LINES: usize = 100;

/// Offenders allowed for a while: `(file, None)` for a file too long, `(file, Some(function))`
/// for a function. Each must still offend, so the list can only shrink: remove an entry once
/// its file or function is within the rule. None today.
const ALLOWED: &[(&str, Option<&str>)] = &[];

/// A file or a function over its limit.
#[derive(Debug, Clone, PartialEq)]
struct Offence {
    /// The file, relative to the repository root.
    path: String,
    /// The function, `None` for the file itself.
    function: Option<String>,
    /// Where the function starts (1-based; 0 for the file).
    line: usize,
    /// Its length in lines.
    lines: usize,
}

impl Offence {
    fn allowed(&self, (path, function): (&str, Option<&str>)) -> bool {
        self.path == path && self.function.as_deref() == function
    }

    fn describe(&self) -> String {
        match &self.function {
            None => format!(
                "{}: {} lines (more than {MAX_FILE_LINES})",
                self.path, self.lines
            ),
            Some(f) => format!(
                "{}:{}: fn {f} is {} lines (more than {MAX_FN_LINES})",
                self.path, self.line, self.lines
            ),
        }
    }
}

/// The tracked `*.rs` and `*.py` files of the repository at `root`, relative to it.
fn tracked_sources(root: &Path) -> Vec<String> {
    let out = Command::new("git")
        .args(["ls-files", "-z", "--", "*.rs", "*.py"])
        .current_dir(root)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run git to list the tracked sources (is git installed?): {e}")
        });
    assert!(
        out.status.success(),
        "git ls-files failed in {}: {}",
        root.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .split('\0')
        .filter(|p| !p.is_empty())
        .map(String::from)
        .collect()
}

/// Every offence of the source `text` of file `path`.
fn offences(path: &str, text: &str) -> Vec<Offence> {
    let mut found = Vec::new();
    let lines = text.lines().count();
    if lines > MAX_FILE_LINES {
        found.push(Offence {
            path: path.to_string(),
            function: None,
            line: 0,
            lines,
        });
    }
    let functions = if path.ends_with(".py") {
        python_functions(text)
    } else {
        rust_functions(text)
    };
    for (line, name, lines) in functions {
        if lines > MAX_FN_LINES {
            found.push(Offence {
                path: path.to_string(),
                function: Some(name),
                line,
                lines,
            });
        }
    }
    found
}

/// `text` with the contents of its string and character literals and its comments blanked
/// (each character but a newline made a space; the quotes of a string stay), so that braces
/// and `fn` in them do not count and every line keeps its place.
fn code_only(text: &str) -> Vec<char> {
    let c: Vec<char> = text.chars().collect();
    let mut out = Vec::with_capacity(c.len());
    let blank = |out: &mut Vec<char>, ch: char| out.push(if ch == '\n' { '\n' } else { ' ' });
    let mut i = 0;
    while i < c.len() {
        let next = c.get(i + 1).copied();
        if c[i] == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                blank(&mut out, c[i]);
                i += 1;
            }
        } else if c[i] == '/' && next == Some('*') {
            i = block_comment(&c, i, &mut out);
        } else if let Some(hashes) = raw_string_start(&c, i) {
            i = raw_string(&c, i, hashes, &mut out);
        } else if c[i] == '"' {
            out.push('"');
            i += 1;
            while i < c.len() && c[i] != '"' {
                let n = if c[i] == '\\' { 2 } else { 1 };
                for &ch in &c[i..(i + n).min(c.len())] {
                    blank(&mut out, ch);
                }
                i += n;
            }
            if i < c.len() {
                out.push('"');
                i += 1;
            }
        } else if c[i] == '\'' {
            // A character literal ('x', '\n', '\u{..}', '\''), else a lifetime or a label.
            let end = if next == Some('\\') {
                (i + 3..c.len()).find(|&j| c[j] == '\'')
            } else if c.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            let end = end.unwrap_or(i);
            for &ch in &c[i..=end] {
                blank(&mut out, ch);
            }
            i = end + 1;
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// Blanks the (possibly nested) block comment starting at `c[i]`; returns where it ends.
fn block_comment(c: &[char], mut i: usize, out: &mut Vec<char>) -> usize {
    let mut depth = 0;
    while i < c.len() {
        let pair = (c[i], c.get(i + 1).copied().unwrap_or(' '));
        let step = match pair {
            ('/', '*') => {
                depth += 1;
                2
            }
            ('*', '/') => {
                depth -= 1;
                2
            }
            _ => 1,
        };
        for &ch in &c[i..(i + step).min(c.len())] {
            out.push(if ch == '\n' { '\n' } else { ' ' });
        }
        i += step;
        if depth == 0 {
            break;
        }
    }
    i
}

/// The number of `#` of a raw string (`r"`, `r#"`, `br#"`, ...) starting at `c[i]`.
fn raw_string_start(c: &[char], i: usize) -> Option<usize> {
    let ident = |ch: char| ch.is_alphanumeric() || ch == '_';
    if i > 0 && ident(c[i - 1]) {
        return None;
    }
    let r = match c[i] {
        'r' => i + 1,
        'b' if c.get(i + 1) == Some(&'r') => i + 2,
        _ => return None,
    };
    let hashes = c[r..].iter().take_while(|&&ch| ch == '#').count();
    (c.get(r + hashes) == Some(&'"')).then_some(hashes)
}

/// Blanks the raw string with `hashes` starting at `c[i]`, keeping its prefix and quotes;
/// returns where it ends.
fn raw_string(c: &[char], mut i: usize, hashes: usize, out: &mut Vec<char>) -> usize {
    while c[i] != '"' {
        out.push(c[i]);
        i += 1;
    }
    out.push('"');
    i += 1;
    while i < c.len() {
        if c[i] == '"'
            && c[i + 1..]
                .iter()
                .take(hashes)
                .filter(|&&h| h == '#')
                .count()
                == hashes
        {
            out.push('"');
            out.extend(std::iter::repeat_n('#', hashes));
            return i + 1 + hashes;
        }
        out.push(if c[i] == '\n' { '\n' } else { ' ' });
        i += 1;
    }
    i
}

/// The name of the function a code line (literals and comments blanked) starts, if any.
fn fn_name(line: &str) -> Option<&str> {
    let mut rest = line.trim_start();
    if let Some(r) = rest.strip_prefix("pub") {
        if r.starts_with('(') {
            rest = r[r.find(')')? + 1..].trim_start();
        } else if r.starts_with(char::is_whitespace) {
            rest = r.trim_start();
        }
    }
    loop {
        let before = rest;
        for kw in ["const", "async", "unsafe", "extern"] {
            if let Some(r) = rest.strip_prefix(kw) {
                if r.starts_with(char::is_whitespace) {
                    rest = r.trim_start();
                }
            }
        }
        // The ABI after `extern` (its name blanked).
        if let Some(r) = rest.strip_prefix('"') {
            rest = r[r.find('"')? + 1..].trim_start();
        }
        if rest == before {
            break;
        }
    }
    let r = rest.strip_prefix("fn")?;
    if !r.starts_with(char::is_whitespace) {
        return None;
    }
    let r = r.trim_start();
    let end = r
        .find(|ch: char| !(ch.is_alphanumeric() || ch == '_'))
        .unwrap_or(r.len());
    let name = &r[..end];
    (!name.is_empty() && !name.starts_with(|ch: char| ch.is_ascii_digit())).then_some(name)
}

/// Every Rust function with a body in `text`, nested ones too: `(first line (1-based),
/// name, lines)`.
fn rust_functions(text: &str) -> Vec<(usize, String, usize)> {
    let code = code_only(text);
    let mut starts = vec![0];
    starts.extend((0..code.len()).filter(|&i| code[i] == '\n').map(|i| i + 1));
    let line_of = |at: usize| starts.partition_point(|&s| s <= at) - 1;
    let mut found = Vec::new();
    for (n, &start) in starts.iter().enumerate() {
        let end = starts.get(n + 1).map_or(code.len(), |&e| e - 1);
        let line: String = code[start..end].iter().collect();
        let Some(name) = fn_name(&line) else {
            continue;
        };
        if let Some(close) = body_end(&code, start) {
            found.push((n + 1, name.to_string(), line_of(close) - n + 1));
        }
    }
    found
}

/// Where the body of the function whose header starts at `code[from]` ends (its closing
/// brace); `None` for a declaration without a body (`fn f();`).
fn body_end(code: &[char], from: usize) -> Option<usize> {
    let mut parens = 0i64;
    let mut braces = 0i64;
    for (i, &ch) in code.iter().enumerate().skip(from) {
        match ch {
            '(' | '[' => parens += 1,
            ')' | ']' => parens -= 1,
            ';' if braces == 0 && parens == 0 => return None,
            '{' => braces += 1,
            '}' => {
                braces -= 1;
                if braces == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// Every Python function in `text`, nested ones too: `(first line (1-based), name, lines)`,
/// from its `def` to its last line before the next code line at its indent or less (blank
/// and comment lines do not end it).
fn python_functions(text: &str) -> Vec<(usize, String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let code = |l: &str| !l.trim().is_empty() && !l.trim_start().starts_with('#');
    let mut found = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        let Some(r) = t
            .strip_prefix("def ")
            .or_else(|| t.strip_prefix("async def "))
        else {
            continue;
        };
        let name: String = r
            .chars()
            .take_while(|ch| ch.is_alphanumeric() || *ch == '_')
            .collect();
        let mut last = i;
        for (j, m) in lines.iter().enumerate().skip(i + 1) {
            if !code(m) {
                continue;
            }
            if indent(m) <= indent(l) {
                break;
            }
            last = j;
        }
        found.push((i + 1, name, last - i + 1));
    }
    found
}

#[test]
fn no_tracked_source_file_or_function_is_over_its_limit() {
    let root = crate::root();
    let mut found = Vec::new();
    for path in tracked_sources(&root) {
        let file = root.join(&path);
        let bytes = match std::fs::read(&file) {
            Ok(b) => b,
            // Tracked but removed from the work tree (a move not yet committed).
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => panic!("{}: {e}", file.display()),
        };
        found.extend(offences(&path, &String::from_utf8_lossy(&bytes)));
    }
    let mut problems: Vec<String> = found
        .iter()
        .filter(|o| !ALLOWED.iter().any(|&a| o.allowed(a)))
        .map(Offence::describe)
        .collect();
    for &(path, function) in ALLOWED {
        if !found.iter().any(|o| o.allowed((path, function))) {
            let what = function.map_or(String::new(), |f| format!(" fn {f}"));
            problems.push(format!(
                "{path}{what} is allowed but no longer offends: remove it from the allowance"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "files over {MAX_FILE_LINES} lines or functions over {MAX_FN_LINES} lines:\n{}",
        problems.join("\n")
    );
}

#[test]
fn braces_in_literals_and_comments_do_not_count() {
    let text = r###"
pub(crate) fn a() {
    let s = "}}}";
    let r = r#"}"#;
    let c = '}';
    let e = '\'';
    // }
    /* } /* } */ } */
    let l: &'static str = s;
}
fn b<'x>(v: &'x [u8; 3]) -> [u8; 2] {
    fn inner() {}
    [0; 2]
}
trait T {
    fn declared(&self);
    const fn also(&self) -> u8 { 0 }
}
unsafe extern "C" fn c() {
    println!("fn not_a_function() {{");
}
"###;
    let fns = rust_functions(text);
    let want = [
        (2, "a", 9),
        (11, "b", 4),
        (12, "inner", 1),
        (17, "also", 1),
        (19, "c", 3),
    ];
    let got: Vec<(usize, &str, usize)> = fns.iter().map(|(l, n, k)| (*l, n.as_str(), *k)).collect();
    assert_eq!(got, want);
}

#[test]
fn a_python_function_ends_before_the_next_line_at_its_indent() {
    let text = "def f(x):\n    y = x\n\n    # note\n    return y\n\n\nclass C:\n    async def g(self):\n        pass\n# end\n";
    let got = python_functions(text);
    assert_eq!(got, [(1, "f".to_string(), 5), (9, "g".to_string(), 2)]);
}

#[test]
fn a_file_over_the_limit_and_a_long_function_are_offences() {
    let long_fn = format!(
        "fn long() {{\n{}}}\n",
        "    x();\n".repeat(MAX_FN_LINES - 1)
    );
    let o = offences("x.rs", &long_fn);
    assert_eq!(o.len(), 1, "{o:?}");
    assert_eq!(
        (o[0].function.as_deref(), o[0].lines),
        (Some("long"), MAX_FN_LINES + 1)
    );
    assert!(offences("x.rs", &"\n".repeat(MAX_FILE_LINES)).is_empty());
    let o = offences("x.py", &"\n".repeat(MAX_FILE_LINES + 1));
    assert_eq!((o.len(), o[0].function.clone()), (1, None));
}
