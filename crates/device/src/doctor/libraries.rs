//! Libraries and optional parts: the display session and the window libraries opened at run time, and
//! gpsd, liblsl and the broker.

use std::net::{TcpStream, ToSocketAddrs as _};
use std::time::Duration;

use super::{Area, BROKER_TIMEOUT, Environment, Finding, Verdict};

/// A library the console loads at run time, and the Debian package that has it.
pub(super) struct Lib {
    soname: &'static str,
    package: &'static str,
}

pub(super) const GL_LIBS: [Lib; 2] =
    [Lib { soname: "libEGL.so.1", package: "libegl1" }, Lib { soname: "libGL.so.1", package: "libgl1" }];
pub(super) const COMMON_LIBS: [Lib; 1] = [Lib { soname: "libxkbcommon.so.0", package: "libxkbcommon0" }];
pub(super) const X11_LIBS: [Lib; 6] = [
    Lib { soname: "libX11.so.6", package: "libx11-6" },
    Lib { soname: "libX11-xcb.so.1", package: "libx11-xcb1" },
    Lib { soname: "libXcursor.so.1", package: "libxcursor1" },
    Lib { soname: "libXi.so.6", package: "libxi6" },
    Lib { soname: "libXrandr.so.2", package: "libxrandr2" },
    Lib { soname: "libxkbcommon-x11.so.0", package: "libxkbcommon-x11-0" },
];
pub(super) const WAYLAND_LIBS: [Lib; 3] = [
    Lib { soname: "libwayland-client.so.0", package: "libwayland-client0" },
    Lib { soname: "libwayland-cursor.so.0", package: "libwayland-cursor0" },
    Lib { soname: "libwayland-egl.so.1", package: "libwayland-egl1" },
];

/// The Debian packages of every library the console's window opens at run time (the packaging script
/// makes them dependencies).
pub fn window_packages() -> Vec<&'static str> {
    GL_LIBS.iter().chain(&COMMON_LIBS).chain(&X11_LIBS).chain(&WAYLAND_LIBS).map(|l| l.package).collect()
}

/// The display session and the libraries the console's window needs (they are opened at run time, so a
/// missing one would only show when the window opens).
pub fn display_findings(env: &Environment) -> Vec<Finding> {
    let finding = |check: &str, verdict, detail: String| Finding::new(Area::Display, check, verdict, detail);
    let wayland = env.var("WAYLAND_DISPLAY").is_some();
    let x11 = env.var("DISPLAY").is_some();
    let mut out = vec![match (wayland, x11) {
        (true, _) => finding("session", Verdict::Ok, "a Wayland session (WAYLAND_DISPLAY)".into()),
        (false, true) => finding("session", Verdict::Ok, "an X11 session (DISPLAY)".into()),
        (false, false) => finding(
            "session",
            Verdict::Warning,
            "no display (neither DISPLAY nor WAYLAND_DISPLAY): the console window cannot open here; the subcommands work".into(),
        )
        .fix("run it from the desktop (its application menu), or over ssh -X"),
    }];
    let dirs = env.library_dirs();
    let find = |soname: &str| dirs.iter().map(|d| d.join(soname)).find(|p| env.at(p).exists());
    // Each library: a problem if the session in use needs it, a warning if only the other kind would.
    let mut check = |libs: &[Lib], needed: bool| {
        for lib in libs {
            out.push(match find(lib.soname) {
                Some(p) => finding(lib.soname, Verdict::Ok, format!("{}", p.display())),
                None => finding(
                    lib.soname,
                    if needed { Verdict::Problem } else { Verdict::Warning },
                    format!(
                        "{} is missing: the console window {}",
                        lib.soname,
                        if needed { "will not open" } else { "needs it in some sessions" }
                    ),
                )
                .fix(format!("sudo apt install {}", lib.package)),
            });
        }
    };
    check(&GL_LIBS, wayland || x11);
    check(&COMMON_LIBS, wayland || x11);
    check(&X11_LIBS, x11 && !wayland);
    check(&WAYLAND_LIBS, wayland);
    let driver = dirs
        .iter()
        .any(|d| env.list(d.join("dri")).is_ok_and(|names| names.iter().any(|n| n.ends_with("_dri.so"))));
    out.push(if driver {
        finding("OpenGL driver", Verdict::Ok, "Mesa's drivers are installed".into())
    } else {
        finding(
            "OpenGL driver",
            Verdict::Warning,
            "no Mesa driver (dri/*_dri.so): without a vendor driver OpenGL will not start".into(),
        )
        .fix("sudo apt install libgl1-mesa-dri")
    });
    out
}

/// gpsd, liblsl and the broker: only needed for some set-ups, so never a problem unless configured.
pub fn optional_findings(env: &Environment, broker: Option<&str>) -> Vec<Finding> {
    let finding = |check: &str, verdict, detail: String| Finding::new(Area::Optional, check, verdict, detail);
    let mut out = vec![match env.which("gpsd") {
        Some(p) => finding("gpsd", Verdict::Ok, format!("{} present", p.display())),
        None => finding(
            "gpsd",
            Verdict::Info,
            "gpsd is not installed (needed only for a gpsd:// GPS source)".into(),
        )
        .fix("sudo apt install gpsd"),
    }];
    // The one search `--lsl` and the console's lab outputs use (vestnav-lsl), loading the library as they
    // would: a file found but unusable is said with its reason.
    out.push(match vestnav_lsl::Lsl::load() {
        Ok(lsl) => finding("liblsl", Verdict::Ok, format!("{} (liblsl {})", lsl.path(), lsl.version_text())),
        Err(missing) => {
            let why = missing.tried.iter().map(|(what, why)| format!("{what}: {why}")).collect::<Vec<_>>();
            finding(
                "liblsl",
                Verdict::Info,
                format!("liblsl not found (needed only for Lab Streaming Layer); tried {}", why.join("; ")),
            )
            .fix(vestnav_lsl::INSTALL_HINT)
        }
    });
    out.push(match broker {
        None => finding("broker", Verdict::Info, "none configured".into()),
        Some(url) => match reach_broker(url, BROKER_TIMEOUT) {
            Ok(addr) => finding("broker", Verdict::Ok, format!("{url} answers ({addr})")),
            Err(e) => finding("broker", Verdict::Problem, format!("{url}: {e}"))
                .fix("start the broker, or check the host, port and firewall"),
        },
    });
    out
}

/// Connects to the broker's host and port (`mqtt://host:1883`, `tcp://host:port`, `host:port`; the MQTT
/// default ports when none is given) within `timeout` per address; the address that answered.
pub fn reach_broker(url: &str, timeout: Duration) -> Result<std::net::SocketAddr, String> {
    let (scheme, rest) = url.split_once("://").unwrap_or(("", url));
    let authority = rest.split(['/', '?', '#']).next().unwrap_or("");
    let authority = authority.rsplit_once('@').map_or(authority, |(_, host)| host);
    let default_port = match scheme {
        "mqtts" | "ssl" => 8883,
        _ => 1883,
    };
    let has_port = authority.rsplit_once(':').is_some_and(|(_, p)| p.bytes().all(|b| b.is_ascii_digit()))
        && !authority.ends_with(']');
    let target = if has_port { authority.to_owned() } else { format!("{authority}:{default_port}") };
    if authority.is_empty() {
        return Err("no host in the URL".into());
    }
    let addrs: Vec<_> =
        target.to_socket_addrs().map_err(|e| format!("cannot resolve {target}: {e}"))?.collect();
    let mut last = format!("{target} resolves to no address");
    for addr in addrs.into_iter().take(4) {
        match TcpStream::connect_timeout(&addr, timeout) {
            Ok(_) => return Ok(addr),
            Err(e) => last = format!("cannot connect to {addr}: {e}"),
        }
    }
    Err(last)
}
