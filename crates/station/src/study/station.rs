//! The station's side of the study runner: the [`StudyIo`] it gives the runner (the session clock, the
//! markers into the session log, the operator's manual path to the vest, the stop path) and the
//! [`Station`] methods that apply [`StudyCommand`]s, turn the runner in each pump and show its view.

use std::time::Duration;

use vestnav_device::session_log::LogEntry;
use vestnav_device::wtcu::{Limits, VestCommand, VestEvent};

use super::{StudyCommand, StudyIo, StudyPhase, StudyRunner, StudyView, Timing};
use crate::Station;
use crate::lab::LabOutputs;

/// The station's study: the session loaded, if any, and the timing the next one is loaded with.
#[derive(Debug, Default)]
pub struct StudySlot {
    runner: Option<StudyRunner>,
    timing: Timing,
    /// The lab outputs of the session loaded: its clock and its markers for the whole session (lab
    /// outputs turned on later serve the next session).
    lab: Option<LabOutputs>,
}

/// The station as the runner sees it.
struct Io<'a>(&'a mut Station);

impl StudyIo for Io<'_> {
    fn now_s(&self) -> f64 {
        self.0.study_clock_s()
    }

    fn marker(&mut self, text: &str, at_s: f64) {
        if let Some(lab) = &self.0.study.lab {
            lab.marker(text, at_s);
        }
        self.0.log(LogEntry::Note { text: format!("study marker {at_s:.6} {text}") });
    }

    fn send(&mut self, command: VestCommand) -> Result<(), String> {
        self.0.send_manual(command, None)
    }

    fn stop_vest(&mut self) {
        self.0.stop_all();
    }

    fn hold_guidance(&mut self) {
        if self.0.settings.guidance.auto {
            let mut s = self.0.settings;
            s.guidance.auto = false;
            self.0.set_settings(s);
        }
    }
}

impl Station {
    /// The clock of the study session loaded [s]: liblsl's clock when the lab outputs had LSL on at load,
    /// else seconds since the load; before any load, seconds since the station started.
    pub fn study_clock_s(&self) -> f64 {
        match &self.study.lab {
            Some(lab) => lab.now(),
            None => self.epoch.elapsed().as_secs_f64(),
        }
    }

    /// The study loaded, if any.
    pub fn study(&self) -> Option<&StudyRunner> {
        self.study.runner.as_ref()
    }

    /// The timing between trials of the sessions loaded from now on.
    pub fn set_study_timing(&mut self, timing: Timing) {
        self.study.timing = timing;
    }

    /// What a view shows of the study loaded.
    pub fn study_view(&self) -> Option<StudyView> {
        self.study.runner.as_ref().map(StudyRunner::view)
    }

    /// How soon the runner needs the next pump (a view that sleeps between events wakes by then).
    pub fn study_wake_in(&self) -> Option<Duration> {
        let until = self.study.runner.as_ref()?.next_deadline_s()?;
        Some(Duration::from_secs_f64((until - self.study_clock_s()).clamp(0.0, 3600.0)))
    }

    /// Applies a study command; `Err` says why it was refused.
    pub fn study_command(&mut self, cmd: StudyCommand) -> Result<(), String> {
        self.log(LogEntry::Note { text: cmd.describe() });
        match cmd {
            StudyCommand::Load { protocol, participant, session, out_dir } => {
                if self
                    .study
                    .runner
                    .as_ref()
                    .is_some_and(|s| !s.phase().is_over() && s.phase() != StudyPhase::Ready)
                {
                    return Err("study load refused: a session runs; abort or unload it first".to_owned());
                }
                let limits =
                    self.vest.device.map_or_else(Limits::default, |d| Limits::default().tighter(&d.limits));
                let runner = StudyRunner::load(
                    &protocol,
                    &participant,
                    &session,
                    &out_dir,
                    &limits,
                    self.study.timing,
                )?;
                self.study.runner = Some(runner);
                Ok(())
            }
            StudyCommand::Unload => {
                self.with_study(|r, io| {
                    if !r.phase().is_over() && r.phase() != StudyPhase::Ready {
                        let _ = r.command(StudyCommand::Abort, io);
                    }
                });
                self.study.runner = None;
                self.study.lab = None;
                Ok(())
            }
            cmd => {
                let Some(mut r) = self.study.runner.take() else {
                    return Err(format!("{} refused: no study loaded", cmd.describe()));
                };
                let result = r.command(cmd, &mut Io(self));
                self.study.runner = Some(r);
                result
            }
        }
    }

    /// The runner's share of a pump: the vest's events of this pump, then its timers.
    pub(crate) fn study_pump(&mut self, events: &[VestEvent]) {
        self.with_study(|r, io| {
            for ev in events {
                r.vest_event(ev, io);
            }
            r.turn(io);
        });
    }

    /// Ends a running session because the station ends (its vest already stopped).
    pub(crate) fn study_exit(&mut self) {
        self.with_study(StudyRunner::exit);
    }

    fn with_study(&mut self, f: impl FnOnce(&mut StudyRunner, &mut dyn StudyIo)) {
        if let Some(mut r) = self.study.runner.take() {
            f(&mut r, &mut Io(self));
            self.study.runner = Some(r);
        }
    }
}
