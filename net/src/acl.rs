//! Zenoh's access control for a run, deny by default.
//!
//! The orchestrator admits each remote role, known by the common name of its certificate
//! under the run's authority ([`crate::credentials`]), to exactly what serving that role takes, in this run only:
//!
//! | what the role does | messages | keys (under `tiltsim/run/<run>/`) |
//! |---|---|---|
//! | finds the run, measures the clock, says hello | query in, reply out | `*/offer` (any run's), `offer`, `clock`, `join/<role>` |
//! | takes its requests and process faults | subscriber in, put out | `<role>/request`, `<role>/control` |
//! | answers and notes | put in, subscriber out | `<role>/reply`, `<role>/note` |
//! | is alive, watches the orchestrator | token in, token out, liveliness subscribers both ways | `<role>/alive`, `orchestrator/alive` |
//!
//! and the orchestrator's queryables are declared to it on the three handshake keys. A
//! certificate of a role the run does not have on another host matches no subject: nothing it
//! sends is taken and nothing is sent to it. A participant admits the orchestrator's
//! certificate only, so another role's holder cannot pose as the run.

use serde_json::{json, Value};

use cosim::Role;

use crate::credentials::{Holder, ORCHESTRATOR};
use crate::keys;

/// Every message kind of Zenoh 1.10's access control.
const ALL_MESSAGES: [&str; 9] = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
];

fn rule(id: String, flow: &str, messages: &[&str], key_exprs: Vec<String>) -> Value {
    json!({
        "id": id,
        "messages": messages,
        "flows": [flow],
        "permission": "allow",
        "key_exprs": key_exprs,
    })
}

/// The rules of one remote role, each named `<role>-<what>`.
fn role_rules(run: &str, r: Role) -> Vec<Value> {
    let n = r.name();
    let handshake = vec![
        keys::ANY_OFFER.to_string(),
        keys::clock(run),
        keys::join(run, r),
    ];
    vec![
        rule(format!("{n}-ask"), "ingress", &["query"], handshake.clone()),
        rule(format!("{n}-answer"), "egress", &["reply"], handshake),
        rule(
            format!("{n}-offered"),
            "egress",
            &["declare_queryable"],
            vec![keys::offer(run), keys::clock(run), keys::join_any(run)],
        ),
        rule(
            format!("{n}-takes"),
            "ingress",
            &["declare_subscriber"],
            vec![keys::request(run, r), keys::control(run, r)],
        ),
        rule(
            format!("{n}-given"),
            "egress",
            &["put"],
            vec![keys::request(run, r), keys::control(run, r)],
        ),
        rule(
            format!("{n}-says"),
            "ingress",
            &["put"],
            vec![keys::reply(run, r), keys::note(run, r)],
        ),
        rule(
            format!("{n}-heard"),
            "egress",
            &["declare_subscriber"],
            vec![keys::reply(run, r), keys::note(run, r)],
        ),
        rule(
            format!("{n}-alive"),
            "ingress",
            &["liveliness_token"],
            vec![keys::alive(run, r)],
        ),
        rule(
            format!("{n}-sees-orchestrator"),
            "egress",
            &["liveliness_token"],
            vec![keys::orchestrator_alive(run)],
        ),
        rule(
            format!("{n}-watches"),
            "ingress",
            &["declare_liveliness_subscriber", "liveliness_query"],
            vec![keys::orchestrator_alive(run)],
        ),
        rule(
            format!("{n}-watched"),
            "egress",
            &["declare_liveliness_subscriber", "liveliness_query"],
            vec![keys::alive(run, r)],
        ),
    ]
}

/// The orchestrator's access control for run `run` with `remote` roles on other hosts, whose
/// certificates name the authority `authority_id`.
pub fn orchestrator(run: &str, remote: &[Role], authority_id: &str) -> Value {
    let mut rules = Vec::new();
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for &r in remote {
        let these = role_rules(run, r);
        let ids: Vec<Value> = these.iter().map(|x| x["id"].clone()).collect();
        rules.extend(these);
        let cn = Holder::Role(r).common_name(authority_id);
        subjects.push(json!({ "id": r.name(), "cert_common_names": [cn] }));
        policies.push(json!({ "id": r.name(), "rules": ids, "subjects": [r.name()] }));
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// The access control of `tiltsim bench --network`'s floor: the echo, holding the plant's
/// certificate, may take the pings and send the pongs, and show it is there.
pub fn bench(ping: &str, pong: &str, token: &str, authority_id: &str) -> Value {
    let n = Role::Plant.name();
    let cn = Holder::Role(Role::Plant).common_name(authority_id);
    let rules = vec![
        rule(
            "pings".into(),
            "ingress",
            &["declare_subscriber"],
            vec![ping.into()],
        ),
        rule("pinged".into(), "egress", &["put"], vec![ping.into()]),
        rule("pongs".into(), "ingress", &["put"], vec![pong.into()]),
        rule(
            "ponged".into(),
            "egress",
            &["declare_subscriber"],
            vec![pong.into()],
        ),
        rule(
            "present".into(),
            "ingress",
            &["liveliness_token"],
            vec![token.into()],
        ),
        rule(
            "looked-for".into(),
            "egress",
            &["liveliness_query"],
            vec![token.into()],
        ),
    ];
    let ids: Vec<Value> = rules.iter().map(|x| x["id"].clone()).collect();
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": [{ "id": n, "cert_common_names": [cn] }],
        "policies": [{ "id": n, "rules": ids, "subjects": [n] }],
    })
}

/// A participant's access control: everything of tiltsim's runs with the orchestrator of the
/// authority `authority_id`, nothing with anyone else.
pub fn participant(authority_id: &str) -> Value {
    let cn = Holder::Orchestrator.common_name(authority_id);
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [{
            "id": "run",
            "messages": ALL_MESSAGES,
            "flows": ["ingress", "egress"],
            "permission": "allow",
            "key_exprs": ["tiltsim/run/**"],
        }],
        "subjects": [{ "id": ORCHESTRATOR, "cert_common_names": [cn] }],
        "policies": [{ "id": ORCHESTRATOR, "rules": ["run"], "subjects": [ORCHESTRATOR] }],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_role_is_admitted_to_its_own_keys_of_this_run_only() {
        let acl = orchestrator("r1", &[Role::Controller], "0123456789abcdef");
        assert_eq!(acl["default_permission"], "deny");
        assert_eq!(acl["subjects"].as_array().unwrap().len(), 1);
        assert_eq!(
            acl["subjects"][0]["cert_common_names"][0],
            "controller.0123456789abcdef"
        );
        let keys: Vec<String> = acl["rules"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|r| r["key_exprs"].as_array().unwrap().clone())
            .map(|k| k.as_str().unwrap().to_string())
            .collect();
        for k in &keys {
            let of_run = k.starts_with("tiltsim/run/r1/");
            assert!(of_run || k == keys::ANY_OFFER, "{k}");
            // No key of another role, no wildcard over roles but the join queryable's.
            assert!(!k.contains("/actuator/") && !k.contains("/plant/"), "{k}");
            assert!(!k.ends_with("/**"), "{k}");
        }
        // Every rule is used by the role's policy.
        let ids = acl["policies"][0]["rules"].as_array().unwrap().len();
        assert_eq!(ids, acl["rules"].as_array().unwrap().len());
    }
}
