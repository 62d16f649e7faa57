//! Tests of the vest worker against the in-process emulated unit: STOP ALL, guidance latch, liveness, exit.

use super::*;
use crate::wtcu::emulator::UnitConfig;
use vestnav_core::vest::Frame;

fn emulated() -> (VestHandle, Receiver<VestEvent>) {
    let connector: Connector = Box::new(|| {
        Ok(Box::new(EmulatedPort::new(&UnitConfig::default(), Duration::from_millis(2)))
            as Box<dyn Transport>)
    });
    VestHandle::spawn_with_receiver(connector, WorkerSettings::default()).unwrap()
}

/// Waits for the first event matching `f`, collecting everything seen.
fn wait(
    rx: &Receiver<VestEvent>,
    seen: &mut Vec<VestEvent>,
    f: impl Fn(&VestEvent) -> bool,
) -> Option<Instant> {
    let end = Instant::now() + Duration::from_secs(3);
    while Instant::now() < end {
        if let Ok(ev) = rx.recv_timeout(Duration::from_millis(10)) {
            let hit = f(&ev);
            seen.push(ev);
            if hit {
                return Some(Instant::now());
            }
        }
    }
    None
}

fn ready(rx: &Receiver<VestEvent>) {
    let mut seen = Vec::new();
    assert!(wait(rx, &mut seen, |e| *e == VestEvent::State(LinkState::Ready)).is_some(), "{seen:?}");
}

fn long_pattern() -> Pattern {
    Pattern {
        name: "long".into(),
        frames: vec![
            Frame { mask: TactorMask(0x000F), duration_ms: 1500 },
            Frame { mask: TactorMask::NONE, duration_ms: 500 },
        ],
        repeats: 3,
    }
}

#[test]
fn stop_all_jumps_a_full_queue_and_cancels_what_was_queued() {
    let (vest, rx) = emulated();
    ready(&rx);
    // Fill the queue: whatever is waiting there must not delay the stop, nor play after it.
    let mut queued = 0;
    while vest.send(VestCommand::Play(long_pattern()), CommandOrigin::Manual).is_ok() {
        queued += 1;
        assert!(queued <= 64, "the queue is bounded");
    }
    assert_eq!(vest.send(VestCommand::RequestStatus, CommandOrigin::Manual), Err(VestSendError::Full));
    let t0 = Instant::now();
    vest.stop_all();
    let mut seen = Vec::new();
    let acked = wait(&rx, &mut seen, |e| matches!(e, VestEvent::Acked { kind: CommandKind::StopAll, .. }))
        .expect("STOP ALL acknowledged");
    // Not behind the queued PLAYs (each would add its round trip). The 50 ms bound itself is measured
    // end to end over a real PTY by the integration tests that run alone (tests/integration/safety.rs);
    // this crate's tests share the machine with floods and 200 MB streams.
    assert!(acked - t0 < Duration::from_millis(250), "{:?}", acked - t0);
    // Everything queued before the stop is refused, never played after it.
    std::thread::sleep(Duration::from_millis(100));
    seen.extend(rx.try_iter());
    let plays_after_stop = seen
        .iter()
        .skip_while(|e| !matches!(e, VestEvent::Acked { kind: CommandKind::StopAll, .. }))
        .filter(|e| matches!(e, VestEvent::Acked { kind: CommandKind::Play, .. }))
        .count();
    assert_eq!(plays_after_stop, 0, "{seen:?}");
    assert!(seen.iter().any(
        |e| matches!(e, VestEvent::Rejected { reason, .. } if reason.contains("cancelled by STOP ALL"))
    ));
}

/// Every cue handed to the worker has exactly one outcome, and a refusal names who sent it, wherever it
/// happened: superseded in the link's queue, cancelled by STOP ALL, or refused by the worker. (A study
/// counts guidance's cues that reached the wearer by this.)
#[test]
fn every_cue_has_one_outcome_that_names_its_sender() {
    let (vest, rx) = emulated();
    ready(&rx);
    let mut sent = 0;
    // A burst: while one is in flight the next waits in the link's queue and the one after supersedes it.
    while sent < 20 && vest.send(VestCommand::Play(long_pattern()), CommandOrigin::Guidance).is_ok() {
        sent += 1;
    }
    let mut seen = Vec::new();
    std::thread::sleep(Duration::from_millis(100));
    vest.stop_all();
    assert!(
        wait(&rx, &mut seen, |e| matches!(e, VestEvent::Acked { kind: CommandKind::StopAll, .. })).is_some()
    );
    std::thread::sleep(Duration::from_millis(100));
    seen.extend(rx.try_iter());
    let acked = seen.iter().filter(|e| matches!(e, VestEvent::Acked { kind: CommandKind::Play, .. })).count();
    let refused: Vec<_> = seen
        .iter()
        .filter_map(|e| match e {
            VestEvent::Rejected { kind: CommandKind::Play, origin, reason } => Some((origin, reason)),
            _ => None,
        })
        .collect();
    assert_eq!(acked + refused.len(), sent, "{seen:?}");
    assert!(refused.iter().any(|(_, why)| why.contains("superseded")), "{refused:?}");
    assert!(refused.iter().all(|(o, _)| **o == Some(CommandOrigin::Guidance)), "{refused:?}");
}

#[test]
fn automatic_commands_are_refused_after_stop_all_until_resumed() {
    let (vest, rx) = emulated();
    ready(&rx);
    let cue = VestCommand::Fire { mask: TactorMask(1), duration_ms: 200 };
    assert_eq!(vest.send(cue.clone(), CommandOrigin::Guidance), Ok(()));
    vest.stop_all();
    assert!(vest.is_halted());
    assert!(matches!(vest.send(cue.clone(), CommandOrigin::Guidance), Err(VestSendError::Halted(_))));
    // The operator's own commands still go.
    assert_eq!(vest.send(cue.clone(), CommandOrigin::Manual), Ok(()));
    let mut seen = Vec::new();
    assert!(wait(&rx, &mut seen, |e| matches!(e, VestEvent::Halted { .. })).is_some());
    vest.resume_guidance();
    assert!(!vest.is_halted());
    assert_eq!(vest.send(cue, CommandOrigin::Guidance), Ok(()));
    assert!(wait(&rx, &mut seen, |e| *e == VestEvent::Resumed).is_some());
}

#[test]
fn a_stalled_watched_thread_stops_every_tactor() {
    let (vest, rx) = emulated();
    ready(&rx);
    let beat = vest.heartbeat(Watched::Guidance, Duration::from_millis(100));
    // The first beat only announces the thread: a long pause after it is start-up, not a stall.
    beat.beat();
    std::thread::sleep(Duration::from_millis(250));
    assert!(!vest.is_halted(), "armed by the first beat");
    // The last beat: the guidance thread stalls after it, and the worker's clock runs from it.
    let last_beat = Instant::now();
    beat.beat();
    assert_eq!(vest.send(VestCommand::Play(long_pattern()), CommandOrigin::Guidance), Ok(()));
    let mut seen = Vec::new();
    let stop_acked = |e: &VestEvent| matches!(e, VestEvent::Acked { kind: CommandKind::StopAll, .. });
    assert!(wait(&rx, &mut seen, |e| matches!(e, VestEvent::TactorsOn(Some(m)) if !m.is_empty())).is_some());
    // The worker stops the vest by itself, never before the bound. (Under load the stop may already have
    // come while the pattern's start was awaited: then only that it came is checked.)
    if !seen.iter().any(stop_acked) {
        let stopped = wait(&rx, &mut seen, stop_acked).expect("the worker stopped the vest");
        let after = stopped - last_beat;
        assert!(after >= Duration::from_millis(100) && after < Duration::from_millis(500), "{after:?}");
    }
    assert!(seen.iter().any(|e| matches!(e, VestEvent::Halted { reason } if reason.contains("guidance"))));
    assert!(matches!(
        vest.send(VestCommand::Play(long_pattern()), CommandOrigin::Guidance),
        Err(VestSendError::Halted(_))
    ));
    // A released heartbeat is not a stall.
    vest.resume_guidance();
    beat.beat();
    beat.release();
    std::thread::sleep(Duration::from_millis(300));
    assert!(!vest.is_halted());
}

#[test]
fn the_stopper_stops_and_closes_within_the_exit_budget() {
    let (vest, rx) = emulated();
    ready(&rx);
    assert_eq!(vest.send(VestCommand::Play(long_pattern()), CommandOrigin::Guidance), Ok(()));
    let stopper = vest.stopper();
    let t0 = Instant::now();
    assert!(stopper.stop_and_close(Duration::from_millis(180)), "STOP ALL acknowledged");
    assert!(t0.elapsed() < Duration::from_millis(200), "{:?}", t0.elapsed());
    let until = Instant::now() + Duration::from_secs(2);
    while vest.is_running() && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!vest.is_running());
    assert_eq!(vest.send(VestCommand::RequestStatus, CommandOrigin::Manual), Err(VestSendError::Stopped));
}
