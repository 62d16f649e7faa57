//! GPS decoder throughput: the same decoder (`NmeaDecoder`: framer, NMEA assembly, UBX decoder) on a UBX
//! log and on NMEA logs of about the same size, in MB/s (criterion's throughput) and epochs per second
//! (printed once per input: epochs in the input x iterations per second).

#![allow(missing_docs)] // criterion_main! generates an undocumented `main`.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use vestnav_device::gps::{DecoderConfig, GpsEvent, NmeaDecoder};

fn data(rel: &str) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data").join(rel);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Decodes the whole input; returns the number of fixes.
fn decode(bytes: &[u8]) -> u64 {
    let now = Instant::now();
    let mut d = NmeaDecoder::new(DecoderConfig::file());
    let mut fixes = 0;
    for chunk in bytes.chunks(64 * 1024) {
        d.handle_bytes(chunk, now);
        while let Some(ev) = d.poll_event() {
            fixes += u64::from(matches!(ev, GpsEvent::Fix(_)));
        }
    }
    d.finish(now);
    while let Some(ev) = d.poll_event() {
        fixes += u64::from(matches!(ev, GpsEvent::Fix(_)));
    }
    fixes
}

fn throughput(c: &mut Criterion) {
    let inputs = [
        ("UBX u-blox GLONASS (ublox-glo.log)", data("gpsd-logs-more/ublox-glo.log")),
        ("UBX NEO-M8L + HNR (ublox-neo-m8l.log)", data("gpsd-logs-more/ublox-neo-m8l.log")),
        ("NMEA B&G Zeus (bundg_zeus_9.log)", data("gpsd-logs-more/bundg_zeus_9.log")),
        ("NMEA u-blox M9 (ublox-neo-m9n-nmea.log)", data("gpsd-logs/ublox-neo-m9n-nmea.log")),
    ];
    let mut g = c.benchmark_group("gps decode");
    for (name, bytes) in &inputs {
        let epochs = decode(bytes);
        // Epochs per second, measured outside criterion so the figure is printed next to its MB/s.
        let t0 = Instant::now();
        let mut n = 0u32;
        while t0.elapsed().as_secs_f64() < 1.0 {
            black_box(decode(black_box(bytes)));
            n += 1;
        }
        let s = t0.elapsed().as_secs_f64() / f64::from(n);
        eprintln!(
            "{name}: {} bytes, {epochs} epochs; {:.1} MB/s, {:.0} epochs/s",
            bytes.len(),
            bytes.len() as f64 / s / 1e6,
            epochs as f64 / s
        );
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        g.bench_function(*name, |b| b.iter(|| decode(black_box(bytes))));
    }
    g.finish();
}

criterion_group!(benches, throughput);
criterion_main!(benches);
