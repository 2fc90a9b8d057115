//! The run's credentials for Zenoh's mutual TLS.
//!
//! Both ends derive one certificate authority from the run's secret: its Ed25519 key is the
//! HKDF-SHA256 (RFC 5869) expansion of the secret, so whoever holds the secret can sign
//! certificates the other end trusts and nobody else can. Each process then makes a key pair
//! of its own, drawn from the system's random source, and a certificate for it signed by that
//! authority, whose common name says who it is and under which authority:
//! `orchestrator.<id>`, `plant.<id>`, `actuator.<id>` or `controller.<id>`, where `<id>` is
//! the first 16 hex digits of the SHA-256 of the authority's public key ([`authority_id`]).
//! Access control matches the whole name, so a certificate from any other authority a TLS
//! library may also trust never passes for one of the run's. Zenoh's TLS link checks the chain at both ends before a session exists, and
//! its access control admits each common name to that role's key expressions only
//! ([`crate::acl`]).
//!
//! The cryptography is rustls's and ring's (through Zenoh and rcgen); this module only
//! derives the authority's key and asks rcgen for the certificates.

use hkdf::Hkdf;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose, PKCS_ED25519,
};
use sha2::Sha256;

use cosim::Role;

/// The common name of the orchestrator's certificate.
pub const ORCHESTRATOR: &str = "orchestrator";

/// The common name of the run's certificate authority.
const AUTHORITY: &str = "tiltsim run authority";

/// Who a certificate is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Holder {
    /// The run's orchestrator.
    Orchestrator,
    /// A participant.
    Role(Role),
}

impl Holder {
    /// Who it is, the first part of its certificate's common name.
    pub fn name(self) -> &'static str {
        match self {
            Holder::Orchestrator => ORCHESTRATOR,
            Holder::Role(r) => r.name(),
        }
    }

    /// The certificate's common name under the authority `authority_id`, which Zenoh's access
    /// control matches.
    pub fn common_name(self, authority_id: &str) -> String {
        format!("{}.{authority_id}", self.name())
    }

    /// The holder a common name names under the authority `authority_id`, if it is one.
    pub fn of_common_name(common_name: &str, authority_id: &str) -> Option<Holder> {
        let (name, id) = common_name.split_once('.')?;
        if id != authority_id {
            return None;
        }
        match name {
            ORCHESTRATOR => Some(Holder::Orchestrator),
            role => Role::parse(role).map(Holder::Role),
        }
    }
}

/// One process's TLS material, as PEM text.
#[derive(Clone)]
pub struct Credentials {
    /// Who holds it.
    pub holder: Holder,
    /// The run's certificate authority: the only root either end trusts.
    pub authority_pem: String,
    /// The holder's certificate, signed by the authority.
    pub certificate_pem: String,
    /// The holder's private key.
    pub key_pem: String,
    /// [`authority_id`] of the run's authority.
    pub authority_id: String,
}

impl std::fmt::Debug for Credentials {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Credentials")
            .field("holder", &self.holder)
            .field("key_pem", &"<hidden>")
            .finish_non_exhaustive()
    }
}

/// A failure to make credentials (rcgen's message).
#[derive(Debug, thiserror::Error)]
#[error("making the run's TLS credentials: {0}")]
pub struct CredentialError(String);

fn rcgen_error(e: rcgen::Error) -> CredentialError {
    CredentialError(e.to_string())
}

/// The DER PrivateKeyInfo of an Ed25519 key (RFC 8410, section 7): a version 0, the algorithm
/// identifier id-Ed25519 (1.3.101.112) and the 32-byte seed as an OCTET STRING inside the
/// OCTET STRING of the private key; everything before the seed is fixed.
fn ed25519_pkcs8(seed: &[u8; 32]) -> Vec<u8> {
    const BEFORE_SEED: [u8; 16] = [
        0x30, 0x2e, 0x02, 0x01, 0x00, 0x30, 0x05, 0x06, 0x03, 0x2b, 0x65, 0x70, 0x04, 0x22, 0x04,
        0x20,
    ];
    let mut der = BEFORE_SEED.to_vec();
    der.extend_from_slice(seed);
    der
}

/// The authority's key: HKDF-SHA256 of the secret, salt and info naming what it is for.
fn authority_key(secret: &str) -> Result<KeyPair, CredentialError> {
    let hk = Hkdf::<Sha256>::new(Some(b"tiltsim-run-authority-v1"), secret.as_bytes());
    let mut seed = [0u8; 32];
    hk.expand(b"ed25519 seed", &mut seed)
        .map_err(|e| CredentialError(e.to_string()))?;
    let der = ed25519_pkcs8(&seed);
    KeyPair::from_pkcs8_der_and_sign_algo(&der.as_slice().into(), &PKCS_ED25519)
        .map_err(rcgen_error)
}

fn authority_params() -> CertificateParams {
    let mut p = CertificateParams::default();
    p.distinguished_name.push(DnType::CommonName, AUTHORITY);
    p.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    p.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    p
}

/// The first 16 hex digits of the SHA-256 of the public key of the authority derived from
/// `secret`: the run's authority, named in every common name.
pub fn authority_id(secret: &str) -> Result<String, CredentialError> {
    use sha2::Digest;
    let key = authority_key(secret)?;
    let d = Sha256::digest(rcgen::PublicKeyData::der_bytes(&key));
    Ok(d.iter().take(8).map(|b| format!("{b:02x}")).collect())
}

/// The credentials of `holder` in the run whose secret is `secret`: the authority derived from
/// the secret, and a fresh key pair with its certificate.
pub fn issue(secret: &str, holder: Holder) -> Result<Credentials, CredentialError> {
    let authority_id = authority_id(secret)?;
    let authority_key = authority_key(secret)?;
    let authority = authority_params()
        .self_signed(&authority_key)
        .map_err(rcgen_error)?;
    let issuer = Issuer::new(authority_params(), authority_key);
    let key = KeyPair::generate_for(&PKCS_ED25519).map_err(rcgen_error)?;
    let name = holder.common_name(&authority_id);
    let mut p = CertificateParams::new(vec![name.clone()]).map_err(rcgen_error)?;
    p.distinguished_name.push(DnType::CommonName, name);
    p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
    p.extended_key_usages = vec![
        ExtendedKeyUsagePurpose::ServerAuth,
        ExtendedKeyUsagePurpose::ClientAuth,
    ];
    let certificate = p.signed_by(&key, &issuer).map_err(rcgen_error)?;
    Ok(Credentials {
        holder,
        authority_pem: authority.pem(),
        certificate_pem: certificate.pem(),
        key_pem: key.serialize_pem(),
        authority_id,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_authority_is_a_function_of_the_secret_and_the_holders_keys_are_not() {
        let a = issue("s3cret", Holder::Orchestrator).unwrap();
        let b = issue("s3cret", Holder::Role(Role::Controller)).unwrap();
        let c = issue("other", Holder::Role(Role::Controller)).unwrap();
        // Ed25519 signatures are deterministic (RFC 8032): the same key and the same fields
        // give the same self-signed authority, at both ends of a run.
        assert_eq!(a.authority_pem, b.authority_pem);
        assert_ne!(a.authority_pem, c.authority_pem);
        assert_ne!(b.key_pem, c.key_pem);
        assert_ne!(
            b.key_pem,
            issue("s3cret", Holder::Role(Role::Controller))
                .unwrap()
                .key_pem
        );
    }

    #[test]
    fn a_common_name_names_its_holder_under_one_authority_only() {
        let id = authority_id("s3cret").unwrap();
        assert_eq!(id.len(), 16);
        assert_ne!(id, authority_id("other").unwrap());
        let c = Holder::Role(Role::Controller).common_name(&id);
        assert_eq!(
            Holder::of_common_name(&c, &id),
            Some(Holder::Role(Role::Controller))
        );
        assert_eq!(Holder::of_common_name(&c, "0123456789abcdef"), None);
        assert_eq!(Holder::of_common_name("controller", &id), None);
        assert_eq!(
            Holder::of_common_name(&format!("orchestrator.{id}"), &id),
            Some(Holder::Orchestrator)
        );
    }

    #[test]
    fn the_pkcs8_wrapper_is_the_one_of_rfc_8410() {
        // RFC 8410 section 10.3's example private key: 16 fixed bytes, then the 32-byte seed.
        use base64::Engine;
        let pem_body = "MC4CAQAwBQYDK2VwBCIEINTuctv5E1hK1bbY8fdp+K06/nwoy/HU++CXqI9EdVhC";
        let der = base64::engine::general_purpose::STANDARD
            .decode(pem_body)
            .unwrap();
        assert_eq!(der.len(), 48);
        let seed: [u8; 32] = der[16..].try_into().unwrap();
        assert_eq!(ed25519_pkcs8(&seed), der);
    }
}
