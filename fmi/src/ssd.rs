//! SSP 1.0 system structure (`SystemStructure.ssd`): FMUs as components, their connectors,
//! parameter values and connections, and the step of each, as co-simulation masters that read
//! SSP load them (libcosim's `ssp_loader`, OMSimulator).
//!
//! The step sizes use the Open Simulation Platform's annotations (type
//! `com.opensimulationplatform`): `osp:FixedStepAlgorithm baseStepSize` on the default
//! experiment and `osp:StepSizeHint` on each component; masters that do not know them ignore
//! them. Elements whose children a reader iterates (`ssd:Elements`, `ssd:Connections`,
//! `ssv:Parameters`, `osp:Algorithm`) carry no attributes of their own.

use std::fmt::Write as _;

use crate::description::{esc, real};
use crate::layout::ParamValue;

/// The type of a connector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConnectorType {
    /// `ssc:Real`.
    Real,
    /// `ssc:Integer`.
    Integer,
}

/// A connector of a component: one of its FMU's inputs or outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Connector {
    /// The FMU variable's name.
    pub name: String,
    /// `true` for an output, `false` for an input.
    pub output: bool,
    /// Its type.
    pub ty: ConnectorType,
}

/// A component: one FMU of the system.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    /// The instance name.
    pub name: String,
    /// The FMU's path relative to the `.ssd` file.
    pub source: String,
    /// Its inputs and outputs.
    pub connectors: Vec<Connector>,
    /// Parameter values set before initialisation (FMU variable name, value).
    pub parameters: Vec<(String, ParamValue)>,
    /// The communication step it is given (s).
    pub step_s: f64,
}

/// A connection from an output to an input.
#[derive(Debug, Clone, PartialEq)]
pub struct Connection {
    /// Component and connector of the output.
    pub from: (String, String),
    /// Component and connector of the input.
    pub to: (String, String),
}

/// A system of FMUs.
#[derive(Debug, Clone, PartialEq)]
pub struct System {
    /// The system's name.
    pub name: String,
    /// What it is.
    pub description: String,
    /// The base step of the master (s).
    pub base_step_s: f64,
    /// The default stop time (s).
    pub stop_s: f64,
    /// The FMUs.
    pub components: Vec<Component>,
    /// The connections.
    pub connections: Vec<Connection>,
}

/// Why a system cannot be written as SSP 1.0.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SsdError {
    /// An integer parameter outside SSP's (and FMI 2.0's) 32 bits.
    #[error("parameter `{component}.{name}` = {value} does not fit an SSP Integer (32 bits)")]
    Integer {
        /// The component.
        component: String,
        /// The parameter.
        name: String,
        /// Its value.
        value: String,
    },
    /// A connection that names a connector the system does not have.
    #[error("connection {from} -> {to}: {why}")]
    Connection {
        /// `component.connector` of the output.
        from: String,
        /// `component.connector` of the input.
        to: String,
        /// What is missing.
        why: String,
    },
}

/// One `ssv:Parameter` element.
fn parameter(component: &str, name: &str, v: &ParamValue) -> Result<String, SsdError> {
    let int = |value: String, fits: Option<i32>| {
        fits.map(|i| format!(r#"<ssv:Integer value="{i}"/>"#))
            .ok_or_else(|| SsdError::Integer {
                component: component.to_string(),
                name: name.to_string(),
                value,
            })
    };
    let body = match v {
        ParamValue::F64(x) => format!(r#"<ssv:Real value="{}"/>"#, real(*x)),
        ParamValue::U64(x) => int(x.to_string(), i32::try_from(*x).ok())?,
        ParamValue::I64(x) => int(x.to_string(), i32::try_from(*x).ok())?,
        ParamValue::Bool(b) => format!(r#"<ssv:Boolean value="{b}"/>"#),
        ParamValue::Str(s) => format!(r#"<ssv:String value="{}"/>"#, esc(s)),
    };
    Ok(format!(
        "                  <ssv:Parameter name=\"{}\">{body}</ssv:Parameter>\n",
        esc(name)
    ))
}

/// Checks that every connection joins an output to an input of the system, and that no input
/// is fed twice.
fn check_connections(sys: &System) -> Result<(), SsdError> {
    let find = |(c, n): &(String, String)| {
        sys.components
            .iter()
            .find(|k| &k.name == c)
            .and_then(|k| k.connectors.iter().find(|x| &x.name == n))
    };
    for (i, k) in sys.connections.iter().enumerate() {
        let err = |why: String| SsdError::Connection {
            from: format!("{}.{}", k.from.0, k.from.1),
            to: format!("{}.{}", k.to.0, k.to.1),
            why,
        };
        match (find(&k.from), find(&k.to)) {
            (Some(a), Some(b)) if a.output && !b.output && a.ty == b.ty => {}
            (Some(_), Some(_)) => {
                return Err(err("allowed an output to an input of the same type".into()))
            }
            (None, _) => return Err(err("no such output".into())),
            (_, None) => return Err(err("no such input".into())),
        }
        if sys.connections[..i].iter().any(|o| o.to == k.to) {
            return Err(err("the input is fed by an earlier connection".into()));
        }
    }
    Ok(())
}

/// The `SystemStructure.ssd` text of `sys`.
pub fn write_ssd(sys: &System) -> Result<String, SsdError> {
    check_connections(sys)?;
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        x,
        r#"<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations" name="{}" version="1.0" generationTool="tiltsim {}">"#,
        esc(&sys.name),
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        x,
        r#"  <ssd:System name="{}" description="{}">"#,
        esc(&sys.name),
        esc(&sys.description)
    );
    x.push_str("    <ssd:Elements>\n");
    for c in &sys.components {
        let _ = writeln!(
            x,
            r#"      <ssd:Component name="{}" source="{}" type="application/x-fmu-sharedlibrary">"#,
            esc(&c.name),
            esc(&c.source)
        );
        x.push_str("        <ssd:Connectors>\n");
        // Inputs first, then outputs.
        for output in [false, true] {
            for k in c.connectors.iter().filter(|k| k.output == output) {
                let ty = match k.ty {
                    ConnectorType::Real => "<ssc:Real/>",
                    ConnectorType::Integer => "<ssc:Integer/>",
                };
                let _ = writeln!(
                    x,
                    r#"          <ssd:Connector name="{}" kind="{}">{ty}</ssd:Connector>"#,
                    esc(&k.name),
                    if output { "output" } else { "input" }
                );
            }
        }
        x.push_str("        </ssd:Connectors>\n");
        if !c.parameters.is_empty() {
            x.push_str("        <ssd:ParameterBindings>\n          <ssd:ParameterBinding>\n            <ssd:ParameterValues>\n");
            let _ = writeln!(
                x,
                r#"              <ssv:ParameterSet version="1.0" name="{}">"#,
                esc(&c.name)
            );
            x.push_str("                <ssv:Parameters>\n");
            for (name, v) in &c.parameters {
                x.push_str(&parameter(&c.name, name, v)?);
            }
            x.push_str("                </ssv:Parameters>\n              </ssv:ParameterSet>\n            </ssd:ParameterValues>\n          </ssd:ParameterBinding>\n        </ssd:ParameterBindings>\n");
        }
        let _ = writeln!(
            x,
            r#"        <ssd:Annotations><ssc:Annotation type="com.opensimulationplatform"><osp:StepSizeHint value="{}"/></ssc:Annotation></ssd:Annotations>"#,
            real(c.step_s)
        );
        x.push_str("      </ssd:Component>\n");
    }
    x.push_str("    </ssd:Elements>\n    <ssd:Connections>\n");
    for k in &sys.connections {
        let _ = writeln!(
            x,
            r#"      <ssd:Connection startElement="{}" startConnector="{}" endElement="{}" endConnector="{}"/>"#,
            esc(&k.from.0),
            esc(&k.from.1),
            esc(&k.to.0),
            esc(&k.to.1)
        );
    }
    x.push_str("    </ssd:Connections>\n  </ssd:System>\n");
    let _ = writeln!(
        x,
        r#"  <ssd:DefaultExperiment startTime="0" stopTime="{}">"#,
        real(sys.stop_s)
    );
    let _ = writeln!(
        x,
        r#"    <ssd:Annotations><ssc:Annotation type="com.opensimulationplatform"><osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="{}"/></osp:Algorithm></ssc:Annotation></ssd:Annotations>"#,
        real(sys.base_step_s)
    );
    x.push_str("  </ssd:DefaultExperiment>\n</ssd:SystemStructureDescription>\n");
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn system() -> System {
        let conn = |name: &str, output| Connector {
            name: name.into(),
            output,
            ty: ConnectorType::Real,
        };
        System {
            name: "s & t".into(),
            description: "two <FMUs>".into(),
            base_step_s: 1e-3,
            stop_s: 16.8,
            components: vec![
                Component {
                    name: "a".into(),
                    source: "a.fmu".into(),
                    connectors: vec![conn("y", true), conn("u", false)],
                    parameters: vec![
                        ("k".into(), ParamValue::F64(0.1)),
                        ("n".into(), ParamValue::U64(7)),
                        ("on".into(), ParamValue::Bool(true)),
                        ("mode".into(), ParamValue::Str("mpc".into())),
                    ],
                    step_s: 1e-3,
                },
                Component {
                    name: "b".into(),
                    source: "b.fmu".into(),
                    connectors: vec![conn("u", false), conn("y", true)],
                    parameters: vec![],
                    step_s: 0.05,
                },
            ],
            connections: vec![
                Connection {
                    from: ("a".into(), "y".into()),
                    to: ("b".into(), "u".into()),
                },
                Connection {
                    from: ("b".into(), "y".into()),
                    to: ("a".into(), "u".into()),
                },
            ],
        }
    }

    #[test]
    fn a_system_is_written_with_its_parameters_steps_and_connections_and_reads_as_xml() {
        let text = write_ssd(&system()).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        let root = doc.root_element();
        assert_eq!(root.tag_name().name(), "SystemStructureDescription");
        assert_eq!(root.attribute("name"), Some("s & t"));
        let by = |n: &'static str| doc.descendants().filter(move |e| e.has_tag_name(n));
        assert_eq!(by("Component").count(), 2);
        assert_eq!(by("Connection").count(), 2);
        let hints: Vec<_> = by("StepSizeHint")
            .map(|e| e.attribute("value").unwrap().parse::<f64>().unwrap())
            .collect();
        assert_eq!(hints, [1e-3, 0.05]);
        let base = by("FixedStepAlgorithm").next().unwrap();
        assert_eq!(base.attribute("baseStepSize"), Some("1e-3"));
        let params: Vec<_> = by("Parameter")
            .map(|p| {
                let v = p.first_element_child().unwrap();
                (
                    p.attribute("name").unwrap(),
                    v.tag_name().name(),
                    v.attribute("value").unwrap(),
                )
            })
            .collect();
        assert_eq!(
            params,
            [
                ("k", "Real", "1e-1"),
                ("n", "Integer", "7"),
                ("on", "Boolean", "true"),
                ("mode", "String", "mpc")
            ]
        );
        // Inputs before outputs in each component.
        let kinds: Vec<_> = by("Connector")
            .map(|c| c.attribute("kind").unwrap())
            .collect();
        assert_eq!(kinds, ["input", "output", "input", "output"]);
        // The elements a reader iterates over have no attributes.
        for n in ["Elements", "Connections", "Parameters", "Algorithm"] {
            assert!(by(n).all(|e| e.attributes().len() == 0), "{n}");
        }
    }

    #[test]
    fn connections_that_do_not_join_an_output_to_one_free_input_are_refused() {
        let mut s = system();
        s.connections[0].from.1 = "u".into();
        let e = write_ssd(&s).unwrap_err().to_string();
        assert!(
            e.contains("a.u -> b.u") && e.contains("output to an input"),
            "{e}"
        );
        let mut s = system();
        s.connections[1].to = ("b".into(), "u".into());
        let e = write_ssd(&s).unwrap_err().to_string();
        assert!(e.contains("fed by an earlier connection"), "{e}");
        let mut s = system();
        s.connections[0].to.0 = "c".into();
        assert!(write_ssd(&s)
            .unwrap_err()
            .to_string()
            .contains("no such input"));
        let mut s = system();
        s.components[0].parameters = vec![("big".into(), ParamValue::U64(1 << 40))];
        let e = write_ssd(&s).unwrap_err().to_string();
        assert!(e.contains("a.big") && e.contains("32 bits"), "{e}");
    }
}
