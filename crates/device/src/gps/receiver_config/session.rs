//! Sending a configuration: the sans-IO [`ConfigSession`] (commands out one at a time, replies in, a
//! timeout per command) and the [`ConfigTicket`] through which a source's worker reports each outcome.

use std::collections::VecDeque;
use std::sync::mpsc;
use std::time::Instant;

use super::reply::{Reply, reply};
use super::{ACK_TIMEOUT, ConfigCommand, Expect};
use crate::gps::framing::Framer;

/// What became of one command.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Outcome {
    /// The receiver acknowledged it (UBX-ACK-ACK, `SiRF` MID 11).
    Accepted,
    /// The receiver refused it (UBX-ACK-NAK, `SiRF` MID 12).
    Refused,
    /// No acknowledgement within [`ACK_TIMEOUT`].
    NoReply,
    /// Written; the command has no acknowledgement (a protocol switch).
    Sent,
    /// Writing it failed (the text says why).
    WriteFailed(String),
}

impl Outcome {
    /// One word for the operator.
    pub fn label(&self) -> String {
        match self {
            Self::Accepted => "accepted".into(),
            Self::Refused => "refused".into(),
            Self::NoReply => "no reply".into(),
            Self::Sent => "sent (no acknowledgement in this protocol)".into(),
            Self::WriteFailed(e) => format!("not sent: {e}"),
        }
    }
}

/// One command's outcome.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CommandOutcome {
    /// The command's name (`CFG-RATE`).
    pub name: String,
    /// What became of it.
    pub outcome: Outcome,
    /// When it was decided.
    pub at: Instant,
}

/// What a configuration run reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConfigEvent {
    /// One command decided.
    Outcome(CommandOutcome),
    /// The run could not start (the text says why: an invalid setting for this link).
    Failed(String),
    /// Every command decided.
    Finished,
}

/// The sending side of a [`ConfigTicket`] (the source's worker holds it).
#[derive(Debug, Clone)]
pub struct ConfigReporter(mpsc::Sender<ConfigEvent>);

impl ConfigReporter {
    /// Reports `ev`; a ticket dropped meanwhile is not an error.
    pub fn report(&self, ev: ConfigEvent) {
        let _ = self.0.send(ev);
    }
}

/// The operator's side of one configuration run: its events, as they are decided.
#[derive(Debug)]
pub struct ConfigTicket(mpsc::Receiver<ConfigEvent>);

impl ConfigTicket {
    /// A new ticket and the reporter that feeds it.
    pub fn channel() -> (ConfigReporter, Self) {
        let (tx, rx) = mpsc::channel();
        (ConfigReporter(tx), Self(rx))
    }

    /// The next event, if one is there.
    pub fn try_recv(&self) -> Option<ConfigEvent> {
        self.0.try_recv().ok()
    }

    /// The next event, waiting at most `timeout`.
    pub fn recv_timeout(&self, timeout: std::time::Duration) -> Option<ConfigEvent> {
        self.0.recv_timeout(timeout).ok()
    }
}

/// Sends commands one at a time and decides each from the receiver's replies (sans-IO).
///
/// `poll_transmit(now)` gives the next command's bytes when it is due (after the previous one was
/// decided, and after a protocol switch's settling time); `handle_bytes` feeds what the receiver sent;
/// `handle_timeout(now)` decides a command that got no reply; `poll_outcome` hands out the decisions. A
/// refused or unanswered command does not stop the run: a `SiRF` receiver must be switched back to NMEA
/// whatever became of the command in between.
#[derive(Debug)]
pub struct ConfigSession {
    queue: VecDeque<ConfigCommand>,
    waiting: Option<(ConfigCommand, Instant)>,
    next_at: Option<Instant>,
    /// The GPS framer, reading the receiver's replies (bounded; checksums verified).
    framer: Framer,
    outcomes: VecDeque<CommandOutcome>,
}

impl ConfigSession {
    /// A run of `commands`, the first due at once.
    pub fn new(commands: Vec<ConfigCommand>) -> Self {
        Self {
            queue: commands.into(),
            waiting: None,
            next_at: None,
            framer: Framer::new(),
            outcomes: VecDeque::new(),
        }
    }

    /// True once every command is decided and handed out.
    pub fn is_done(&self) -> bool {
        self.queue.is_empty() && self.waiting.is_none() && self.outcomes.is_empty()
    }

    /// The next command to write, when one is due at `now`. The caller writes it and reports a failed write
    /// with [`Self::write_failed`].
    pub fn poll_transmit(&mut self, now: Instant) -> Option<Vec<u8>> {
        if self.waiting.is_some() || self.next_at.is_some_and(|t| now < t) {
            return None;
        }
        self.next_at = None;
        let cmd = self.queue.pop_front()?;
        let bytes = cmd.bytes.clone();
        match cmd.expect {
            Expect::Nothing { settle } => {
                self.next_at = Some(now + settle);
                self.decide(cmd.name, Outcome::Sent, now);
            }
            Expect::UbxAck { .. } | Expect::SirfAck { .. } => self.waiting = Some((cmd, now + ACK_TIMEOUT)),
        }
        Some(bytes)
    }

    /// The last command from [`Self::poll_transmit`] could not be written.
    pub fn write_failed(&mut self, error: &str, now: Instant) {
        if let Some((cmd, _)) = self.waiting.take() {
            self.decide(cmd.name, Outcome::WriteFailed(error.to_owned()), now);
        } else if let Some(last) = self.outcomes.back_mut()
            && last.outcome == Outcome::Sent
        {
            last.outcome = Outcome::WriteFailed(error.to_owned());
        }
    }

    /// Bytes from the receiver.
    pub fn handle_bytes(&mut self, bytes: &[u8], now: Instant) {
        let mut replies = Vec::new();
        self.framer.feed(bytes, |f, _| replies.extend(reply(&f)));
        for r in replies {
            let Some((cmd, _)) = &self.waiting else { return };
            let verdict = match (cmd.expect, r) {
                (Expect::UbxAck { class, id }, Reply::UbxAck { class: c, id: i })
                    if (c, i) == (class, id) =>
                {
                    Outcome::Accepted
                }
                (Expect::UbxAck { class, id }, Reply::UbxNak { class: c, id: i })
                    if (c, i) == (class, id) =>
                {
                    Outcome::Refused
                }
                (Expect::SirfAck { mid }, Reply::SirfAck { mid: m }) if m == mid => Outcome::Accepted,
                (Expect::SirfAck { mid }, Reply::SirfNak { mid: m }) if m == mid => Outcome::Refused,
                _ => continue,
            };
            if let Some((cmd, _)) = self.waiting.take() {
                self.decide(cmd.name, verdict, now);
            }
        }
    }

    /// Decides a command whose reply is overdue at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.waiting.as_ref().is_some_and(|(_, deadline)| now >= *deadline)
            && let Some((cmd, _)) = self.waiting.take()
        {
            self.decide(cmd.name, Outcome::NoReply, now);
        }
    }

    /// The next decided command (call after writing what [`Self::poll_transmit`] gave, so a failed write
    /// is reported as such).
    pub fn poll_outcome(&mut self) -> Option<CommandOutcome> {
        self.outcomes.pop_front()
    }

    fn decide(&mut self, name: String, outcome: Outcome, at: Instant) {
        self.outcomes.push_back(CommandOutcome { name, outcome, at });
    }
}
