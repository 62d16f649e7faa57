//! When the workers wake the view: on a change the operator must see at once, not on every event.
//!
//! A view that draws (the console's window) pays for every wake with a frame: on a laptop without a GPU
//! driver a frame costs tens of milliseconds of CPU. The vest's heading stream (up to 10 Hz), the GPS
//! source's raw sentences and statistics, the unit's status reports and guidance's re-evaluations that
//! change no decision need no frame of their own: they are in the station's state at the view's next turn
//! (the view turns at least once a second while a device is connected, for the ages it shows and the
//! vest's liveness check). A link state, a fix, the tactors the unit reports on, a refusal, a halt, a
//! resume, a new cue or a new hold wake the view at once.

use std::sync::Mutex;
use std::sync::mpsc::{Receiver, TrySendError, sync_channel};

use vestnav_core::guidance::NavState;
use vestnav_core::vest::Cue;
use vestnav_device::gps::GpsEvent;
use vestnav_device::outbox::{Outbox, Waker};
use vestnav_device::wtcu::VestEvent;

use crate::guidance::GuidanceStatus;

/// Whether a GPS event changes what the view shows at once.
pub fn gps_wakes(ev: &GpsEvent) -> bool {
    !matches!(ev, GpsEvent::Raw(_) | GpsEvent::Stats(_) | GpsEvent::Attitude(_))
}

/// Whether a vest event changes what the view shows at once.
pub fn vest_wakes(ev: &VestEvent) -> bool {
    !matches!(ev, VestEvent::Heading(_) | VestEvent::Status(_) | VestEvent::Acked { .. })
}

/// What of a guidance status decides what the operator sees at once: a re-evaluation that changes none
/// of it (a new distance, a heading a degree further) waits for the view's next turn.
/// A re-route wanted (off the path long enough) wakes the view: the station plans it in its turn.
type Decision = (Option<Cue>, bool, Option<String>, usize, u64, NavState, bool, bool, bool);

fn decision(st: &GuidanceStatus) -> Decision {
    (
        st.cue,
        st.sent,
        st.hold.clone(),
        st.next,
        st.route_revision,
        st.state,
        st.finished,
        st.compass_disturbed,
        st.reroute_from.is_some(),
    )
}

/// A bounded channel to the view that never waits (a full channel drops the new event, as the view only
/// needs the newest state) and calls `waker` only for the events `wakes` picks.
pub fn outbox<T: Send + 'static>(
    capacity: usize,
    waker: Option<Waker>,
    wakes: fn(&T) -> bool,
) -> (Outbox<T>, Receiver<T>) {
    let (tx, rx) = sync_channel(capacity.max(1));
    let out = Outbox::sink(move |ev: T| {
        let wake = wakes(&ev);
        if let Err(TrySendError::Disconnected(_)) = tx.try_send(ev) {
            return false;
        }
        if wake && let Some(w) = &waker {
            w();
        }
        true
    });
    (out, rx)
}

/// The guidance worker's channel to the view: wakes it when the `Decision` changes.
pub fn guidance_outbox(
    capacity: usize,
    waker: Option<Waker>,
) -> (Outbox<GuidanceStatus>, Receiver<GuidanceStatus>) {
    let (tx, rx) = sync_channel(capacity.max(1));
    let last: Mutex<Option<Decision>> = Mutex::new(None);
    let out = Outbox::sink(move |st: GuidanceStatus| {
        let d = decision(&st);
        let changed = last.lock().map_or(true, |mut l| l.replace(d.clone()).as_ref() != Some(&d));
        if let Err(TrySendError::Disconnected(_)) = tx.try_send(st) {
            return false;
        }
        if changed && let Some(w) = &waker {
            w();
        }
        true
    });
    (out, rx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn counter() -> (Arc<AtomicUsize>, Waker) {
        let n = Arc::new(AtomicUsize::new(0));
        let m = n.clone();
        (
            n,
            Arc::new(move || {
                m.fetch_add(1, Ordering::Relaxed);
            }),
        )
    }

    #[test]
    fn acks_are_delivered_without_waking_and_a_tactor_change_wakes() {
        let (n, waker) = counter();
        let (out, rx) = outbox(8, Some(waker), vest_wakes);
        let cancel = std::sync::atomic::AtomicBool::new(false);
        for seq in 0..5 {
            assert!(
                out.send(
                    VestEvent::Acked { seq, kind: vestnav_device::wtcu::CommandKind::Heartbeat },
                    &cancel
                )
            );
        }
        assert_eq!(n.load(Ordering::Relaxed), 0);
        assert!(out.send(VestEvent::TactorsOn(None), &cancel));
        assert_eq!(n.load(Ordering::Relaxed), 1);
        assert_eq!(rx.try_iter().count(), 6, "every event still reaches the view");
    }

    #[test]
    fn guidance_wakes_on_a_new_decision_only() {
        let (n, waker) = counter();
        let (out, rx) = guidance_outbox(8, Some(waker));
        let cancel = std::sync::atomic::AtomicBool::new(false);
        let mut st = GuidanceStatus {
            cue: None,
            reason: "walking".to_owned(),
            sent: false,
            hold: None,
            next: 0,
            route_revision: 1,
            distance_m: Some(10.0),
            bearing_deg: None,
            bearing_error_deg: None,
            cross_track_m: None,
            heading_source: vestnav_core::guidance::HeadingSource::None,
            heading_deg: None,
            heading_rule: String::new(),
            compass_disturbed: false,
            declination_deg: None,
            state: NavState::Hold,
            finished: false,
            off_path_s: None,
            reroute_from: None,
        };
        assert!(out.send(st.clone(), &cancel));
        st.distance_m = Some(9.0);
        assert!(out.send(st.clone(), &cancel));
        assert_eq!(n.load(Ordering::Relaxed), 1, "a new distance alone waits for the next turn");
        st.cue = Some(Cue::TurnLeft);
        st.sent = true;
        assert!(out.send(st, &cancel));
        assert_eq!(n.load(Ordering::Relaxed), 2);
        assert_eq!(rx.try_iter().count(), 3);
    }
}
