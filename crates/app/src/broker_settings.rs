//! The Broker window: the MQTT broker of the Stations window in the console's saved settings (URL, CA
//! file, user, password file, client certificate and key — file names only, the secrets stay in their
//! files), connect and disconnect at run time, and the connection's state.
//!
//! Disconnecting drops the operator's link: every station driven from here stops its vest at its link
//! bound unless "continue if link drops" was armed for it (docs/remote.md).

use std::path::{Path, PathBuf};

use egui::{Color32, RichText};
use vestnav_remote::BrokerConfig;

use crate::config::Config;
use crate::file_dialog::{self as fd, Browse, DialogSpec, Mode};
use crate::remote_panel::RemotePanel;

const PEM: DialogSpec =
    DialogSpec { mode: Mode::Open, title: "Choose a PEM file", filter: ("PEM", &["pem", "crt", "key"]) };
const ANY: DialogSpec = DialogSpec { mode: Mode::Open, title: "Choose the password file", filter: ("", &[]) };

/// The Broker window's state.
#[derive(Debug, Default)]
pub struct BrokerWindow {
    /// Whether the window is open.
    pub open: bool,
    browse: [Browse; 4],
    /// Why the last connection attempt failed at once (a bad URL, a missing or readable-by-others file).
    error: Option<String>,
}

/// `cfg` with its relative file names taken in `base`, as the window's "Uses:" lines show them.
pub fn resolved(cfg: &BrokerConfig, base: &Path) -> BrokerConfig {
    let fix = |p: &Option<PathBuf>| {
        p.as_ref().map(|p| fd::resolve(&p.display().to_string(), base).unwrap_or_else(|| p.clone()))
    };
    BrokerConfig {
        url: cfg.url.trim().to_owned(),
        ca: fix(&cfg.ca),
        user: cfg.user.as_ref().map(|u| u.trim().to_owned()).filter(|u| !u.is_empty()),
        password_file: fix(&cfg.password_file),
        cert: fix(&cfg.cert),
        key: fix(&cfg.key),
        insecure_plaintext_loopback: cfg.insecure_plaintext_loopback,
    }
}

/// Connects the Stations window to the broker `cfg` names; the operator's name is its user ("operator"
/// without one).
pub fn connect(panel: &mut RemotePanel, cfg: &BrokerConfig, base: &Path) -> Result<(), String> {
    let c = resolved(cfg, base);
    if c.url.is_empty() {
        return Err("no broker URL".to_owned());
    }
    c.mqtt_options("vestnav-check", None).map_err(|e| e.to_string())?;
    let operator = c.user.clone().unwrap_or_else(|| "operator".to_owned());
    panel.set_broker(&c, &operator).map_err(|e| e.to_string())
}

fn path_row(
    ui: &mut egui::Ui,
    label: &str,
    path: &mut Option<PathBuf>,
    browse: &mut Browse,
    spec: DialogSpec,
    base: &Path,
) {
    ui.label(label);
    let mut text = path.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    fd::path_field(ui, &mut text, browse, spec, base, "file");
    *path = (!text.is_empty()).then(|| PathBuf::from(text));
}

impl BrokerWindow {
    /// Draws the window: edits `cfg.broker` (saved with the other settings) and connects `remote`.
    /// `new_panel` makes the Stations window when there is none yet (with the console's stop path).
    pub fn ui(
        &mut self,
        ctx: &egui::Context,
        cfg: &mut Config,
        remote: &mut Option<RemotePanel>,
        new_panel: impl Fn() -> RemotePanel,
    ) {
        let mut open = self.open;
        let base = cfg.recent.base();
        egui::Window::new("Broker").open(&mut open).default_width(460.0).show(ctx, |ui| {
            match remote.as_ref().and_then(|r| r.fleet()).map(vestnav_remote::Fleet::broker_status) {
                Some((true, _)) => {
                    ui.label(RichText::new("connected").color(Color32::from_rgb(60, 160, 60)));
                }
                Some((false, e)) => {
                    let why = e.unwrap_or_else(|| "connecting".into());
                    ui.label(RichText::new(format!("NOT connected: {why}")).color(ui.visuals().error_fg_color));
                }
                None => {
                    ui.label("not connected");
                }
            }
            let b = &mut cfg.broker;
            ui.label("Broker URL");
            ui.add(egui::TextEdit::singleline(&mut b.url).hint_text("mqtts://10.42.0.1:8883").desired_width(300.0));
            ui.checkbox(&mut b.insecure_plaintext_loopback, "allow plaintext mqtt:// to 127.0.0.1 (this machine only)");
            let [ca, pw, cert, key] = &mut self.browse;
            path_row(ui, "CA certificate (empty: the system's)", &mut b.ca, ca, PEM, &base);
            ui.label("User (also the operator's name)");
            let mut user = b.user.clone().unwrap_or_default();
            ui.add(egui::TextEdit::singleline(&mut user).hint_text("operator").desired_width(200.0));
            b.user = (!user.is_empty()).then_some(user);
            path_row(ui, "Password file (first line; mode 600)", &mut b.password_file, pw, ANY, &base);
            path_row(ui, "Client certificate (optional)", &mut b.cert, cert, PEM, &base);
            path_row(ui, "Client key (mode 600)", &mut b.key, key, PEM, &base);
            ui.checkbox(&mut cfg.broker_at_start, "Connect when the console starts");
            ui.horizontal(|ui| {
                let connected = remote.as_ref().is_some_and(|r| r.fleet().is_some());
                if ui.button(if connected { "Reconnect" } else { "Connect" }).clicked() {
                    // The old link goes first (in `set_broker`): one operator session at a time.
                    // A Stations window is made only for a connection that starts.
                    let result = if let Some(panel) = remote.as_mut() {
                        panel.leave_broker();
                        connect(panel, &cfg.broker, &base).map(|()| panel.open = true)
                    } else {
                        let mut panel = new_panel();
                        connect(&mut panel, &cfg.broker, &base).map(|()| *remote = Some(panel))
                    };
                    self.error = result.err();
                }
                if ui
                    .add_enabled(connected, egui::Button::new("Disconnect"))
                    .on_hover_text("Each station then stops its vest at its operator-link bound, unless 'continue if link drops' is armed for it")
                    .clicked()
                {
                    if let Some(r) = remote.as_mut() {
                        r.leave_broker();
                    }
                    self.error = None;
                }
            });
            if let Some(e) = &self.error {
                ui.label(RichText::new(format!("cannot connect: {e}")).color(ui.visuals().error_fg_color));
            }
        });
        self.open = open;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_saved_broker_holds_file_names_only_and_round_trips() {
        let b = BrokerConfig {
            url: "mqtts://10.42.0.1:8883".into(),
            ca: Some("/etc/vestnav/ca.crt".into()),
            user: Some("operator".into()),
            password_file: Some("/home/op/.vestnav/password".into()),
            ..BrokerConfig::default()
        };
        let cfg = Config { broker: b.clone(), broker_at_start: true, ..Config::default() };
        let text = serde_json::to_string(&cfg).unwrap();
        assert!(text.contains("\"password_file\":\"/home/op/.vestnav/password\""), "{text}");
        let back: Config = serde_json::from_str(&text).unwrap();
        assert_eq!(back.broker, b);
        assert!(back.broker_at_start);
        // An old file without the section reads as no broker.
        let old: Config = serde_json::from_str("{}").unwrap();
        assert!(old.broker.url.is_empty() && !old.broker_at_start);
    }

    #[test]
    fn no_url_or_a_plaintext_remote_broker_is_refused_before_any_connection() {
        let base = std::env::temp_dir();
        let mut panel = RemotePanel::new(vestnav_station::stop::StopPath::default(), None);
        assert!(connect(&mut panel, &BrokerConfig::default(), &base).is_err());
        let plain = BrokerConfig { url: "mqtt://10.0.0.1:1883".into(), ..BrokerConfig::default() };
        assert!(connect(&mut panel, &plain, &base).is_err());
        assert!(panel.fleet().is_none(), "nothing connected");
    }
}
