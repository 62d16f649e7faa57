//! The broker options shared by `vestnav station` and the console: where the MQTT broker is and the
//! credentials, always from files (see `vestnav_remote::broker`).

use std::path::PathBuf;

use vestnav_remote::BrokerConfig;

/// How to reach an MQTT broker.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BrokerArgs {
    /// The MQTT broker: `mqtts://HOST[:PORT]` (TLS, port 8883 by default); `mqtt://127.0.0.1:PORT` only with
    /// --insecure-plaintext-loopback.
    #[arg(long, value_name = "URL")]
    pub broker: Option<String>,
    /// CA certificate(s) of the broker (PEM); default: the system's.
    #[arg(long, value_name = "FILE", requires = "broker")]
    pub ca: Option<PathBuf>,
    /// MQTT user name (with --password-file).
    #[arg(long, value_name = "USER", requires = "password_file")]
    pub user: Option<String>,
    /// File holding the password on its first line (mode 600: refused if the group or others can read it).
    #[arg(long, value_name = "FILE", requires = "user")]
    pub password_file: Option<PathBuf>,
    /// Client certificate for TLS client authentication (PEM, with --key).
    #[arg(long, value_name = "FILE", requires = "key")]
    pub cert: Option<PathBuf>,
    /// Its private key (PEM; mode 600).
    #[arg(long, value_name = "FILE", requires = "cert")]
    pub key: Option<PathBuf>,
    /// Allow plaintext `mqtt://` to 127.0.0.1 or `::1` (a broker on this machine; tests).
    #[arg(long)]
    pub insecure_plaintext_loopback: bool,
}

impl BrokerArgs {
    /// The broker configuration, when --broker is given.
    pub fn config(&self) -> Option<BrokerConfig> {
        Some(BrokerConfig {
            url: self.broker.clone()?,
            ca: self.ca.clone(),
            user: self.user.clone(),
            password_file: self.password_file.clone(),
            cert: self.cert.clone(),
            key: self.key.clone(),
            insecure_plaintext_loopback: self.insecure_plaintext_loopback,
        })
    }
}
