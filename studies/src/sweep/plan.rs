//! The plans: the Monte Carlo parameters and the grid's key, and what sample `j` of a plan is.

use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use tiltsim_scenario::scenario::Scenario;

use super::SweepError;

/// The vehicle parameters a Monte Carlo sweep perturbs: masses, inertias and suspension.
pub const PERTURBED: [&str; 15] = [
    "m_v", "i_vr", "m_b", "i_br", "k_az", "k_sz", "k_rz", "c_rz", "k_sy", "c_sy", "k_vr", "k_pz",
    "c_pz", "k_py", "c_py",
];

/// Interval of the stored lateral-acceleration series (s).
pub const SERIES_DT: f64 = 0.01;

/// What a sweep varies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "method")]
pub enum Plan {
    /// Uniform factors `1 ± spread` on [`PERTURBED`].
    MonteCarlo {
        /// Number of samples.
        samples: usize,
        /// Relative half-width of the uniform distribution.
        spread: f64,
        /// Seed of the draws.
        seed: u64,
    },
    /// One key set to each value.
    Grid {
        /// Dotted scenario key.
        key: String,
        /// Values, one sample each.
        values: Vec<f64>,
    },
}

impl Plan {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Plan::MonteCarlo { samples, .. } => *samples,
            Plan::Grid { values, .. } => values.len(),
        }
    }
    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Names of the parameter columns.
    pub fn columns(&self) -> Vec<String> {
        match self {
            Plan::MonteCarlo { .. } => PERTURBED.iter().map(|p| format!("factor_{p}")).collect(),
            Plan::Grid { key, .. } => vec![key.clone()],
        }
    }
}

/// Parses a grid `KEY=SPEC` where SPEC is `start:stop:step` (inclusive) or `v1,v2,...`.
pub fn parse_grid(arg: &str) -> Result<Plan, SweepError> {
    grid_plan(arg).map_err(SweepError::Argument)
}

pub(super) fn grid_plan(arg: &str) -> Result<Plan, String> {
    let (key, spec) = arg
        .split_once('=')
        .ok_or_else(|| format!("--grid `{arg}`: expected KEY=START:STOP:STEP or KEY=V1,V2,..."))?;
    let num = |x: &str| {
        let x = x.trim();
        // A value is held as f64: a whole number written in digits must be one that f64
        // holds exactly, or it would arrive as its neighbour (2^53 + 1 as 2^53).
        if let Ok(n) = x.parse::<i128>() {
            if n.unsigned_abs() > 1u128 << 53 {
                return Err(format!(
                    "--grid `{arg}`: `{x}` is a whole number beyond 2^53 = 9007199254740992, which a grid value cannot hold exactly; set it with `tiltsim run --set KEY={x}` (or `--seed`)"
                ));
            }
        }
        x.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("--grid `{arg}`: `{x}` is not a finite number"))
    };
    let values = if spec.contains(':') {
        let p: Vec<&str> = spec.split(':').collect();
        if p.len() != 3 {
            return Err(format!("--grid `{arg}`: a range is START:STOP:STEP"));
        }
        let (a, b, st) = (num(p[0])?, num(p[1])?, num(p[2])?);
        if st <= 0.0 || b < a || (b - a) / st > 10_000.0 {
            return Err(format!(
                "--grid `{arg}`: need STOP >= START and 0 < STEP, at most 10000 values"
            ));
        }
        let n = ((b - a) / st + 1e-9).floor() as usize;
        // Computed from the index, so values do not drift by accumulated rounding.
        (0..=n).map(|i| a + i as f64 * st).collect()
    } else {
        spec.split(',').map(num).collect::<Result<Vec<_>, _>>()?
    };
    if key.trim().is_empty() || values.is_empty() {
        return Err(format!("--grid `{arg}`: need a key and at least one value"));
    }
    Ok(Plan::Grid {
        key: key.trim().to_string(),
        values,
    })
}

/// Sets the dotted `key` of a scenario to `v` (a whole number where the key holds one,
/// [`Scenario::with_setting`]), and re-validates. Errors name the key.
pub fn with_key(base: &Scenario, key: &str, v: f64) -> Result<Scenario, SweepError> {
    // `v` written in full (never with an exponent), which parses back to the same f64.
    let s = base
        .with_setting(key, &v.to_string())
        .map_err(SweepError::Argument)?;
    let errors = s.validate();
    if !errors.is_empty() {
        let lines: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
        return Err(SweepError::Argument(format!(
            "key `{key}` = {v}: {}",
            lines.join("; ")
        )));
    }
    Ok(s)
}

/// Checks a plan against its base scenario before anything runs: every grid value is one
/// the key takes (a whole number, exactly held, where the key holds one) and gives a valid
/// scenario. The error names the key, the value and what is allowed.
pub fn check_plan(base: &Scenario, plan: &Plan) -> Result<(), SweepError> {
    let Plan::Grid { key, values } = plan else {
        return Ok(());
    };
    // A key that holds a whole number takes whole numbers that a grid value (f64) holds
    // exactly: at most 2^53 in magnitude.
    if base.holds_integer(key) {
        if let Some(v) = values
            .iter()
            .find(|v| v.fract() != 0.0 || v.abs() > 9_007_199_254_740_992.0)
        {
            return Err(SweepError::Argument(format!(
                "grid key `{key}` = {v}: allowed whole numbers from -9007199254740992 to 9007199254740992 for this key"
            )));
        }
    }
    for v in values {
        with_key(base, key, *v)?;
    }
    Ok(())
}

/// The scenario of sample `j` and its parameter values (factors or the grid value).
pub fn sample(base: &Scenario, plan: &Plan, j: usize) -> Result<(Scenario, Vec<f64>), SweepError> {
    match plan {
        Plan::MonteCarlo { spread, seed, .. } => {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(*seed);
            rng.set_stream(j as u64);
            let factors: Vec<f64> = PERTURBED
                .iter()
                .map(|_| 1.0 + spread * (2.0 * rng.random::<f64>() - 1.0))
                .collect();
            let mut s = base.clone();
            s.design_vehicle = Some(base.controller_vehicle().clone());
            let v = &mut s.vehicle;
            let fields: [&mut f64; 15] = [
                &mut v.m_v,
                &mut v.i_vr,
                &mut v.m_b,
                &mut v.i_br,
                &mut v.k_az,
                &mut v.k_sz,
                &mut v.k_rz,
                &mut v.c_rz,
                &mut v.k_sy,
                &mut v.c_sy,
                &mut v.k_vr,
                &mut v.k_pz,
                &mut v.c_pz,
                &mut v.k_py,
                &mut v.c_py,
            ];
            for (f, k) in fields.into_iter().zip(&factors) {
                *f *= k;
            }
            Ok((s, factors))
        }
        Plan::Grid { key, values } => Ok((with_key(base, key, values[j])?, vec![values[j]])),
    }
}

/// The settings sample `j` changes, as dotted keys and values: every leaf of its scenario
/// that differs from `base` (for a Monte Carlo sample the 15 scaled parameters and the
/// nominal design vehicle). `tiltsim run SCENARIO --set KEY=VALUE ...` with them runs exactly
/// that sample.
pub fn overrides(
    base: &Scenario,
    plan: &Plan,
    j: usize,
) -> Result<Vec<(String, toml::Value)>, SweepError> {
    let (s, _) = sample(base, plan, j)?;
    let to_value =
        |s: &Scenario| toml::Value::try_from(s).map_err(|e| SweepError::Argument(e.to_string()));
    let (a, b) = (to_value(base)?, to_value(&s)?);
    fn diff(
        path: &str,
        a: Option<&toml::Value>,
        b: &toml::Value,
        out: &mut Vec<(String, toml::Value)>,
    ) {
        match b {
            toml::Value::Table(t) => {
                for (k, v) in t {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    diff(&p, a.and_then(|a| a.get(k)), v, out);
                }
            }
            _ if a != Some(b) => out.push((path.to_string(), b.clone())),
            _ => {}
        }
    }
    let mut out = Vec::new();
    diff("", Some(&a), &b, &mut out);
    Ok(out)
}
