//! How a station or a console reaches the broker: the URL (`mqtts://HOST:PORT` by default; plaintext
//! `mqtt://` only to the loopback address with an explicit flag), the credentials (always from files, which
//! must not be readable by the group or others), and the TLS client configuration on the tree's rustls with
//! its aws-lc-rs provider.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use rumqttc::{MqttOptions, TlsConfiguration, Transport};
use rustls::pki_types::pem::PemObject as _;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};

/// Largest credential or certificate file read [bytes].
const MAX_CREDENTIAL_FILE: u64 = 1 << 20;
/// The MQTT keep-alive: a broker that heard nothing for 1.5 times this publishes the client's last will.
pub const KEEP_ALIVE: Duration = Duration::from_secs(5);

/// Why a broker configuration cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The URL is not `mqtts://HOST[:PORT]` or `mqtt://127.0.0.1[:PORT]`.
    #[error("broker URL {url:?}: {why}")]
    Url {
        /// The URL as given.
        url: String,
        /// What is wrong.
        why: String,
    },
    /// Plaintext was asked for without the flag, or to a host other than the loopback address.
    #[error(
        "broker URL {0:?}: plaintext MQTT only to 127.0.0.1 or ::1 and with --insecure-plaintext-loopback; use mqtts://"
    )]
    Plaintext(String),
    /// A credential file is readable by the group or others.
    #[error("{path}: readable by group or others (mode {mode:o}); run `chmod 600 {path}`")]
    Permissions {
        /// The file.
        path: String,
        /// Its permission bits.
        mode: u32,
    },
    /// A file cannot be read or parsed.
    #[error("{path}: {why}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        why: String,
    },
    /// A user without a password file, a certificate without a key, or the like.
    #[error("{0}")]
    Incomplete(String),
    /// rustls refused the configuration.
    #[error("TLS: {0}")]
    Tls(String),
}

/// Where the broker is and how to prove who we are. It serialises (the console keeps it in its settings
/// file): only file names, never a secret.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct BrokerConfig {
    /// `mqtts://HOST:PORT` (port 8883 by default) or, with [`Self::insecure_plaintext_loopback`],
    /// `mqtt://127.0.0.1:PORT` (1883).
    pub url: String,
    /// The CA certificate(s) that signed the broker's certificate (PEM); `None`: the system's CAs.
    pub ca: Option<PathBuf>,
    /// The MQTT user name.
    pub user: Option<String>,
    /// The file holding the password (its first line), mode 600 or stricter.
    pub password_file: Option<PathBuf>,
    /// A client certificate (PEM) for TLS client authentication.
    pub cert: Option<PathBuf>,
    /// Its private key (PEM), mode 600 or stricter.
    pub key: Option<PathBuf>,
    /// Allows `mqtt://` to the loopback address (tests, a broker on the same machine).
    pub insecure_plaintext_loopback: bool,
}

/// A parsed broker URL.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrokerUrl {
    /// TLS or plaintext.
    pub tls: bool,
    /// Host name or address.
    pub host: String,
    /// Port.
    pub port: u16,
}

impl BrokerUrl {
    /// Parses `mqtts://HOST[:PORT]` or `mqtt://HOST[:PORT]` (an IPv6 address in brackets).
    pub fn parse(url: &str) -> Result<Self, ConfigError> {
        let bad = |why: &str| ConfigError::Url { url: url.to_owned(), why: why.to_owned() };
        let (tls, rest) = if let Some(r) = url.strip_prefix("mqtts://") {
            (true, r)
        } else if let Some(r) = url.strip_prefix("mqtt://") {
            (false, r)
        } else {
            return Err(bad("must start with mqtts:// (or mqtt:// to the loopback address)"));
        };
        let rest = rest.trim_end_matches('/');
        let default_port = if tls { 8883 } else { 1883 };
        let (host, port) = if let Some(r) = rest.strip_prefix('[') {
            let (h, after) = r.split_once(']').ok_or_else(|| bad("unclosed '[' in an IPv6 address"))?;
            let port = match after.strip_prefix(':') {
                Some(p) => p.parse().map_err(|_| bad("the port is not a number 1-65535"))?,
                None if after.is_empty() => default_port,
                None => return Err(bad("unexpected text after the address")),
            };
            (h.to_owned(), port)
        } else {
            match rest.rsplit_once(':') {
                Some((h, p)) => {
                    (h.to_owned(), p.parse().map_err(|_| bad("the port is not a number 1-65535"))?)
                }
                None => (rest.to_owned(), default_port),
            }
        };
        if host.is_empty() || host.contains(['/', '@', ' ']) {
            return Err(bad("no host, or a path or user in it"));
        }
        if port == 0 {
            return Err(bad("port 0"));
        }
        Ok(Self { tls, host, port })
    }

    /// Whether the host is the loopback address.
    pub fn is_loopback(&self) -> bool {
        self.host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
    }
}

impl BrokerConfig {
    /// The client options for `client_id`, checked: the URL, plaintext only to loopback with the flag, the
    /// files' permissions, the certificates parsed. `will` is the last will, if any.
    pub fn mqtt_options(
        &self,
        client_id: &str,
        will: Option<rumqttc::LastWill>,
    ) -> Result<MqttOptions, ConfigError> {
        let url = BrokerUrl::parse(&self.url)?;
        let plaintext_allowed = self.insecure_plaintext_loopback && url.is_loopback();
        if !url.tls && !plaintext_allowed {
            return Err(ConfigError::Plaintext(self.url.clone()));
        }
        let mut o = MqttOptions::new(client_id, url.host.clone(), url.port);
        o.set_keep_alive(KEEP_ALIVE);
        o.set_clean_session(true);
        o.set_max_packet_size(crate::wire::MAX_PACKET, crate::wire::MAX_PACKET);
        if let Some(w) = will {
            o.set_last_will(w);
        }
        match (&self.user, &self.password_file) {
            (Some(u), Some(f)) => {
                let password = read_password(f)?;
                o.set_credentials(u.clone(), password);
            }
            (Some(_), None) => return Err(ConfigError::Incomplete("--user needs --password-file".into())),
            (None, Some(_)) => return Err(ConfigError::Incomplete("--password-file needs --user".into())),
            (None, None) => {}
        }
        if url.tls {
            o.set_transport(Transport::tls_with_config(TlsConfiguration::Rustls(Arc::new(
                self.tls_config()?,
            ))));
        } else if self.cert.is_some() {
            return Err(ConfigError::Incomplete("a client certificate needs mqtts://".into()));
        }
        Ok(o)
    }

    /// The TLS client configuration: the CA (or the system's), the client certificate if any.
    fn tls_config(&self) -> Result<rustls::ClientConfig, ConfigError> {
        let mut roots = rustls::RootCertStore::empty();
        if let Some(ca) = &self.ca {
            let bytes = read_file(ca)?;
            let mut n = 0;
            for c in CertificateDer::pem_slice_iter(&bytes) {
                let c = c.map_err(|e| file_error(ca, &format!("not a PEM certificate: {e}")))?;
                roots.add(c).map_err(|e| file_error(ca, &format!("unusable CA certificate: {e}")))?;
                n += 1;
            }
            if n == 0 {
                return Err(file_error(ca, "no certificate in it"));
            }
        } else {
            let found = rustls_native_certs::load_native_certs();
            for c in found.certs {
                let _ = roots.add(c);
            }
            if roots.is_empty() {
                return Err(ConfigError::Incomplete("no system CA certificates found: give --ca".into()));
            }
        }
        let provider = Arc::new(rustls::crypto::aws_lc_rs::default_provider());
        let builder = rustls::ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(|e| ConfigError::Tls(e.to_string()))?
            .with_root_certificates(roots);
        match (&self.cert, &self.key) {
            (Some(cert), Some(key)) => {
                let bytes = read_file(cert)?;
                let chain = CertificateDer::pem_slice_iter(&bytes)
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| file_error(cert, &format!("not a PEM certificate: {e}")))?;
                if chain.is_empty() {
                    return Err(file_error(cert, "no certificate in it"));
                }
                check_private(key)?;
                let key_bytes = read_file(key)?;
                let key_der = PrivateKeyDer::from_pem_slice(&key_bytes)
                    .map_err(|e| file_error(key, &format!("not a PEM private key: {e}")))?;
                builder.with_client_auth_cert(chain, key_der).map_err(|e| ConfigError::Tls(e.to_string()))
            }
            (None, None) => Ok(builder.with_no_client_auth()),
            _ => Err(ConfigError::Incomplete("--cert and --key go together".into())),
        }
    }
}

/// Waits at most `within` for a connection thread to end (a shutdown never blocks on the network);
/// true when it has.
pub(crate) fn wait_for_end(thread: &std::thread::JoinHandle<()>, within: Duration) -> bool {
    let deadline = std::time::Instant::now() + within;
    while !thread.is_finished() && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    thread.is_finished()
}

fn file_error(path: &Path, why: &str) -> ConfigError {
    ConfigError::File { path: path.display().to_string(), why: why.to_owned() }
}

fn read_file(path: &Path) -> Result<Vec<u8>, ConfigError> {
    vestnav_files::read_limited(path, MAX_CREDENTIAL_FILE).map_err(|e| file_error(path, &e.to_string()))
}

/// Refuses a secret (password or key file) that the group or others may read.
pub fn check_private(path: &Path) -> Result<(), ConfigError> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let meta = std::fs::metadata(path).map_err(|e| file_error(path, &e.to_string()))?;
        let mode = meta.permissions().mode() & 0o777;
        if mode & 0o077 != 0 {
            return Err(ConfigError::Permissions { path: path.display().to_string(), mode });
        }
    }
    Ok(())
}

/// The password: the file's first line (private file, at most 1 MiB, UTF-8).
fn read_password(path: &Path) -> Result<String, ConfigError> {
    check_private(path)?;
    let bytes = read_file(path)?;
    let text = String::from_utf8(bytes).map_err(|_| file_error(path, "not UTF-8 text"))?;
    let line = text.lines().next().unwrap_or("").trim_end_matches('\r');
    if line.is_empty() {
        return Err(file_error(path, "empty: the password is its first line"));
    }
    Ok(line.to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        let u = BrokerUrl::parse("mqtts://broker.example:8884").unwrap();
        assert_eq!((u.tls, u.host.as_str(), u.port), (true, "broker.example", 8884));
        assert_eq!(BrokerUrl::parse("mqtts://h").unwrap().port, 8883);
        let v6 = BrokerUrl::parse("mqtt://[::1]:1999").unwrap();
        assert_eq!((v6.host.as_str(), v6.port), ("::1", 1999));
        assert!(v6.is_loopback());
        for bad in ["http://h", "mqtts://", "mqtts://h:0", "mqtts://h:99999", "mqtts://u@h", "mqtts://[::1"] {
            assert!(BrokerUrl::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn plaintext_only_to_loopback_with_the_flag() {
        let mut c = BrokerConfig { url: "mqtt://127.0.0.1:1883".into(), ..BrokerConfig::default() };
        assert!(matches!(c.mqtt_options("x", None), Err(ConfigError::Plaintext(_))));
        c.insecure_plaintext_loopback = true;
        assert!(c.mqtt_options("x", None).is_ok());
        c.url = "mqtt://10.0.0.5:1883".into();
        assert!(matches!(c.mqtt_options("x", None), Err(ConfigError::Plaintext(_))));
    }

    #[cfg(unix)]
    #[test]
    fn a_password_file_others_can_read_is_refused() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = std::env::temp_dir().join(format!("vestnav-remote-perm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("password");
        std::fs::write(&f, "secret\n").unwrap();
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o640)).unwrap();
        let c = BrokerConfig {
            url: "mqtt://127.0.0.1:1883".into(),
            user: Some("op".into()),
            password_file: Some(f.clone()),
            insecure_plaintext_loopback: true,
            ..BrokerConfig::default()
        };
        let e = c.mqtt_options("x", None).unwrap_err().to_string();
        assert!(e.contains("readable by group or others") && e.contains("chmod 600"), "{e}");
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o600)).unwrap();
        let o = c.mqtt_options("x", None).unwrap();
        assert_eq!(o.credentials().map(|l| l.password), Some("secret".to_owned()));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
