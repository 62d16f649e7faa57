//! Serial ports: which USB and Bluetooth ports exist, and whether this user may open them.

use super::{
    Area, Environment, Finding, Group, Verdict, bluetooth_findings, owner_of, parse_groups, permits,
};

/// Whether a port name looks like one a GPS or a vest shows up as (`ttyS*` on-board UARTs always exist
/// and are left out unless named).
pub(super) fn is_candidate_port(name: &str) -> bool {
    ["ttyUSB", "ttyACM", "rfcomm"].iter().any(|p| name.strip_prefix(p).is_some_and(|n| !n.is_empty()))
}

/// The serial ports: every USB and Bluetooth port under `/dev` and each of `named`, whether it exists and
/// whether this user may open it.
pub fn serial_findings(env: &Environment, named: &[String]) -> Vec<Finding> {
    let mut ports: Vec<String> = env
        .list("/dev")
        .unwrap_or_default()
        .into_iter()
        .filter(|n| is_candidate_port(n))
        .map(|n| format!("/dev/{n}"))
        .collect();
    for p in named {
        if !ports.contains(p) {
            ports.push(p.clone());
        }
    }
    if ports.is_empty() {
        return vec![
            Finding::new(
                Area::SerialPorts,
                "serial ports",
                Verdict::Info,
                "no USB serial adapter (/dev/ttyUSB*, /dev/ttyACM*) or Bluetooth binding (/dev/rfcomm*) present",
            )
            .fix("plug the GPS or vest in, or bind the Bluetooth device: sudo rfcomm bind 0 <MAC> 1 (docs/hardware.md)"),
        ];
    }
    let groups = parse_groups(&env.read_small("/etc/group").unwrap_or_default());
    ports.iter().map(|p| port_finding(env, &groups, p)).collect()
}

/// What the console shows when `port` fails to open: the port's own verdict and, for a Bluetooth binding,
/// the Bluetooth checks.
pub fn port_findings(env: &Environment, port: &str) -> Vec<Finding> {
    let groups = parse_groups(&env.read_small("/etc/group").unwrap_or_default());
    let mut findings = vec![port_finding(env, &groups, port)];
    if port.starts_with("/dev/rfcomm") {
        findings.extend(bluetooth_findings(env));
    }
    findings
}

pub(super) fn port_finding(env: &Environment, groups: &[Group], port: &str) -> Finding {
    let finding = |verdict, detail: String| Finding::new(Area::SerialPorts, port, verdict, detail);
    let meta = match std::fs::metadata(env.at(port)) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let f = finding(Verdict::Problem, format!("{port} does not exist"));
            return if port.starts_with("/dev/rfcomm") {
                let n = port.trim_start_matches("/dev/rfcomm");
                f.fix(format!(
                    "bind the paired device: sudo rfcomm bind {n} <MAC> 1 (bluetoothctl devices Paired lists the MACs)"
                ))
            } else {
                f.fix("plug the device in; `vestnav doctor` lists the ports present")
            };
        }
        Err(e) => return finding(Verdict::Problem, format!("cannot inspect {port}: {e}")),
    };
    let owner = owner_of(&meta);
    let who = &env.identity;
    let group = groups.iter().find(|g| g.gid == owner.gid);
    let group_name = group.map_or_else(|| owner.gid.to_string(), |g| g.name.clone());
    if permits(who, owner, 0o6) {
        return finding(Verdict::Ok, format!("{} may open it (group {group_name})", who.user));
    }
    // The group could grant it: is the user in that group on paper (a new login would do) or not at all?
    if owner.mode & 0o060 == 0o060 {
        let on_paper = group.is_some_and(|g| g.members.contains(&who.user));
        return if on_paper {
            finding(
                Verdict::Problem,
                format!(
                    "{} is in group {group_name} in /etc/group, but not in this login session, so {port} cannot be opened",
                    who.user
                ),
            )
            .fix(format!("log out and back in (or run `newgrp {group_name}` in this shell)"))
        } else {
            finding(
                Verdict::Problem,
                format!(
                    "{} may not open it: it belongs to group {group_name}, and {} is not in it",
                    who.user, who.user
                ),
            )
            .fix(format!("sudo usermod -aG {group_name} {}, then log out and back in", who.user))
        };
    }
    finding(
        Verdict::Problem,
        format!(
            "{} may not open it: mode {:03o}, owner uid {}, group {group_name} gives no one else read and write",
            who.user,
            owner.mode & 0o777,
            owner.uid
        ),
    )
    .fix(format!(
        "give the dialout group access: sudo chgrp dialout {port} && sudo chmod 660 {port} (for good: a udev rule, docs/hardware.md)"
    ))
}
