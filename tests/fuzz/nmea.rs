//! Target 1: the NMEA decoder over mutated real logs (gpsd's regression logs).
//!
//! Each input goes through three decoders: `decode_reader_with_marks` (what `nmea decode` and log replay
//! use), a file-mode `NmeaDecoder` fed in random chunks (must give exactly the same fixes: chunking must
//! not matter), and a live-mode decoder fed in random chunks on a simulated clock that honours
//! `poll_timeout` (what the serial source does).

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use vestnav_device::gps::fix::MAX_SATELLITES;
use vestnav_device::gps::{DecoderConfig, Fix, FixMode, GpsEvent, NmeaDecoder, decode_reader_with_marks};

use crate::harness::{self, Counts, Known, Rng, add, bump};
use crate::mutate::{fix_checksums, mutate};

/// The real logs, read once.
fn corpus() -> &'static Vec<(String, Vec<u8>)> {
    static C: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    C.get_or_init(|| {
        let mut v: Vec<(String, Vec<u8>)> =
            harness::gpsd_log_dirs().iter().flat_map(|d| harness::read_dir_files(d, ".log")).collect();
        assert!(!v.is_empty(), "no gpsd logs found in tests/data/gpsd-logs");
        // A recording with marks and timestamps, as `vestnav` writes it.
        let mut recording =
            b"$PVNAV,TS,1700000000000*1C\r\n$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n\
              $PVNAV,MARK,1,cone 1*00\r\n"
                .to_vec();
        fix_checksums(&mut recording);
        v.push(("recording".into(), recording));
        v
    })
}

/// Every invariant a fix leaving a decoder must hold (NMEA and gpsd alike).
pub fn check_fix(f: &Fix) -> Result<(), String> {
    let finite_in = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
    if let Some(lat) = f.lat_deg
        && !finite_in(lat, -90.0, 90.0)
    {
        return Err(format!("latitude out of range: {lat}"));
    }
    if let Some(lon) = f.lon_deg
        && !finite_in(lon, -180.0, 180.0)
    {
        return Err(format!("longitude out of range: {lon}"));
    }
    if f.lat_deg.is_some() != f.lon_deg.is_some() {
        return Err(format!("half a position: lat {:?} lon {:?}", f.lat_deg, f.lon_deg));
    }
    if f.has_position() && f.mode == Some(FixMode::NoFix) {
        return Err("position with mode NoFix".into());
    }
    for (name, v) in [("hdop", f.hdop), ("pdop", f.pdop), ("vdop", f.vdop), ("speed", f.speed_m_s)] {
        if let Some(v) = v
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(format!("negative or non-finite {name}: {v}"));
        }
    }
    for (name, v) in [("course", f.course_deg), ("true heading", f.true_heading_deg)] {
        if let Some(v) = v
            && !(0.0..360.0).contains(&v)
        {
            return Err(format!("{name} outside [0, 360): {v}"));
        }
    }
    if let Some(e) = &f.error {
        if !(e.horizontal_m.is_finite() && e.horizontal_m >= 0.0) {
            return Err(format!("negative or non-finite horizontal error: {}", e.horizontal_m));
        }
        if let Some(v) = e.vertical_m
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(format!("negative or non-finite vertical error: {v}"));
        }
    }
    for (name, v) in [("alt", f.alt_m), ("geoid separation", f.geoid_sep_m)] {
        if let Some(v) = v
            && !v.is_finite()
        {
            return Err(format!("non-finite {name}: {v}"));
        }
    }
    if f.satellites.len() > MAX_SATELLITES as usize {
        return Err(format!("satellite list not bounded: {}", f.satellites.len()));
    }
    for s in &f.satellites {
        for (name, v) in [("elevation", s.elevation_deg), ("azimuth", s.azimuth_deg), ("snr", s.snr_dbhz)] {
            if let Some(v) = v
                && !v.is_finite()
            {
                return Err(format!("non-finite satellite {name}: {v}"));
            }
        }
    }
    if f.sats_used.is_some_and(|n| n > MAX_SATELLITES) || f.sats_visible.is_some_and(|n| n > MAX_SATELLITES) {
        return Err(format!("satellite count not bounded: {:?} {:?}", f.sats_used, f.sats_visible));
    }
    let check = f.clone().validate();
    if !check.is_clean() {
        return Err(format!("emitted fix not clean under Fix::validate: {check:?} in {f:?}"));
    }
    Ok(())
}

fn generate(rng: &mut Rng) -> Vec<u8> {
    let corpus = corpus();
    let long = harness::long_run();
    let max_len = if long { 4 << 20 } else { 96 << 10 };
    let roll = rng.below(100);
    if roll < 3 {
        // Pure garbage.
        let n = rng.size(if long { 1 << 20 } else { 16 << 10 });
        return rng.bytes(n);
    }
    if roll < 5 && long {
        // One enormous line, with or without a sentence start.
        let n = rng.size(3 << 20);
        let mut v = vec![b'9'; n];
        if let Some(first) = v.first_mut() {
            *first = b'$';
        }
        return v;
    }
    let (_, log) = rng.pick(corpus);
    let mut data = if long && rng.chance(0.1) || log.len() <= 8192 {
        log.clone()
    } else {
        // A window starting at a line start.
        let at = rng.below(log.len());
        let at = log[..at].iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
        let n = rng.size(if long { 256 << 10 } else { 24 << 10 }).max(256);
        log[at..(at + n).min(log.len())].to_vec()
    };
    let others: Vec<&[u8]> = (0..2).map(|_| rng.pick(corpus).1.as_slice()).collect();
    let rounds = 1 + rng.size(12);
    mutate(rng, &mut data, &others, rounds, max_len);
    if rng.chance(0.7) {
        fix_checksums(&mut data);
    }
    data
}

/// Fixes with the receive instant removed, for comparing decoders.
fn comparable(mut fixes: Vec<Fix>) -> Vec<Fix> {
    for f in &mut fixes {
        f.received_at = None;
    }
    fixes
}

fn check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let (fixes, marks, stats) =
        decode_reader_with_marks(input).map_err(|e| format!("io error from a slice: {e}"))?;
    let line_ends = input.iter().filter(|&&b| b == b'\n' || b == b'\r').count() as u64;
    if stats.bytes != input.len() as u64 {
        return Err(format!("byte count: stats say {}, fed {}", stats.bytes, input.len()));
    }
    if stats.sentences > line_ends + 1 {
        return Err(format!("more sentences ({}) than lines ({})", stats.sentences, line_ends + 1));
    }
    // Every fix comes from at least one verified sentence or binary frame (a UBX HNR-PVT is one frame).
    let items =
        stats.sentences + stats.ubx_frames + stats.sirf_frames + stats.casic_frames + stats.skytraq_frames;
    if fixes.len() as u64 > items {
        return Err(format!("fix count unbounded: {} fixes from {items} sentences and frames", fixes.len()));
    }
    if stats.epochs != fixes.len() as u64 {
        return Err(format!("epoch count: stats say {}, {} fixes emitted", stats.epochs, fixes.len()));
    }
    if marks.len() as u64 > stats.sentences {
        return Err(format!("mark count unbounded: {} marks", marks.len()));
    }
    for f in &fixes {
        check_fix(f)?;
    }
    add(counts, "fixes", fixes.len() as u64);
    add(counts, "fixes with position", fixes.iter().filter(|f| f.has_position()).count() as u64);
    add(counts, "sentences accepted", stats.sentences);
    add(counts, "sentences rejected", stats.rejected());
    add(counts, "invalid positions removed", stats.invalid_positions);
    add(counts, "implausible values removed", stats.implausible_values);
    add(counts, "marks", marks.len() as u64);

    // The same stream in random chunks (sizes drawn from the input itself, so the case is reproducible).
    let mut rng = Rng::new(input.iter().fold(input.len() as u64, |h, &b| h.rotate_left(5) ^ u64::from(b)));
    let now = Instant::now();
    let mut dec = NmeaDecoder::new(DecoderConfig::file());
    let mut chunked = Vec::new();
    let mut rest = input;
    while !rest.is_empty() {
        let n = (1 + rng.size(4096)).min(rest.len());
        dec.handle_bytes(&rest[..n], now);
        rest = &rest[n..];
        drain(&mut dec, &mut chunked);
    }
    dec.finish(now);
    drain(&mut dec, &mut chunked);
    if comparable(chunked) != comparable(fixes.clone()) {
        return Err("chunking changes the fixes: one read differs from random chunks".into());
    }

    // Live: chunks on a simulated clock, timeouts honoured as the serial source does.
    let mut live = NmeaDecoder::new(DecoderConfig::live());
    let mut t = now;
    let mut live_fixes = Vec::new();
    let mut rest = input;
    while !rest.is_empty() {
        let n = (1 + rng.size(512)).min(rest.len());
        let next = t + Duration::from_millis(rng.size(1200) as u64);
        while let Some(deadline) = live.poll_timeout().filter(|d| *d <= next) {
            t = t.max(deadline);
            live.handle_timeout(t);
            if let Some(again) = live.poll_timeout().filter(|d| *d <= t) {
                return Err(format!(
                    "handle_timeout leaves a deadline already past (would spin): {:?}",
                    t - again
                ));
            }
        }
        t = next;
        live.handle_bytes(&rest[..n], t);
        rest = &rest[n..];
        drain(&mut live, &mut live_fixes);
    }
    live.finish(t);
    drain(&mut live, &mut live_fixes);
    let lstats = live.stats();
    // One fix per epoch at most, and an epoch needs at least one sentence or binary frame.
    let items = lstats.sentences
        + lstats.ubx_frames
        + lstats.sirf_frames
        + lstats.casic_frames
        + lstats.skytraq_frames;
    if live_fixes.len() as u64 > items {
        return Err(format!(
            "live fix count unbounded: {} fixes, {} sentences and binary frames",
            live_fixes.len(),
            items
        ));
    }
    for f in &live_fixes {
        check_fix(f)?;
        if f.received_at.is_none_or(|r| r < now || r > t) {
            return Err(format!("live fix stamped outside the simulated clock: {:?}", f.received_at));
        }
    }
    bump(counts, "inputs");
    add(counts, "live fixes", live_fixes.len() as u64);
    Ok(())
}

fn drain(dec: &mut NmeaDecoder, out: &mut Vec<Fix>) {
    while let Some(e) = dec.poll_event() {
        if let GpsEvent::Fix(f) = e {
            out.push(*f);
        }
    }
}

const KNOWN: &[Known] = &[];

#[test]
fn nmea_decoder_survives_mutated_real_logs() {
    harness::fuzz("nmea", 2000, KNOWN, generate, check);
}

/// Specific hostile shapes, always tried: megabyte lines, NUL floods, binary frame headers with huge
/// lengths, a sentence split at every byte.
#[test]
fn nmea_decoder_survives_hostile_shapes() {
    let gga = b"$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n";
    let mut inputs: Vec<Vec<u8>> = vec![
        vec![b'$'; 1 << 20],
        vec![0; 1 << 20],
        [b"$GPGGA,".as_slice(), &vec![b'9'; 2 << 20], b"*00\r\n"].concat(),
        [&[0xB5, 0x62, 1, 7, 0xFF, 0xFF][..], gga].concat(),
        [&[0xA0, 0xA2, 0xFF, 0xFF][..], gga].concat(),
        gga.repeat(20_000),
        b"\r\n".repeat(500_000),
    ];
    let mut lat = gga.to_vec();
    lat.splice(18..27, b"9999.9999".iter().copied());
    fix_checksums(&mut lat);
    inputs.push(lat);
    let mut counts = Counts::new();
    for input in &inputs {
        let start = Instant::now();
        check(input, &mut counts).unwrap_or_else(|e| panic!("{e} on {}", harness::escape(input, 200)));
        assert!(start.elapsed() < Duration::from_mins(1), "{} bytes took {:?}", input.len(), start.elapsed());
    }
}
