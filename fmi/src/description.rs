//! `modelDescription.xml`: written for tiltsim's own FMUs (FMI 3.0), read for any FMU (FMI 2.0
//! and 3.0, co-simulation).

use std::fmt::Write as _;

use tiltsim_protocol::msg::ScalarType;

use crate::layout::{fmi3_scalar_type, Layout, ParamValue};
use crate::units::UNIT_DEFS;

/// What the exporter says about the FMU besides its variables.
#[derive(Debug, Clone)]
pub struct ExportInfo {
    /// `modelName`.
    pub model_name: String,
    /// `modelIdentifier`: the library's file name without `.so`.
    pub model_identifier: String,
    /// `instantiationToken`.
    pub token: String,
    /// What the model is (the scenario's description).
    pub description: String,
    /// The step it takes inside (s): FMI 3 `fixedInternalStepSize`, and the
    /// `<DefaultExperiment stepSize>`. The importer steps with whole multiples of it.
    pub step_s: f64,
    /// Whether the communication step may change from call to call
    /// (`canHandleVariableCommunicationStepSize`).
    pub variable_step: bool,
    /// The scenario's duration (s), for `<DefaultExperiment>`.
    pub stop_s: f64,
}

/// `s` as XML attribute text: markup characters escaped, line breaks and tabs as spaces.
pub(crate) fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\n' | '\r' | '\t' => o.push(' '),
            c => o.push(c),
        }
    }
    o
}

/// A real in the shortest form that reads back to the same bits.
pub fn real(v: f64) -> String {
    format!("{v:e}")
}

/// The FMI 3.0 co-simulation model description of `layout`.
pub fn write_fmi3(layout: &Layout, info: &ExportInfo) -> String {
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="3.0" modelName="{}" instantiationToken="{}" description="{}" generationTool="tiltsim {}" variableNamingConvention="flat">"#,
        esc(&info.model_name),
        esc(&info.token),
        esc(&info.description),
        env!("CARGO_PKG_VERSION"),
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{}" canHandleVariableCommunicationStepSize="{}" fixedInternalStepSize="{}" canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="false" canSerializeFMUState="false" hasEventMode="false" providesIntermediateUpdate="false" mightReturnEarlyFromDoStep="false"/>"#,
        esc(&info.model_identifier),
        info.variable_step,
        real(info.step_s)
    );
    units_xml(layout, &mut x);
    let _ = writeln!(
        x,
        r#"  <DefaultExperiment startTime="0" stopTime="{}" stepSize="{}"/>"#,
        real(info.stop_s),
        real(info.step_s)
    );
    x.push_str("  <ModelVariables>\n");
    x.push_str(r#"    <Float64 name="time" valueReference="0" causality="independent" variability="continuous" unit="s" description="Simulated time"/>"#);
    x.push('\n');
    fmi3_scalars(layout, &mut x);
    fmi3_parameters(layout, &mut x);
    x.push_str("  </ModelVariables>\n  <ModelStructure>\n");
    for i in 0..layout.outputs.len() {
        let deps: Vec<String> = layout
            .direct_inputs(i)
            .iter()
            .map(|&j| layout.input_vr(j).to_string())
            .collect();
        let _ = writeln!(
            x,
            r#"    <Output valueReference="{}" dependencies="{}"/>"#,
            layout.output_vr(i),
            deps.join(" ")
        );
    }
    for i in 0..layout.outputs.len() {
        let _ = writeln!(
            x,
            r#"    <InitialUnknown valueReference="{}"/>"#,
            layout.output_vr(i)
        );
    }
    x.push_str("  </ModelStructure>\n</fmiModelDescription>\n");
    x
}

/// The FMI 3.0 variables of the inputs and the outputs of `layout`.
fn fmi3_scalars(layout: &Layout, x: &mut String) {
    for (i, s) in layout.inputs.iter().enumerate() {
        let (var, start) = match s.ty {
            ScalarType::F64 => ("continuous", "0"),
            ScalarType::U32 => ("discrete", "0"),
        };
        let _ = writeln!(
            x,
            r#"    <{t} name="{n}" valueReference="{vr}" causality="input" variability="{var}" start="{start}"{u} description="{d}"/>"#,
            t = fmi3_scalar_type(s.ty),
            n = esc(&s.name),
            vr = layout.input_vr(i),
            u = if s.ty == ScalarType::F64 {
                unit_attr(s.unit)
            } else {
                String::new()
            },
            d = esc(s.description),
        );
    }
    for (i, s) in layout.outputs.iter().enumerate() {
        let var = match s.ty {
            ScalarType::F64 => "continuous",
            ScalarType::U32 => "discrete",
        };
        let _ = writeln!(
            x,
            r#"    <{t} name="{n}" valueReference="{vr}" causality="output" variability="{var}" initial="calculated"{u} description="{d}"/>"#,
            t = fmi3_scalar_type(s.ty),
            n = esc(&s.name),
            vr = layout.output_vr(i),
            u = if s.ty == ScalarType::F64 {
                unit_attr(s.unit)
            } else {
                String::new()
            },
            d = esc(s.description),
        );
    }
}

/// The FMI 3.0 variables of the parameters of `layout`.
fn fmi3_parameters(layout: &Layout, x: &mut String) {
    for (i, p) in layout.params.iter().enumerate() {
        let vr = layout.param_vr(i);
        let head = format!(
            r#"    <{t} name="{n}" valueReference="{vr}" causality="parameter" variability="fixed"{d}"#,
            t = p.value.fmi3_type(),
            n = esc(&p.name),
            d = description_attr(p.description),
        );
        let _ = match &p.value {
            ParamValue::F64(v) => {
                writeln!(x, r#"{head} start="{}"{}/>"#, real(*v), unit_attr(p.unit))
            }
            ParamValue::U64(v) => writeln!(x, r#"{head} start="{v}"/>"#),
            ParamValue::I64(v) => writeln!(x, r#"{head} start="{v}"/>"#),
            ParamValue::Bool(v) => writeln!(x, r#"{head} start="{v}"/>"#),
            ParamValue::Str(v) => writeln!(
                x,
                "{head}>\n      <Start value=\"{}\"/>\n    </String>",
                esc(v)
            ),
        };
    }
}

/// The FMI 2.0 co-simulation model description of `layout` (same value references as FMI
/// 3.0; FMI 2.0 has no 64-bit integers: unsigned and 64-bit values are `Integer`, and a value
/// that does not fit 32 bits is an error).
pub fn write_fmi2(layout: &Layout, info: &ExportInfo) -> Result<String, String> {
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="2.0" modelName="{}" guid="{}" description="{}" generationTool="tiltsim {}" variableNamingConvention="flat" numberOfEventIndicators="0">"#,
        esc(&info.model_name),
        esc(&info.token),
        esc(&info.description),
        env!("CARGO_PKG_VERSION"),
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{}" canHandleVariableCommunicationStepSize="{}" canInterpolateInputs="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="false" canSerializeFMUstate="false"/>"#,
        esc(&info.model_identifier),
        info.variable_step,
    );
    units_xml(layout, &mut x);
    let _ = writeln!(
        x,
        r#"  <DefaultExperiment startTime="0" stopTime="{}" stepSize="{}"/>"#,
        real(info.stop_s),
        real(info.step_s)
    );
    x.push_str("  <ModelVariables>\n");
    let outputs = fmi2_scalars(layout, &mut x);
    fmi2_parameters(layout, &mut x)?;
    x.push_str("  </ModelVariables>\n  <ModelStructure>\n    <Outputs>\n");
    for (o, i) in outputs.iter().enumerate() {
        // The inputs are the first variables: input j has index j + 1.
        let deps: Vec<String> = layout
            .direct_inputs(o)
            .iter()
            .map(|&j| (j + 1).to_string())
            .collect();
        let _ = writeln!(
            x,
            r#"      <Unknown index="{i}" dependencies="{}"/>"#,
            deps.join(" ")
        );
    }
    x.push_str("    </Outputs>\n    <InitialUnknowns>\n");
    for i in &outputs {
        let _ = writeln!(x, r#"      <Unknown index="{i}"/>"#);
    }
    x.push_str("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n");
    Ok(x)
}

/// The FMI 2.0 variables of the inputs and the outputs of `layout`; returns the outputs'
/// indices (1-based, in the order of the variables).
fn fmi2_scalars(layout: &Layout, x: &mut String) -> Vec<usize> {
    let mut index = 0usize;
    let mut outputs = Vec::new();
    for (i, s) in layout.inputs.iter().enumerate() {
        index += 1;
        let (var, ty) = match s.ty {
            ScalarType::F64 => (
                "continuous",
                format!(r#"<Real start="0"{}/>"#, unit_attr(s.unit)),
            ),
            ScalarType::U32 => ("discrete", r#"<Integer start="0"/>"#.to_string()),
        };
        let _ = writeln!(
            x,
            r#"    <ScalarVariable name="{}" valueReference="{}" causality="input" variability="{var}" description="{}">{ty}</ScalarVariable>"#,
            esc(&s.name),
            layout.input_vr(i),
            esc(s.description),
        );
    }
    for (i, s) in layout.outputs.iter().enumerate() {
        index += 1;
        outputs.push(index);
        let (var, ty) = match s.ty {
            ScalarType::F64 => ("continuous", format!(r#"<Real{}/>"#, unit_attr(s.unit))),
            ScalarType::U32 => ("discrete", "<Integer/>".to_string()),
        };
        let _ = writeln!(
            x,
            r#"    <ScalarVariable name="{}" valueReference="{}" causality="output" variability="{var}" initial="calculated" description="{}">{ty}</ScalarVariable>"#,
            esc(&s.name),
            layout.output_vr(i),
            esc(s.description),
        );
    }
    outputs
}

/// The FMI 2.0 variables of the parameters of `layout`; a value that does not fit 32 bits is
/// an error.
fn fmi2_parameters(layout: &Layout, x: &mut String) -> Result<(), String> {
    for (i, p) in layout.params.iter().enumerate() {
        let int = |v: i64| {
            i32::try_from(v).map_err(|_| {
                format!(
                    "parameter `{}` = {v} does not fit an FMI 2.0 Integer (32 bits); export FMI 3.0",
                    p.name
                )
            })
        };
        let ty = match &p.value {
            ParamValue::F64(v) => format!(r#"<Real start="{}"{}/>"#, real(*v), unit_attr(p.unit)),
            ParamValue::U64(v) => format!(
                r#"<Integer start="{}"/>"#,
                int(i64::try_from(*v).unwrap_or(i64::MAX))?
            ),
            ParamValue::I64(v) => format!(r#"<Integer start="{}"/>"#, int(*v)?),
            ParamValue::Bool(v) => format!(r#"<Boolean start="{v}"/>"#),
            ParamValue::Str(v) => format!(r#"<String start="{}"/>"#, esc(v)),
        };
        let _ = writeln!(
            x,
            r#"    <ScalarVariable name="{}" valueReference="{}" causality="parameter" variability="fixed" initial="exact"{}>{ty}</ScalarVariable>"#,
            esc(&p.name),
            layout.param_vr(i),
            description_attr(p.description),
        );
    }
    Ok(())
}

/// The `unit` attribute of unit `u` (none for a unitless value).
fn unit_attr(u: &str) -> String {
    if u.is_empty() {
        String::new()
    } else {
        format!(r#" unit="{}""#, esc(u))
    }
}

/// The `description` attribute of description `d` (none where it is empty).
fn description_attr(d: &str) -> String {
    if d.is_empty() {
        String::new()
    } else {
        format!(r#" description="{}""#, esc(d))
    }
}

/// `<UnitDefinitions>` of the units `layout` uses.
fn units_xml(layout: &Layout, x: &mut String) {
    let mut used: Vec<&str> = layout.inputs.iter().map(|s| s.unit).collect();
    used.extend(layout.outputs.iter().map(|s| s.unit));
    used.extend(layout.params.iter().map(|p| p.unit));
    x.push_str("  <UnitDefinitions>\n");
    for (name, (kg, m, s, a, rad, factor)) in UNIT_DEFS {
        if !used.contains(name) {
            continue;
        }
        let mut b = String::new();
        for (k, e) in [("kg", kg), ("m", m), ("s", s), ("A", a), ("rad", rad)] {
            if *e != 0 {
                let _ = write!(b, r#" {k}="{e}""#);
            }
        }
        if *factor != 1.0 {
            let _ = write!(b, r#" factor="{}""#, real(*factor));
        }
        let _ = writeln!(x, r#"    <Unit name="{}"><BaseUnit{b}/></Unit>"#, esc(name));
    }
    x.push_str("  </UnitDefinitions>\n");
}

/// FMI version of an FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmiVersion {
    /// FMI 2.0.
    V2,
    /// FMI 3.0.
    V3,
}

impl core::fmt::Display for FmiVersion {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FmiVersion::V2 => "FMI 2.0",
            FmiVersion::V3 => "FMI 3.0",
        })
    }
}

/// A variable's type as tiltsim can exchange it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarKind {
    /// FMI 2 `Real`, FMI 3 `Float64`.
    Real,
    /// FMI 2 `Integer`, FMI 3 `Int32`.
    Int32,
    /// FMI 3 `UInt32`.
    UInt32,
    /// FMI 3 `UInt64`.
    UInt64,
    /// FMI 3 `Int64`.
    Int64,
    /// `Boolean`.
    Boolean,
    /// `String`.
    Str,
    /// Anything else (FMI 3 `Float32`, `Int8`, `Binary`, `Clock`, …): listed, never exchanged.
    Other,
}

/// A variable of an FMU as its description declares it.
#[derive(Debug, Clone)]
pub struct VarDesc {
    /// Name.
    pub name: String,
    /// Value reference.
    pub vr: u32,
    /// `causality` (FMI's default `local` where absent).
    pub causality: String,
    /// Type.
    pub kind: VarKind,
    /// The type's element name as written (`Real`, `Float64`, …).
    pub type_name: String,
    /// Declared array dimensions (FMI 3 arrays are not supported).
    pub is_array: bool,
    /// The `unit` the variable (or its type element in FMI 2) declares.
    pub unit: Option<String>,
    /// Its `description`.
    pub description: Option<String>,
}

/// What tiltsim needs from an FMU's `modelDescription.xml`.
#[derive(Debug, Clone)]
pub struct ModelDescription {
    /// Version.
    pub version: FmiVersion,
    /// `modelName`.
    pub model_name: String,
    /// FMI 2 `guid`, FMI 3 `instantiationToken`.
    pub token: String,
    /// The co-simulation `modelIdentifier`; `None` for a model-exchange-only FMU.
    pub cs_identifier: Option<String>,
    /// Whether it has a model-exchange interface.
    pub has_model_exchange: bool,
    /// `canHandleVariableCommunicationStepSize`.
    pub variable_step: bool,
    /// FMI 3 `fixedInternalStepSize`.
    pub fixed_step: Option<f64>,
    /// `<DefaultExperiment stepSize>`.
    pub default_step: Option<f64>,
    /// Whether it has a `<DefaultExperiment>`.
    pub has_default_experiment: bool,
    /// The value references `<ModelStructure>` lists as outputs (FMI 3 `<Output>`, FMI 2
    /// `<Outputs><Unknown index>`); `None` without a `<ModelStructure>`.
    pub structure_outputs: Option<Vec<u32>>,
    /// The variables.
    pub vars: Vec<VarDesc>,
}

/// The value references of the outputs `<ModelStructure>` lists.
fn structure_outputs(
    ms: roxmltree::Node,
    mv: Option<roxmltree::Node>,
    version: FmiVersion,
) -> Vec<u32> {
    match version {
        FmiVersion::V3 => ms
            .children()
            .filter(|c| c.has_tag_name("Output"))
            .filter_map(|c| c.attribute("valueReference")?.trim().parse().ok())
            .collect(),
        FmiVersion::V2 => {
            // FMI 2 names a variable by its 1-based place among <ModelVariables>' elements.
            let order: Vec<Option<u32>> = mv.map_or_else(Vec::new, |mv| {
                mv.children()
                    .filter(|c| c.is_element())
                    .map(|e| e.attribute("valueReference")?.trim().parse().ok())
                    .collect()
            });
            ms.children()
                .filter(|c| c.has_tag_name("Outputs"))
                .flat_map(|o| o.children().filter(|c| c.has_tag_name("Unknown")))
                .filter_map(|u| {
                    let i: usize = u.attribute("index")?.trim().parse().ok()?;
                    *order.get(i.checked_sub(1)?)?
                })
                .collect()
        }
    }
}

/// The FMI version an `fmiModelDescription` element declares (2.x or 3.x).
fn version_of(root: roxmltree::Node) -> Result<FmiVersion, String> {
    let v = root.attribute("fmiVersion").unwrap_or("");
    if v.starts_with("2.") {
        Ok(FmiVersion::V2)
    } else if v.starts_with("3.") {
        Ok(FmiVersion::V3)
    } else {
        Err(format!(
            "fmiVersion `{v}`: tiltsim reads FMI 2.0 and FMI 3.0 FMUs"
        ))
    }
}

/// The variables of a `<ModelVariables>` element of `version` that have a name and a value
/// reference.
fn variables(mv: roxmltree::Node, version: FmiVersion) -> Vec<VarDesc> {
    let mut vars = Vec::new();
    for e in mv.children().filter(|c| c.is_element()) {
        let (type_name, kind, is_array) = var_type(e, version);
        let (Some(name), Some(vr)) = (
            e.attribute("name"),
            e.attribute("valueReference")
                .and_then(|s| s.trim().parse().ok()),
        ) else {
            continue;
        };
        // FMI 3 puts the unit on the variable, FMI 2 on its type element.
        let unit = e
            .attribute("unit")
            .or_else(|| {
                e.children()
                    .find(|c| c.is_element())
                    .and_then(|c| c.attribute("unit"))
            })
            .map(str::to_string);
        vars.push(VarDesc {
            name: name.to_string(),
            vr,
            causality: e.attribute("causality").unwrap_or("local").to_string(),
            kind,
            type_name,
            is_array,
            unit,
            description: e.attribute("description").map(str::to_string),
        });
    }
    vars
}

/// The type of variable element `e`: its name, its kind and whether it is an array (FMI 2.0
/// names it by a child element and has no arrays; FMI 3.0 by the element, with dimensions).
fn var_type(e: roxmltree::Node, version: FmiVersion) -> (String, VarKind, bool) {
    match version {
        FmiVersion::V2 => {
            let t = e
                .children()
                .find(|c| c.is_element())
                .map(|c| c.tag_name().name().to_string())
                .unwrap_or_default();
            let k = match t.as_str() {
                "Real" => VarKind::Real,
                "Integer" | "Enumeration" => VarKind::Int32,
                "Boolean" => VarKind::Boolean,
                "String" => VarKind::Str,
                _ => VarKind::Other,
            };
            (t, k, false)
        }
        FmiVersion::V3 => {
            let t = e.tag_name().name().to_string();
            let k = match t.as_str() {
                "Float64" => VarKind::Real,
                "Int32" | "Enumeration" => VarKind::Int32,
                "UInt32" => VarKind::UInt32,
                "Int64" => VarKind::Int64,
                "UInt64" => VarKind::UInt64,
                "Boolean" => VarKind::Boolean,
                "String" => VarKind::Str,
                _ => VarKind::Other,
            };
            let arr = e.children().any(|c| c.has_tag_name("Dimension"));
            (t, k, arr)
        }
    }
}

impl ModelDescription {
    /// Reads a description; the error says what is wrong.
    pub fn parse(xml: &str) -> Result<ModelDescription, String> {
        let doc = roxmltree::Document::parse(xml).map_err(|e| format!("not XML: {e}"))?;
        let root = doc.root_element();
        if root.tag_name().name() != "fmiModelDescription" {
            return Err(format!(
                "root element is <{}>, not <fmiModelDescription>",
                root.tag_name().name()
            ));
        }
        let version = version_of(root)?;
        let token = match version {
            FmiVersion::V2 => root.attribute("guid"),
            FmiVersion::V3 => root.attribute("instantiationToken"),
        }
        .unwrap_or("")
        .to_string();
        let child = |n: &str| root.children().find(|c| c.has_tag_name(n));
        let cs = child("CoSimulation");
        let flag = |a: &str| cs.and_then(|c| c.attribute(a)) == Some("true");
        let num = |n: Option<roxmltree::Node>, a: &str| {
            n.and_then(|c| c.attribute(a))
                .and_then(|s| s.trim().parse::<f64>().ok())
        };
        let vars = child("ModelVariables").map_or_else(Vec::new, |mv| variables(mv, version));
        Ok(ModelDescription {
            version,
            model_name: root.attribute("modelName").unwrap_or("").to_string(),
            token,
            cs_identifier: cs
                .and_then(|c| c.attribute("modelIdentifier"))
                .map(str::to_string),
            has_model_exchange: child("ModelExchange").is_some(),
            variable_step: flag("canHandleVariableCommunicationStepSize"),
            fixed_step: num(cs, "fixedInternalStepSize"),
            default_step: num(child("DefaultExperiment"), "stepSize"),
            has_default_experiment: child("DefaultExperiment").is_some(),
            structure_outputs: child("ModelStructure")
                .map(|ms| structure_outputs(ms, child("ModelVariables"), version)),
            vars,
        })
    }

    /// The variable called `name`.
    pub fn var(&self, name: &str) -> Option<&VarDesc> {
        self.vars.iter().find(|v| v.name == name)
    }
}
