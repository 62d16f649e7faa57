//! A study named on the command line (`vestnav --study PROTOCOL.toml`): the Study tab opens with the
//! protocol checked and its first participant proposed, for the operator to Load and Start. With
//! `--study-wearer sim:P[:SEED[:RT_MS]]` the console also loads it into the results folder, starts it, and
//! the station's simulated wearer (`vestnav_station::study::wearer`, the one `vestnav study run --wearer`
//! uses) answers each trial after its response time: a demonstration of the tab without a participant,
//! and how the documentation's Study screenshot is made.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use vestnav_station::Station;
use vestnav_station::command::Command;
use vestnav_station::study::wearer::{SimulatedWearer, WearerSpec};
use vestnav_station::study::{StudyCommand, StudyPhase};

use super::StudyPanel;

/// `--study` and `--study-wearer`.
#[derive(Debug, Clone)]
pub struct StudyLaunch {
    /// The protocol file.
    pub protocol: PathBuf,
    /// A simulated wearer answering (the study is then loaded and started at once).
    pub wearer: Option<WearerSpec>,
    /// The results folder (`None`: the tab's, `study` in the console's files folder).
    pub out_dir: Option<PathBuf>,
}

/// The simulated wearer of a demonstration and the answer it is about to give.
pub(super) struct Demo {
    wearer: SimulatedWearer,
    /// The trial answered, when, and the answer.
    answer_at: Option<(usize, Instant, String)>,
}

impl StudyPanel {
    /// Puts `launch`'s protocol in the tab (checked, the first participant proposed); with a wearer, loads
    /// it into the results folder (under `base` when relative) and starts it. A refusal shows under the
    /// controls as any other.
    pub fn launch(&mut self, launch: &StudyLaunch, station: &mut Station, base: &std::path::Path) {
        self.protocol = launch.protocol.display().to_string();
        if let Some(d) = &launch.out_dir {
            self.out_dir = d.display().to_string();
        }
        let checked = super::check_protocol(&launch.protocol);
        if let Ok(s) = &checked.result {
            self.participant = s.participants.first().cloned().unwrap_or_else(|| "P01".to_owned());
            if let Some(first) = s.sessions.first() {
                first.clone_into(&mut self.session);
            }
        }
        let valid = checked.result.is_ok();
        self.checked = Some(checked);
        let Some(spec) = launch.wearer else { return };
        let wearer = match SimulatedWearer::from_spec(spec) {
            Ok(w) => w,
            Err(e) => {
                self.refused = Some(format!("--study-wearer: {e}"));
                return;
            }
        };
        let Some(out_dir) = crate::file_dialog::resolve(&self.out_dir, base) else { return };
        if !valid {
            return;
        }
        let load = StudyCommand::Load {
            protocol: launch.protocol.clone(),
            participant: self.participant.clone(),
            session: self.session.clone(),
            out_dir,
        };
        self.send_local(load, station);
        if self.refused.is_none() {
            self.refused = station.apply(Command::Study(StudyCommand::Start)).err();
        }
        self.demo = Some(Demo { wearer, answer_at: None });
    }

    /// The simulated wearer's turn, every frame whichever tab is shown (the console's frame calls it): each
    /// trial of the console's own station is answered once, its response time after the wearer first saw
    /// it waiting. Returns how soon the view must turn again for it (`None`: no wearer).
    pub fn simulate(&mut self, station: &mut Station, now: Instant) -> Option<Duration> {
        let demo = self.demo.as_mut()?;
        let v = station.study_view()?;
        if v.phase.is_over() {
            self.demo = None;
            return None;
        }
        if !matches!(v.phase, StudyPhase::Presenting | StudyPhase::AwaitingResponse) {
            demo.answer_at = None;
            return Some(Duration::from_millis(100));
        }
        let answer = station.study().and_then(|s| s.current()).map(|t| t.answer.clone())?;
        if demo.answer_at.as_ref().is_none_or(|(n, _, _)| *n != v.trial) {
            let (response, rt_s) = demo.wearer.respond(&answer, &v.choices);
            demo.answer_at = Some((v.trial, now + Duration::from_secs_f64(rt_s), response));
        }
        let (_, at, response) = demo.answer_at.clone()?;
        if now < at {
            return Some(at - now);
        }
        self.refused = station.apply(Command::Study(StudyCommand::Respond { answer: response })).err();
        Some(Duration::from_millis(100))
    }
}
