//! A scenario file read (bounded in size), parsed as TOML into typed settings, and every
//! type error turned into a message that names the field and what to write.

use std::path::Path;

use super::*;

/// The most a scenario file may hold: the largest shipped scenario is a few kB, so 4 MiB is
/// room for any hand-written or generated one, and a device or a wrong file (`/dev/zero`, a
/// recording) is refused after reading at most this much.
pub const MAX_SCENARIO_BYTES: u64 = 4 << 20;

/// Reads a scenario file, at most [`MAX_SCENARIO_BYTES`] of it.
pub(super) fn read_limited(path: &Path) -> Result<String, ScenarioError> {
    use std::io::Read as _;
    let read = |source| ScenarioError::Read {
        file: path.into(),
        source,
    };
    let f = std::fs::File::open(path).map_err(read)?;
    let mut bytes = Vec::new();
    f.take(MAX_SCENARIO_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(read)?;
    if bytes.len() as u64 > MAX_SCENARIO_BYTES {
        return Err(ScenarioError::TooLarge { file: path.into() });
    }
    String::from_utf8(bytes).map_err(|e| {
        read(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        ))
    })
}

/// A parser message cut to 600 characters: a hostile file cannot flood the terminal with
/// its own text (the message's first lines name the line and key).
pub(super) fn cut(msg: &str) -> String {
    if msg.chars().count() <= 600 {
        msg.to_string()
    } else {
        let head: String = msg.chars().take(600).collect();
        format!("{head} … (message cut)")
    }
}

/// Deserializes scenario text, naming the field a type error is in and what it allows.
pub(super) fn typed(text: &str) -> Result<Scenario, String> {
    let de = toml::Deserializer::parse(text).map_err(|e| e.to_string())?;
    let e = match serde_path_to_error::deserialize::<_, Scenario>(de) {
        Ok(s) => return Ok(s),
        Err(e) => e,
    };
    let path = e.path().to_string();
    let inner = e.inner().to_string();
    let guess = did_you_mean(&inner, "\n");
    if path.is_empty() || path == "?" {
        return Err(format!("{}{guess}", inner.trim_end()));
    }
    let hint = hint(text, &path, &inner)
        .map(|h| format!("\n{h}"))
        .unwrap_or_default();
    Err(format!("field `{path}`: {}{hint}{guess}", inner.trim_end()))
}

/// `did you mean `NAME`?` after `sep`, for a parser message about an unknown choice or key
/// that is near an expected one ([`super::suggest`]); empty otherwise.
pub(super) fn did_you_mean(message: &str, sep: &str) -> String {
    super::suggest::in_message(message)
        .map(|name| format!("{sep}did you mean `{name}`?"))
        .unwrap_or_default()
}

/// What to write instead, for the type errors whose own message misleads: a table written as
/// an array of tables (`[[links.measurement]]`), and a choice given as something else than one
/// of its names (`mode = 3`), whose allowed names are found by asking the parser itself.
pub(super) fn hint(text: &str, path: &str, inner: &str) -> Option<String> {
    if let Some((table, _)) = path.rsplit_once('[') {
        if inner.contains("invalid type: map") {
            return Some(format!(
                "`{table}` is one table: write `[{table}]`, not `[[{table}]]` (which makes a list of tables)"
            ));
        }
    }
    if !inner.contains("string or table") && !inner.contains("invalid type") {
        return None;
    }
    // Replace the value at `path` by a name no choice has; the parser's complaint about
    // that name lists the allowed ones.
    let mut doc: toml::Table = toml::from_str(text).ok()?;
    let keys: Vec<&str> = path.split('.').collect();
    let (last, parents) = keys.split_last()?;
    let mut t = &mut doc;
    for k in parents {
        t = t.get_mut(*k)?.as_table_mut()?;
    }
    t.insert((*last).to_string(), toml::Value::String("\u{1}".into()));
    let probe = toml::to_string(&doc).ok()?;
    let de = toml::Deserializer::parse(&probe).ok()?;
    let e = serde_path_to_error::deserialize::<_, Scenario>(de).err()?;
    let msg = e.inner().to_string();
    // serde's own wording: "expected one of `a`, `b`, `c`" or "expected `a` or `b`".
    let (_, allowed) = msg
        .split_once("unknown variant")?
        .1
        .split_once("expected ")?;
    let allowed = allowed.lines().next()?.trim();
    (e.path().to_string() == path).then(|| format!("allowed: {allowed}"))
}

impl Scenario {
    /// Reads, parses and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = read_limited(path)?;
        let mut s = Scenario::parse(&text, path)?;
        if s.name.is_empty() {
            s.name = path
                .file_stem()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
        }
        Ok(s)
    }

    /// Parses and validates scenario text; `file` is used in messages.
    pub fn parse(text: &str, file: &Path) -> Result<Scenario, ScenarioError> {
        let mut s = typed(text).map_err(|message| ScenarioError::Parse {
            file: file.into(),
            message: cut(message.trim_end()),
        })?;
        // FMU paths are relative to the scenario file.
        if let Some(dir) = file.parent() {
            for f in s.participants.each_mut() {
                if f.fmu.is_relative() {
                    f.fmu = dir.join(&f.fmu);
                }
            }
        }
        let errors = s.validate();
        if errors.is_empty() {
            Ok(s)
        } else {
            Err(ScenarioError::Invalid {
                file: file.into(),
                errors,
            })
        }
    }
}
