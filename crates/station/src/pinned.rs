//! The pinned-receiver diagnosis the GPS panel and guidance's banner show: core's [`PinDetector`] (a
//! position repeated exactly while nothing says the receiver moves) fed with every fix and the vest
//! compass's pitch, plus the receiver family the stream shows ([`Family::detect`]), which names the
//! cause and the fix: `SiRF` static navigation off, or u-blox static hold off, through the receiver
//! configuration path (a direct serial port).

use vestnav_core::pinned::{PinDetector, PinnedReport};
use vestnav_device::gps::receiver_config::{Family, ReceiverConfig};

/// A receiver holding its position, with what is known of why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinned {
    /// Core's report (how long, where, what says the wearer moves).
    pub report: PinnedReport,
    /// The receiver family its stream shows, if it shows one.
    pub family: Option<Family>,
}

impl Pinned {
    /// The diagnosis from `detector` at `now_s` with the family `family`; `None` while no position is held.
    pub fn diagnose(detector: &PinDetector, now_s: f64, family: Option<Family>) -> Option<Self> {
        detector.report(now_s).map(|report| Self { report, family })
    }

    /// The cause in a few words, for the banner's head.
    pub fn cause(&self) -> &'static str {
        match self.family {
            Some(Family::Sirf) => "SiRF static navigation is pinning the position",
            Some(Family::Ublox | Family::Ublox9) => "u-blox static hold is pinning the position",
            None => "the receiver is holding one position (a static-navigation filter?)",
        }
    }

    /// The whole diagnosis: cause, evidence, consequence, what to do.
    pub fn text(&self) -> String {
        let held = self.report.held_s;
        let evidence = match self.report.wearer_moves {
            Some(e) => format!(" while {}", e.describe()),
            None => " (no compass or simulator says whether the wearer moves)".to_owned(),
        };
        let todo = match self.family {
            Some(Family::Sirf) => "Turn static navigation off (GPS panel, one click).",
            Some(_) => "Turn static hold off (GPS panel, one click).",
            None => "Open Receiver in the GPS panel and turn the receiver's static navigation or hold off.",
        };
        format!(
            "{}: the same position for {held:.0} s{evidence}; guidance is holding (attention cues, no \
             direction, no arrival) until the position moves again. {todo}",
            self.cause()
        )
    }

    /// The configuration that removes the cause, when the family is known.
    pub fn remedy(&self) -> Option<ReceiverConfig> {
        match self.family? {
            Family::Sirf => {
                Some(ReceiverConfig { sirf_static_nav: Some(false), ..ReceiverConfig::new(Family::Sirf) })
            }
            f @ (Family::Ublox | Family::Ublox9) => {
                Some(ReceiverConfig { static_hold_m_s: Some(0.0), ..ReceiverConfig::new(f) })
            }
        }
    }
}
