//! Bluetooth: the adapter, the `BlueZ` daemon, the `rfcomm` tool, paired SPP devices and their bindings.

use std::path::Path;

use super::{Area, Environment, Finding, SPP_UUID, Verdict};

/// Bluetooth: an adapter, the `BlueZ` daemon, the `rfcomm` tool, paired SPP devices and bindings.
pub fn bluetooth_findings(env: &Environment) -> Vec<Finding> {
    let finding =
        |check: &str, verdict, detail: String| Finding::new(Area::Bluetooth, check, verdict, detail);
    let mut out = Vec::new();
    let adapters: Vec<String> = env
        .list("/sys/class/bluetooth")
        .unwrap_or_default()
        .into_iter()
        .filter(|n| n.starts_with("hci") && !n.contains(':'))
        .collect();
    out.push(if adapters.is_empty() {
        finding("adapter", Verdict::Warning, "no Bluetooth adapter found (/sys/class/bluetooth)".into())
            .fix("plug in a Bluetooth dongle or enable Bluetooth in the firmware settings; a USB GPS or vest needs none")
    } else {
        finding("adapter", Verdict::Ok, format!("adapter {}", adapters.join(", ")))
    });
    let running = env.process_running("bluetoothd");
    out.push(if running {
        finding("bluetoothd", Verdict::Ok, "the BlueZ service runs".into())
    } else {
        finding("bluetoothd", Verdict::Warning, "the BlueZ service (bluetoothd) is not running".into())
            .fix("sudo apt install bluez && sudo systemctl enable --now bluetooth")
    });
    out.push(match env.which("rfcomm") {
        Some(p) => finding("rfcomm", Verdict::Ok, format!("{} present", p.display())),
        None => finding(
            "rfcomm",
            Verdict::Warning,
            "the rfcomm tool is missing: Bluetooth serial ports cannot be bound".into(),
        )
        .fix("sudo apt install bluez (Debian ships rfcomm in it; some releases in bluez-deprecated)"),
    });
    out.push(paired_finding(env));
    let bound: Vec<String> =
        env.list("/dev").unwrap_or_default().into_iter().filter(|n| n.starts_with("rfcomm")).collect();
    out.push(if bound.is_empty() {
        finding("bound ports", Verdict::Info, "no Bluetooth serial port bound (/dev/rfcomm*)".into())
            .fix("sudo rfcomm bind 0 <MAC> 1 for each paired GPS or vest (docs/hardware.md)")
    } else {
        finding("bound ports", Verdict::Ok, format!("bound: /dev/{}", bound.join(", /dev/")))
    });
    out
}

/// Paired devices offering the Serial Port Profile, from `BlueZ`'s store (`/var/lib/bluetooth/ADAPTER/DEVICE/
/// info`, readable by root only).
pub(super) fn paired_finding(env: &Environment) -> Finding {
    let finding =
        |verdict, detail: String| Finding::new(Area::Bluetooth, "paired SPP devices", verdict, detail);
    let store = Path::new("/var/lib/bluetooth");
    let adapters = match env.list(store) {
        Ok(a) => a,
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => {
            return finding(Verdict::Info, "BlueZ's pairing store is readable by root only".into())
                .fix("list them with: bluetoothctl devices Paired");
        }
        Err(_) => {
            return finding(Verdict::Info, "no pairing store (/var/lib/bluetooth): nothing paired".into())
                .fix("pair the GPS and the vest: bluetoothctl, then `pair <MAC>` and `trust <MAC>` (docs/hardware.md)");
        }
    };
    let mut spp = Vec::new();
    let mut others = 0;
    for adapter in adapters.iter().filter(|a| a.contains(':')) {
        for device in env.list(store.join(adapter)).unwrap_or_default().iter().filter(|d| d.contains(':')) {
            let Ok(info) = env.read_small(store.join(adapter).join(device).join("info")) else { continue };
            let name = info.lines().find_map(|l| l.strip_prefix("Name=")).unwrap_or("").trim();
            let services = info.lines().find_map(|l| l.strip_prefix("Services=")).unwrap_or("");
            if services.to_ascii_lowercase().contains(SPP_UUID) {
                spp.push(if name.is_empty() { device.clone() } else { format!("{name} ({device})") });
            } else {
                others += 1;
            }
        }
    }
    if spp.is_empty() {
        finding(Verdict::Info, format!("no paired device offers a serial port ({others} other paired)")).fix(
            "pair the GPS and the vest: bluetoothctl, then `pair <MAC>` and `trust <MAC>` (docs/hardware.md)",
        )
    } else {
        finding(Verdict::Ok, spp.join(", "))
    }
}
