//! A participant of a scenario as an FMI 3.0 (or 2.0) co-simulation FMU: the model description from
//! [`tiltsim_fmi::Layout`], the FMU library `libtiltsim_fmu.so` (crate `tiltsim-fmu`, built
//! by cargo beside `tiltsim`) and the participant's settings as `resources/tiltsim.json`.

use std::path::{Path, PathBuf};

use cosim::Role;
use tiltsim_fmi::description::{write_fmi2, write_fmi3, ExportInfo, FmiVersion};
use tiltsim_fmi::layout::{period_ticks, token, FmuConfig, Stepping};
use tiltsim_fmi::Layout;
use tiltsim_scenario::scenario::Scenario;

use crate::engine::Inits;

/// Why an FMU could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The FMU library was not found.
    #[error("the FMU library was not found (looked at {}); build it with `cargo build --release -p tiltsim-fmu` and name it with --library or TILTSIM_FMU_LIBRARY, or install tiltsim with it inside: `cargo install --path orchestrator --features embed-fmu`", .0.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))]
    NoLibrary(Vec<PathBuf>),
    /// The role is an FMU in this scenario already.
    #[error("the scenario's {0} is an FMU already ([participants.{0}]); export the native participant from a scenario without it")]
    AlreadyFmu(Role),
    /// A setting an SSP system cannot carry (`export-ssp`).
    #[error("{field} = {value}: allowed {allowed}")]
    NotInSsp {
        /// The scenario's key.
        field: String,
        /// Its value.
        value: String,
        /// What is allowed, and why.
        allowed: String,
    },
    /// A setting without a unit (the unit table is incomplete).
    #[error("{0}")]
    Layout(String),
    /// Writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}

/// How an FMU is written.
#[derive(Debug, Clone)]
pub struct FmuOptions<'a> {
    /// FMI 2.0 or 3.0.
    pub version: FmiVersion,
    /// Which communication steps it takes.
    pub stepping: Stepping,
    /// The FMU library to pack (see [`library_candidates`]).
    pub library: Option<&'a Path>,
}

/// What was written.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The step it takes inside and declares (s): the base tick, or with
    /// [`Stepping::Period`] the participant's period.
    pub step_s: f64,
    /// The participant's own period (s): it computes on its multiples.
    pub period_s: f64,
    /// Number of inputs.
    pub inputs: usize,
    /// Number of outputs.
    pub outputs: usize,
    /// Number of parameters.
    pub parameters: usize,
    /// The FMU's variables.
    pub layout: Layout,
}

/// Where the FMU library is looked for: `explicit`, `TILTSIM_FMU_LIBRARY`, then beside this
/// executable (`target/<profile>/` and its `deps/`).
pub fn library_candidates(explicit: Option<&Path>) -> Vec<PathBuf> {
    if let Some(p) = explicit {
        return vec![p.to_path_buf()];
    }
    if let Some(p) = std::env::var_os("TILTSIM_FMU_LIBRARY") {
        return vec![PathBuf::from(p)];
    }
    let mut v = Vec::new();
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        v.push(dir.join("libtiltsim_fmu.so"));
        v.push(dir.join("deps").join("libtiltsim_fmu.so"));
        // Test binaries live in deps/ themselves.
        if let Some(up) = dir.parent() {
            v.push(up.join("libtiltsim_fmu.so"));
        }
    }
    v
}

static EMBEDDED: std::sync::OnceLock<&'static [u8]> = std::sync::OnceLock::new();

/// Makes `bytes` (the FMU library built into the executable: `tiltsim` installed with the
/// `embed-fmu` feature) the library packed when none is named and none is found beside the
/// executable.
pub fn embed_library(bytes: &'static [u8]) {
    let _ = EMBEDDED.set(bytes);
}

/// The tiltsim_fmu library to pack: the newest of the candidates ([`library_candidates`]),
/// else the one built into the executable ([`embed_library`]). cargo leaves a copy in
/// target/<profile>/ when the crate itself is built and one in deps/ when tiltsim's build
/// builds it: the newer is the current one.
fn newest_library(library: Option<&Path>) -> Result<Vec<u8>, ExportError> {
    let candidates = library_candidates(library);
    let named = library.is_some() || std::env::var_os("TILTSIM_FMU_LIBRARY").is_some();
    let lib_path = match pick_library(&candidates, named, EMBEDDED.get().copied())? {
        Picked::File(p) => p,
        Picked::Embedded(bytes) => return Ok(bytes.to_vec()),
    };
    std::fs::read(lib_path).map_err(|source| ExportError::Io {
        path: lib_path.clone(),
        source,
    })
}

/// Where the library to pack comes from.
#[derive(Debug, PartialEq)]
enum Picked<'a> {
    /// The newest existing file of the candidates.
    File(&'a PathBuf),
    /// The executable's own copy.
    Embedded(&'static [u8]),
}

/// The newest existing file of `candidates`; when there is none, the embedded library unless
/// a library was `named` (a name that leads nowhere is an error, not a silent substitute).
fn pick_library<'a>(
    candidates: &'a [PathBuf],
    named: bool,
    embedded: Option<&'static [u8]>,
) -> Result<Picked<'a>, ExportError> {
    let found = candidates
        .iter()
        .filter_map(|p| Some((std::fs::metadata(p).ok()?.modified().ok()?, p)))
        .max_by_key(|(t, _)| *t)
        .map(|(_, p)| p);
    match (found, embedded) {
        (Some(p), _) => Ok(Picked::File(p)),
        (None, Some(bytes)) if !named => Ok(Picked::Embedded(bytes)),
        (None, _) => Err(ExportError::NoLibrary(candidates.to_vec())),
    }
}

/// The FMU's own settings: the role, the base tick, the stepping and the participant's
/// settings of `s`.
fn config_of(s: &Scenario, role: Role, stepping: Stepping) -> Result<FmuConfig, ExportError> {
    let inits = Inits::from(s);
    let settings = match role {
        Role::Plant => serde_json::to_value(&inits.plant),
        Role::Actuator => serde_json::to_value(&inits.actuator),
        Role::Controller => serde_json::to_value(&inits.controller),
    }
    .map_err(|e| ExportError::Layout(e.to_string()))?;
    Ok(FmuConfig {
        role,
        dt_s: s.run.dt_s,
        stepping,
        settings,
    })
}

/// What the model description says of the FMU of `role` of `s`.
fn export_info(
    s: &Scenario,
    role: Role,
    identifier: &str,
    token: String,
    step_s: f64,
    stepping: Stepping,
) -> ExportInfo {
    ExportInfo {
        model_name: format!("tiltsim {} ({})", role.name(), s.name),
        model_identifier: identifier.to_string(),
        token,
        description: format!(
            "tiltsim's {} participant of scenario `{}`: {}",
            role.name(),
            s.name,
            s.description
        ),
        step_s,
        variable_step: stepping == Stepping::Tick,
        stop_s: s.duration(),
    }
}

/// Writes `role` of scenario `s` as an FMU at `out`.
pub fn export(
    s: &Scenario,
    role: Role,
    out: &Path,
    options: &FmuOptions,
) -> Result<Exported, ExportError> {
    if s.participants.get(role).is_some() {
        return Err(ExportError::AlreadyFmu(role));
    }
    let version = options.version;
    let lib = newest_library(options.library)?;
    let config = config_of(s, role, options.stepping)?;
    let bytes =
        serde_json::to_vec_pretty(&config).map_err(|e| ExportError::Layout(e.to_string()))?;
    let layout =
        Layout::new(role, &config.settings).map_err(|e| ExportError::Layout(e.to_string()))?;
    let period = period_ticks(role, &config.settings, s.run.dt_s).unwrap_or(1);
    let period_s = cosim::time::tick_time(period, s.run.dt_s);
    let step_s = match options.stepping {
        Stepping::Tick => s.run.dt_s,
        Stepping::Period => period_s,
    };
    let identifier = format!("tiltsim_{}", role.name());
    let info = export_info(
        s,
        role,
        &identifier,
        token(&bytes),
        step_s,
        options.stepping,
    );
    let xml = match version {
        FmiVersion::V3 => write_fmi3(&layout, &info),
        FmiVersion::V2 => write_fmi2(&layout, &info).map_err(ExportError::Layout)?,
    };
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| ExportError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    tiltsim_fmi::archive::write_fmu(
        version,
        out,
        &xml,
        &identifier,
        &lib,
        &[("tiltsim.json", &bytes)],
    )
    .map_err(|source| ExportError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    Ok(Exported {
        step_s,
        period_s,
        inputs: layout.inputs.len(),
        outputs: layout.outputs.len(),
        parameters: layout.params.len(),
        layout,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_library_is_the_newest_file_found_else_the_embedded_copy_unless_one_was_named() {
        let dir = std::env::temp_dir().join(format!("tiltsim-pick-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (old, new, absent) = (dir.join("old.so"), dir.join("new.so"), dir.join("no.so"));
        std::fs::write(&old, b"old").unwrap();
        std::thread::sleep(std::time::Duration::from_millis(20));
        std::fs::write(&new, b"new").unwrap();
        static COPY: &[u8] = b"embedded";
        let both = [old.clone(), new.clone(), absent.clone()];
        assert_eq!(
            pick_library(&both, false, Some(COPY)).unwrap(),
            Picked::File(&new)
        );
        let none = [absent.clone()];
        assert_eq!(
            pick_library(&none, false, Some(COPY)).unwrap(),
            Picked::Embedded(COPY)
        );
        // A named library that is not there is an error naming it, embedded copy or not.
        let e = pick_library(&none, true, Some(COPY))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no.so") && e.contains("embed-fmu"), "{e}");
        assert!(pick_library(&none, false, None).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn every_value_of_every_shipped_scenario_is_a_parameter_with_its_unit_and_description() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
        let mut seen = Vec::new();
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            if p.extension().is_none_or(|x| x != "toml") {
                continue;
            }
            let text = std::fs::read_to_string(&p).unwrap();
            // Parsed without validation: the FMU example's FMU need not exist here.
            let s: Scenario = toml::from_str(&text).unwrap();
            let inits = Inits::from(&s);
            for (role, v) in [
                (Role::Plant, serde_json::to_value(&inits.plant).unwrap()),
                (
                    Role::Actuator,
                    serde_json::to_value(&inits.actuator).unwrap(),
                ),
                (
                    Role::Controller,
                    serde_json::to_value(&inits.controller).unwrap(),
                ),
            ] {
                let l = Layout::new(role, &v).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
                assert!(l.params.len() > 20, "{role}");
                // Every value has a unit or is declared unitless on purpose (counts,
                // switches, choices, weights of mixed states), and a description.
                for q in &l.params {
                    let at = format!("{}: {role} `{}`", p.display(), q.name);
                    assert!(tiltsim_fmi::units::param_unit(&q.name).is_some(), "{at}");
                    let d = tiltsim_fmi::params_doc::param_description(&q.name);
                    assert!(d.is_some_and(|d| !d.trim().is_empty()), "{at}");
                    assert_eq!(q.description, d.unwrap_or_default(), "{at}");
                }
                // Setting every parameter to its own value gives the settings back.
                let values: Vec<_> = l.params.iter().map(|q| q.value.clone()).collect();
                assert_eq!(l.settings_with(&v, &values), v);
            }
            seen.push(p.file_name().unwrap().to_string_lossy().into_owned());
        }
        assert!(seen.len() > 10);
        for name in [
            "paper-lqg.toml",
            "paper-mpc.toml",
            "pi-drive.toml",
            "paper-passive.toml",
            "tilting-mpc.toml",
        ] {
            assert!(seen.iter().any(|s| s == name), "{name} was not checked");
        }
    }
}
