//! Tests of the replay's pause/seek/progress controls, the raw sentence events and the record → replay
//! round trip. Each compares with what the test itself wrote into the file, or with the original source.

use super::*;
use crate::gps::framing::with_checksum;
use crate::gps::record::RecordingTap;
use crate::gps::{Fix, RawLine};

fn collect(rx: &Receiver<GpsEvent>, until: impl Fn(&[GpsEvent]) -> bool, timeout: Duration) -> Vec<GpsEvent> {
    let end = Instant::now() + timeout;
    let mut out = Vec::new();
    while Instant::now() < end && !until(&out) {
        if let Ok(e) = rx.recv_timeout(Duration::from_millis(20)) {
            out.push(e);
        }
    }
    out
}

fn finished(e: &[GpsEvent]) -> bool {
    e.contains(&GpsEvent::State(SourceState::Finished))
}

/// A fresh path in the temporary directory.
fn temp_path(name: &str) -> PathBuf {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos();
    std::env::temp_dir().join(format!("vestnav-{name}-{}-{nanos}", std::process::id()))
}

/// An NMEA log of `n` epochs one second apart from 12:00:00 UTC (GGA + RMC each), walking north.
fn epochs_log(n: u32) -> String {
    let mut s = String::new();
    for k in 0..n {
        let t = format!("1200{k:02}.00");
        let lat = format!("4221.{:04}", 3720 + k * 10);
        s += &with_checksum(&format!("GPGGA,{t},{lat},N,07106.0000,W,1,08,1.0,10.0,M,-33.0,M,,"));
        s += &with_checksum(&format!("GPRMC,{t},A,{lat},N,07106.0000,W,1.0,0.0,230326,,,A"));
    }
    s
}

fn time_of(f: &Fix) -> Option<String> {
    f.time_of_day.map(|t| t.format("%H:%M:%S").to_string())
}

fn fixes(ev: &[GpsEvent]) -> Vec<Fix> {
    ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some((**f).clone()) } else { None }).collect()
}

/// Pausing holds the replay; a seek to 50 % lands on the middle epoch as written in the file (its time
/// and its byte offset), is announced as a discontinuity, and the next fix is that epoch's; a seek back to
/// 0 % goes back to the first epoch the same way.
#[test]
fn pause_seek_and_progress_follow_the_file() {
    let text = epochs_log(11); // 12:00:00 .. 12:00:10: a 10 s span, the middle epoch at 12:00:05
    let path = temp_path("seek.nmea");
    std::fs::write(&path, &text).unwrap();
    let (mut h, rx) = GpsSource::spawn_channel(
        SourceConfig::Replay { path: path.clone(), speed: ReplaySpeed::Times(2.0) },
        4096,
        None,
    )
    .unwrap();
    let ctl = h.replay_control().expect("a replay has controls");
    collect(&rx, |e| e.iter().any(|e| matches!(e, GpsEvent::Raw(_))), Duration::from_secs(5));
    ctl.set_paused(true);
    assert!(ctl.is_paused());
    ctl.seek_fraction(0.5);
    let middle_at = text.find("$GPGGA,120005.00").unwrap() as u64;
    let end = Instant::now() + Duration::from_secs(3);
    while ctl.progress().position_ms != 5000 && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(10));
    }
    let p = ctl.progress();
    assert_eq!((p.position_ms, p.span_ms), (5000, 10_000));
    assert_eq!((p.position_bytes, p.total_bytes), (middle_at, text.len() as u64));
    assert!((p.fraction() - 0.5).abs() < 1e-9);
    // Paused: the position stays where the seek put it.
    let before =
        collect(&rx, |e| e.iter().any(|e| matches!(e, GpsEvent::Discontinuity(_))), Duration::from_secs(2));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(ctl.progress().position_bytes, middle_at);
    assert!(
        before.iter().any(|e| matches!(e, GpsEvent::Discontinuity(n) if n.contains("forward"))),
        "{before:?}"
    );
    ctl.set_paused(false);
    let after = collect(&rx, |e| !fixes(e).is_empty(), Duration::from_secs(5));
    assert_eq!(time_of(&fixes(&after)[0]).as_deref(), Some("12:00:05"));

    // Back to the start: announced, and the next fix is the first epoch's.
    ctl.seek_fraction(0.0);
    let back =
        collect(&rx, |e| e.iter().any(|e| matches!(e, GpsEvent::Discontinuity(_))), Duration::from_secs(3));
    assert!(back.iter().any(|e| matches!(e, GpsEvent::Discontinuity(n) if n.contains("back"))), "{back:?}");
    let next = collect(&rx, |e| !fixes(e).is_empty(), Duration::from_secs(5));
    assert_eq!(time_of(&fixes(&next)[0]).as_deref(), Some("12:00:00"));
    h.stop();
    let _ = std::fs::remove_file(&path);
}

/// Every sentence of the file comes out as a raw line, in the file's order, before the fix it completes.
#[test]
fn raw_lines_are_the_sentences_as_received() {
    let text = epochs_log(3);
    let path = temp_path("raw.nmea");
    std::fs::write(&path, &text).unwrap();
    let (mut h, rx) = GpsSource::spawn_channel(
        SourceConfig::Replay { path: path.clone(), speed: ReplaySpeed::AsFastAsPossible },
        4096,
        None,
    )
    .unwrap();
    let ev = collect(&rx, finished, Duration::from_secs(5));
    let raw: Vec<&RawLine> =
        ev.iter().filter_map(|e| if let GpsEvent::Raw(r) = e { Some(r) } else { None }).collect();
    let written: Vec<&str> = text.lines().collect();
    assert_eq!(raw.iter().map(|r| r.text.as_str()).collect::<Vec<_>>(), written);
    // The first fix (12:00:00) comes after its own GGA and RMC.
    let first_fix = ev.iter().position(|e| matches!(e, GpsEvent::Fix(_))).unwrap();
    let rmc0 =
        ev.iter().position(|e| matches!(e, GpsEvent::Raw(r) if r.text.starts_with("$GPRMC,120000"))).unwrap();
    assert!(rmc0 < first_fix);
    h.stop();
    let _ = std::fs::remove_file(&path);
}

/// Replaying a real receiver's log while recording it, then replaying the recording, gives the same fixes.
#[test]
fn recording_replays_as_the_original_source() {
    let original = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs/nd-1005.log");
    let out = temp_path("rec.nmea");
    let tap = RecordingTap::default();
    tap.start(&out).unwrap();
    // No silent overwrite: the same name again is refused, naming the file.
    let again = RecordingTap::default().start(&out).unwrap_err();
    assert!(again.contains(&out.display().to_string()), "{again}");
    let (chan, rx) = crate::outbox::Outbox::channel(4096, Overflow::Wait, None);
    let mut h = GpsSource::spawn(
        SourceConfig::Replay { path: original, speed: ReplaySpeed::AsFastAsPossible },
        vec![chan, tap.outbox()],
    )
    .unwrap();
    let a = fixes(&collect(&rx, finished, Duration::from_secs(10)));
    h.stop();
    let status = tap.stop().unwrap();
    assert!(!status.active && status.error.is_none(), "{status:?}");
    assert_eq!(status.bytes, std::fs::metadata(&out).unwrap().len());
    assert!(status.sentences > 0);

    let (mut h2, rx2) = GpsSource::spawn_channel(
        SourceConfig::Replay { path: out.clone(), speed: ReplaySpeed::AsFastAsPossible },
        4096,
        None,
    )
    .unwrap();
    let b = fixes(&collect(&rx2, finished, Duration::from_secs(10)));
    h2.stop();
    let strip = |v: Vec<Fix>| v.into_iter().map(|f| Fix { received_at: None, ..f }).collect::<Vec<_>>();
    assert_eq!(a.len(), 16);
    assert_eq!(strip(a), strip(b));
    let _ = std::fs::remove_file(&out);
}
