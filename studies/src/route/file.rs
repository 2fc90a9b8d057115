//! The route file: a line as sections of straight track and curves, one per CSV line.
//!
//! ```text
//! chainage_m,length_m,radius_m,cant_mm,transition_m,shape,vmax_conventional_kmh,vmax_tilting_kmh
//! 0,2500,,,,,160,200
//! 2500,900,-1200,120,110,clothoid,160,200
//! ```
//!
//! * `chainage_m`: where the section starts (m); each section starts where the one before
//!   ends.
//! * `length_m`: its length (m); a curve's holds its two transitions and its circular arc.
//! * `radius_m`: empty for a straight; a curve's radius (m), signed: positive bends one way,
//!   negative the other (the cant leans into the curve either way).
//! * `cant_mm`: a curve's cant (mm over 1500 mm between the rails' running circles); empty or 0
//!   on a straight.
//! * `transition_m`, `shape`: a curve's transition length (m) at each end and its shape,
//!   `clothoid` (linear cant ramp), `cosine` or `bloss` (smoothed ends).
//! * `vmax_conventional_kmh`, `vmax_tilting_kmh`: the section's speed limits (km/h) for
//!   conventional and tilting running.
//!
//! Lines starting with `#` are comments. The line starts and ends on a straight, and curves
//! are separated by straights.

use std::fmt;
use std::path::{Path, PathBuf};

use vehicle_model::TransitionShape;

/// Distance between the running circles of standard-gauge rails that cant is given over (mm).
pub const CANT_BASE_MM: f64 = 1500.0;

/// The columns of a route file, in order.
pub const COLUMNS: [&str; 8] = [
    "chainage_m",
    "length_m",
    "radius_m",
    "cant_mm",
    "transition_m",
    "shape",
    "vmax_conventional_kmh",
    "vmax_tilting_kmh",
];

/// A curve's geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curve {
    /// Radius (m), signed by the curve's direction.
    pub radius_m: f64,
    /// Cant (mm), ≥ 0.
    pub cant_mm: f64,
    /// Length of each transition (m).
    pub transition_m: f64,
    /// Shape of the transitions.
    pub shape: TransitionShape,
}

impl Curve {
    /// The cant as an angle (rad): asin(h / 1500 mm).
    pub fn cant_rad(&self) -> f64 {
        (self.cant_mm / CANT_BASE_MM).asin()
    }
}

/// One section of the line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    /// Line of the file it was read from (1-based, the header is line 1).
    pub line: usize,
    /// Start (m).
    pub chainage_m: f64,
    /// Length (m).
    pub length_m: f64,
    /// The curve, or `None` for a straight.
    pub curve: Option<Curve>,
    /// Speed limit for conventional running (km/h).
    pub vmax_conventional_kmh: f64,
    /// Speed limit for tilting running (km/h).
    pub vmax_tilting_kmh: f64,
}

impl Section {
    /// End (m).
    pub fn end_m(&self) -> f64 {
        self.chainage_m + self.length_m
    }
}

/// A line read from its file.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// Its name (the file's stem).
    pub name: String,
    /// The file.
    pub file: PathBuf,
    /// Its sections, in order.
    pub sections: Vec<Section>,
}

impl Route {
    /// Length (m).
    pub fn length_m(&self) -> f64 {
        self.sections.iter().map(|s| s.length_m).sum()
    }
    /// Number of curves.
    pub fn curves(&self) -> usize {
        self.sections.iter().filter(|s| s.curve.is_some()).count()
    }
}

/// What is wrong with a route file: the file, the line and the field.
#[derive(Debug, Clone, PartialEq)]
pub struct RouteError {
    /// The file.
    pub file: PathBuf,
    /// Its line (1-based), 0 when the whole file is meant.
    pub line: usize,
    /// The column, or "" for the line as a whole.
    pub field: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl fmt::Display for RouteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if self.line > 0 {
            write!(f, ":{}", self.line)?;
        }
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for RouteError {}

/// Reads and checks a route file.
pub fn load(path: &Path) -> Result<Route, RouteError> {
    let text = std::fs::read_to_string(path).map_err(|e| RouteError {
        file: path.to_path_buf(),
        line: 0,
        field: String::new(),
        message: format!("cannot read it: {e}"),
    })?;
    parse(&text, path)
}

/// Parses and checks the text of a route file (`file` names it in errors).
pub fn parse(text: &str, file: &Path) -> Result<Route, RouteError> {
    let err = |line: usize, field: &str, message: String| RouteError {
        file: file.to_path_buf(),
        line,
        field: field.to_string(),
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes());
    let header = reader
        .headers()
        .map_err(|e| err(1, "", format!("not CSV: {e}")))?
        .clone();
    let header_line = header.position().map_or(1, |p| p.line() as usize);
    let got: Vec<&str> = header.iter().collect();
    if got != COLUMNS {
        return Err(err(
            header_line,
            "",
            format!(
                "the header is `{}`; expected `{}`",
                got.join(","),
                COLUMNS.join(",")
            ),
        ));
    }
    let mut sections = Vec::new();
    for rec in reader.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line() as usize);
            err(line, "", format!("not CSV: {e}"))
        })?;
        let line = rec.position().map_or(0, |p| p.line() as usize);
        if rec.len() != COLUMNS.len() {
            return Err(err(
                line,
                "",
                format!(
                    "{} fields; expected {} ({})",
                    rec.len(),
                    COLUMNS.len(),
                    COLUMNS.join(",")
                ),
            ));
        }
        let fields: Vec<&str> = rec.iter().collect();
        sections.push(section(&fields, line).map_err(|(f, m)| err(line, f, m))?);
    }
    check_line(&sections).map_err(|(line, f, m)| err(line, f, m))?;
    let name = file
        .file_stem()
        .map_or("route".into(), |s| s.to_string_lossy().into_owned());
    Ok(Route {
        name,
        file: file.to_path_buf(),
        sections,
    })
}

type FieldError = (&'static str, String);

/// A number in `[lo, hi]`.
fn number(
    text: &str,
    field: &'static str,
    lo: f64,
    hi: f64,
    unit: &str,
) -> Result<f64, FieldError> {
    let v: f64 = text.parse().map_err(|_| {
        (
            field,
            format!("`{text}` is not a number; expected {lo} to {hi} {unit}"),
        )
    })?;
    if !v.is_finite() || v < lo || v > hi {
        return Err((
            field,
            format!("{text} is out of range; expected {lo} to {hi} {unit}"),
        ));
    }
    Ok(v)
}

/// One section from its fields.
fn section(f: &[&str], line: usize) -> Result<Section, FieldError> {
    let chainage_m = number(f[0], "chainage_m", 0.0, 1e7, "m")?;
    let length_m = number(f[1], "length_m", 1.0, 1e6, "m")?;
    let vmax_conventional_kmh = number(f[6], "vmax_conventional_kmh", 10.0, 400.0, "km/h")?;
    let vmax_tilting_kmh = number(f[7], "vmax_tilting_kmh", 10.0, 400.0, "km/h")?;
    let curve = if f[2].is_empty() {
        for (i, name) in [(3, "cant_mm"), (4, "transition_m"), (5, "shape")] {
            if !(f[i].is_empty() || (i == 3 && f[i].parse::<f64>() == Ok(0.0))) {
                return Err((
                    name,
                    format!("`{}` on a straight (radius_m empty); leave it empty", f[i]),
                ));
            }
        }
        None
    } else {
        Some(curve(f, length_m)?)
    };
    Ok(Section {
        line,
        chainage_m,
        length_m,
        curve,
        vmax_conventional_kmh,
        vmax_tilting_kmh,
    })
}

/// A curve's fields.
fn curve(f: &[&str], length_m: f64) -> Result<Curve, FieldError> {
    let radius_m = number(f[2], "radius_m", -1e5, 1e5, "m (empty for a straight)")?;
    if radius_m.abs() < 150.0 {
        return Err((
            "radius_m",
            format!("{radius_m}: |R| must be at least 150 m (empty for a straight)"),
        ));
    }
    let cant_mm = number(f[3], "cant_mm", 0.0, 200.0, "mm")?;
    let transition_m = number(f[4], "transition_m", 1.0, 1e4, "m")?;
    if 2.0 * transition_m > length_m {
        return Err((
            "transition_m",
            format!(
                "two transitions of {transition_m} m do not fit in the section's length_m = {length_m} m (it holds both transitions and the arc)"
            ),
        ));
    }
    let shape = match f[5] {
        "clothoid" | "" => TransitionShape::Clothoid,
        "cosine" => TransitionShape::Cosine,
        "bloss" => TransitionShape::Bloss,
        other => {
            return Err((
                "shape",
                format!("`{other}`; expected clothoid, cosine or bloss"),
            ))
        }
    };
    Ok(Curve {
        radius_m,
        cant_mm,
        transition_m,
        shape,
    })
}

/// The checks across sections: contiguous chainage, straights at both ends and between curves.
fn check_line(s: &[Section]) -> Result<(), (usize, &'static str, String)> {
    let Some(first) = s.first() else {
        return Err((
            0,
            "",
            "no sections: a route has at least one curve between two straights".into(),
        ));
    };
    let last = s[s.len() - 1];
    if first.curve.is_some() || last.curve.is_some() {
        let bad = if first.curve.is_some() { *first } else { last };
        return Err((
            bad.line,
            "radius_m",
            "the line starts and ends on a straight (radius_m empty): the vehicle runs in from and out to straight track".into(),
        ));
    }
    for w in s.windows(2) {
        let (a, b) = (w[0], w[1]);
        if (b.chainage_m - a.end_m()).abs() > 1e-6 * a.end_m().max(1.0) {
            return Err((
                b.line,
                "chainage_m",
                format!(
                    "{} does not continue the section of line {}, which ends at {} m",
                    b.chainage_m,
                    a.line,
                    a.end_m()
                ),
            ));
        }
        if a.curve.is_some() && b.curve.is_some() {
            return Err((
                b.line,
                "radius_m",
                format!(
                    "a curve right after the curve of line {}: put a straight between them",
                    a.line
                ),
            ));
        }
    }
    if !s.iter().any(|x| x.curve.is_some()) {
        return Err((
            0,
            "",
            "no curve: a route has at least one section with a radius_m".into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "chainage_m,length_m,radius_m,cant_mm,transition_m,shape,vmax_conventional_kmh,vmax_tilting_kmh\n";

    fn parse_text(body: &str) -> Result<Route, RouteError> {
        parse(&format!("{HEADER}{body}"), Path::new("line.csv"))
    }

    #[test]
    fn a_line_is_read_with_its_curves_and_limits() {
        let r = parse_text(
            "# a comment\n0,1000,,,,,160,200\n1000,700,-1200,120,110,cosine,150,190\n1700,500,,0,,,160,200\n",
        )
        .unwrap();
        assert_eq!(r.name, "line");
        assert_eq!(r.sections.len(), 3);
        assert_eq!(r.curves(), 1);
        let c = r.sections[1].curve.unwrap();
        assert_eq!(
            (c.radius_m, c.cant_mm, c.shape),
            (-1200.0, 120.0, TransitionShape::Cosine)
        );
        assert_eq!(r.sections[1].line, 4);
        assert_eq!(r.length_m(), 2200.0);
        // 150 mm of cant over 1500 mm is asin(0.1).
        let c = Curve {
            cant_mm: 150.0,
            ..c
        };
        assert!((c.cant_rad() - 0.1f64.asin()).abs() < 1e-15);
    }

    #[test]
    fn errors_name_the_file_the_line_and_the_field() {
        let cases = [
            ("0,1000,,,,,160,200\n1000,700,-1200,120,110,spiral,150,190\n1700,500,,,,,160,200\n", 3, "shape"),
            ("0,1000,,,,,160,200\n1000,700,100,120,110,clothoid,150,190\n1700,500,,,,,160,200\n", 3, "radius_m"),
            ("0,1000,,,,,160,200\n1000,700,1200,250,110,clothoid,150,190\n1700,500,,,,,160,200\n", 3, "cant_mm"),
            ("0,1000,,,,,160,200\n1000,700,1200,120,400,clothoid,150,190\n1700,500,,,,,160,200\n", 3, "transition_m"),
            ("0,1000,,,,,160,200\n1010,700,1200,120,110,clothoid,150,190\n1710,500,,,,,160,200\n", 3, "chainage_m"),
            ("0,1000,,,,,160,x\n1000,700,1200,120,110,clothoid,150,190\n1700,500,,,,,160,200\n", 2, "vmax_tilting_kmh"),
            ("0,1000,,50,,,160,200\n1000,700,1200,120,110,clothoid,150,190\n1700,500,,,,,160,200\n", 2, "cant_mm"),
            ("0,1000,1200,120,110,clothoid,160,200\n1000,500,,,,,160,200\n", 2, "radius_m"),
            ("0,1000,,,,,160,200\n1000,700,1200,120,110,clothoid,150,190\n1700,700,900,120,110,clothoid,150,190\n2400,500,,,,,160,200\n", 4, "radius_m"),
        ];
        for (body, line, field) in cases {
            let e = parse_text(body).unwrap_err();
            assert_eq!((e.line, e.field.as_str()), (line, field), "{e}");
            let shown = e.to_string();
            assert!(
                shown.starts_with(&format!("line.csv:{line}: {field}: ")),
                "{shown}"
            );
        }
        let e = parse("a,b\n1,2\n", Path::new("x.csv")).unwrap_err();
        assert_eq!(e.line, 1);
        assert!(
            e.to_string().contains("expected `chainage_m,length_m"),
            "{e}"
        );
        let e = parse_text("0,1000,,,,,160\n").unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (2, ""));
    }
}
