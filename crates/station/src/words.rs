//! What the station says of its devices and stop path, in one wording for every reader: the console's
//! panels and banners, `vestnav station`'s terminal, a remote console and the session log.

use vestnav_device::gps::{GpsEvent, SourceState};
use vestnav_device::session_log::LogEntry;
use vestnav_device::wtcu::VestEvent;

use crate::StopAlarm;

/// The stop alarm in words: how long, acknowledged or not, which tactors the unit reports on, what to do.
pub fn stop_alarm_text(a: &StopAlarm) -> String {
    let on = a.on.filter(|m| !m.is_empty()).map(|m| {
        format!(
            " and reports tactors {} on",
            m.indices().map(|i| i.to_string()).collect::<Vec<_>>().join(", ")
        )
    });
    let ack = if a.acked { "acknowledged STOP ALL but" } else { "not acknowledged STOP ALL" };
    let what = match (a.acked, on) {
        (true, Some(on)) => format!("the unit {ack}{on}"),
        (false, Some(on)) => format!("the unit has {ack} for {:.1} s{on}", a.for_.as_secs_f64()),
        (_, None) => format!("the unit has {ack} for {:.1} s", a.for_.as_secs_f64()),
    };
    format!("{what}. The wearer may still feel tactors: switch the vest unit off now.")
}

/// What the session log records of a GPS event.
pub(crate) fn gps_log_entry(ev: &GpsEvent) -> Option<LogEntry> {
    match ev {
        GpsEvent::Fix(f) if f.has_position() => Some(LogEntry::Fix {
            lat_deg: f.lat_deg?,
            lon_deg: f.lon_deg?,
            error_m: f.error.map(|e| e.horizontal_m),
            speed_m_s: f.speed_m_s,
            course_deg: f.course_deg,
            gps_utc: f.time.map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true)),
        }),
        GpsEvent::State(s) => Some(LogEntry::Note { text: format!("gps {}", source_state_label(Some(s))) }),
        GpsEvent::Notice(n) | GpsEvent::Discontinuity(n) => {
            Some(LogEntry::Note { text: format!("gps: {n}") })
        }
        GpsEvent::Attitude(a) => Some(LogEntry::heading(a)),
        _ => None,
    }
}

/// A GPS source state in words (the GPS panel, the top bar, the session log and `vestnav station` say it
/// the same way).
pub fn source_state_label(s: Option<&SourceState>) -> String {
    match s {
        None => "disconnected".to_owned(),
        Some(SourceState::Connecting { detail }) => format!("connecting: {detail}"),
        Some(SourceState::Live { .. }) => "live".to_owned(),
        Some(SourceState::Stale) => "stale: no data".to_owned(),
        Some(SourceState::Lost { reason }) => format!("lost: {reason}"),
        Some(SourceState::Reconnecting { attempt, delay_ms }) => {
            format!("reconnecting (attempt {attempt}, in {:.1} s)", *delay_ms as f64 / 1000.0)
        }
        Some(SourceState::Finished) => "end of input".to_owned(),
        Some(SourceState::Stopped) => "stopped".to_owned(),
    }
}

/// What the session log records of a vest event.
pub(crate) fn vest_log_entry(ev: &VestEvent) -> Option<LogEntry> {
    Some(match ev {
        VestEvent::Acked { seq, kind } => LogEntry::Ack { what: format!("{} #{seq}", kind.name()) },
        VestEvent::TactorsOn(Some(mask)) => LogEntry::TactorsOn { mask: *mask },
        VestEvent::Rejected { kind, reason, .. } => {
            LogEntry::Note { text: format!("vest refused {}: {reason}", kind.name()) }
        }
        VestEvent::State(s) => LogEntry::Note { text: format!("vest {s}") },
        VestEvent::Transport(t) => LogEntry::Note { text: format!("vest transport: {t}") },
        VestEvent::Halted { reason } => LogEntry::Note { text: format!("guidance halted: {reason}") },
        VestEvent::Resumed => LogEntry::Note { text: "guidance resumed".to_owned() },
        VestEvent::Identified(info) => LogEntry::Note {
            text: format!(
                "vest identified: protocol v{}, firmware {}, {} tactors, watchdog {} ms",
                info.protocol_version, info.firmware, info.tactor_count, info.watchdog_ms
            ),
        },
        VestEvent::Heading(a) => LogEntry::heading(a),
        VestEvent::TactorsOn(None) | VestEvent::Status(_) => return None,
    })
}
