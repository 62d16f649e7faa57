//! `vestnav nmea decode | record`.

#![allow(clippy::print_stdout)] // printing decoded epochs is this command's job

use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use clap::Args;
use vestnav_device::gps::record::{Recorder, unix_ms_now};
use vestnav_device::gps::source::detect_baud;
use vestnav_device::gps::{
    DecodeStats, DecoderConfig, Fix, FixMode, FixQuality, GpsEvent, Mark, NmeaDecoder,
};

/// Arguments of `vestnav nmea decode`.
#[derive(Debug, Args)]
pub struct DecodeArgs {
    /// NMEA logs or recordings to decode ('-' = standard input).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// One JSON object per epoch (default: one text line per epoch).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vestnav nmea record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Serial port to read (/dev/rfcomm0, /dev/ttyUSB0, COM5, a PTY path).
    pub port: String,
    /// Output file (NMEA with `$PVNAV,TS,<unix_ms>` timestamps; replayable).
    pub file: PathBuf,
    /// Baud rate; detected automatically when omitted.
    #[arg(long)]
    pub baud: Option<u32>,
    /// Stop after this many seconds (default: until interrupted).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Take operator marks from standard input: each line (Enter) records `$PVNAV,MARK,<n>,<line>` at
    /// that moment, an empty line is labelled `cone <n>` — the cone test's marks (`vestnav fieldtest cones`).
    #[arg(long)]
    pub marks: bool,
}

/// The per-epoch JSON object of `nmea decode --json`.
#[derive(serde::Serialize)]
struct EpochJson {
    time: Option<IsoTime>,
    lat: Option<f64>,
    lon: Option<f64>,
    alt_m: Option<f64>,
    mode: Option<&'static str>,
    quality: Option<u8>,
    sats_used: Option<u32>,
    sats_visible: Option<u32>,
    hdop: Option<f64>,
    pdop: Option<f64>,
    vdop: Option<f64>,
    speed_m_s: Option<f64>,
    course_deg: Option<f64>,
    true_heading_deg: Option<f64>,
    error_h_m: Option<f64>,
}

fn mode_name(m: FixMode) -> &'static str {
    match m {
        FixMode::NoFix => "nofix",
        FixMode::Fix2D => "2d",
        FixMode::Fix3D => "3d",
    }
}

/// A UTC time printed as ISO-8601 with milliseconds, e.g. `2011-03-14T11:05:18.000Z`; serialised as a
/// JSON string without an intermediate `String`.
struct IsoTime(chrono::DateTime<chrono::Utc>);

impl std::fmt::Display for IsoTime {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use chrono::{Datelike as _, Timelike as _};
        let t = self.0;
        write!(
            f,
            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z",
            t.year(),
            t.month(),
            t.day(),
            t.hour(),
            t.minute(),
            t.second(),
            (t.nanosecond() / 1_000_000).min(999)
        )
    }
}

impl serde::Serialize for IsoTime {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// ISO-8601 UTC with milliseconds, e.g. `2011-03-14T11:05:18.000Z`.
fn iso(t: chrono::DateTime<chrono::Utc>) -> String {
    IsoTime(t).to_string()
}

fn opt(x: Option<f64>, prec: usize) -> String {
    x.map_or_else(|| "-".to_owned(), |v| format!("{v:.prec$}"))
}

fn write_fix(out: &mut impl Write, f: &Fix, json: bool) -> anyhow::Result<()> {
    if json {
        serde_json::to_writer(
            &mut *out,
            &EpochJson {
                time: f.time.map(IsoTime),
                lat: f.lat_deg,
                lon: f.lon_deg,
                alt_m: f.alt_m,
                mode: f.mode.map(mode_name),
                quality: f.quality.map(FixQuality::digit),
                sats_used: f.sats_used,
                sats_visible: f.sats_visible,
                hdop: f.hdop,
                pdop: f.pdop,
                vdop: f.vdop,
                speed_m_s: f.speed_m_s,
                course_deg: f.course_deg,
                true_heading_deg: f.true_heading_deg,
                error_h_m: f.error.map(|e| e.horizontal_m),
            },
        )?;
        out.write_all(b"\n")?;
    } else {
        writeln!(
            out,
            "{} {:>5} {} {} alt {} m sats {}/{} hdop {} speed {} m/s course {}",
            f.time.map_or_else(|| f.time_of_day.map_or_else(|| "-".into(), |t| t.to_string()), iso),
            f.mode.map_or("-", mode_name),
            opt(f.lat_deg, 7),
            opt(f.lon_deg, 7),
            opt(f.alt_m, 1),
            f.sats_used.map_or_else(|| "-".into(), |n| n.to_string()),
            f.sats_visible.map_or_else(|| "-".into(), |n| n.to_string()),
            opt(f.hdop, 2),
            opt(f.speed_m_s, 2),
            opt(f.course_deg, 1),
        )?;
    }
    Ok(())
}

fn write_mark(out: &mut impl Write, m: &Mark, json: bool) -> anyhow::Result<()> {
    if json {
        let v = serde_json::json!({ "mark": m.number, "label": m.label, "time": m.time.map(iso) });
        writeln!(out, "{v}")?;
    } else {
        writeln!(out, "mark {} {:?} at {}", m.number, m.label, m.time.map_or_else(|| "-".into(), iso))?;
    }
    Ok(())
}

/// Decodes one stream, printing each epoch as it completes (no buffering of the whole file).
fn decode_stream(mut reader: impl Read, out: &mut impl Write, json: bool) -> anyhow::Result<DecodeStats> {
    let mut decoder = NmeaDecoder::new(DecoderConfig::file());
    let mut buf = vec![0u8; 256 * 1024];
    let now = Instant::now();
    let mut done = false;
    while !done {
        let n = match reader.read(&mut buf) {
            Ok(0) => {
                decoder.finish(now);
                done = true;
                0
            }
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.into()),
        };
        decoder.handle_bytes(&buf[..n], now);
        while let Some(ev) = decoder.poll_event() {
            match ev {
                GpsEvent::Fix(f) => write_fix(out, &f, json)?,
                GpsEvent::Mark(m) => write_mark(out, &m, json)?,
                // `nmea decode` prints one line per epoch; HDG compass readings (GpsEvent::Attitude) are
                // counted in the stats but not printed.
                GpsEvent::Attitude(_)
                | GpsEvent::Stats(_)
                | GpsEvent::State(_)
                | GpsEvent::Notice(_)
                | GpsEvent::Raw(_)
                | GpsEvent::Discontinuity(_) => {}
            }
        }
    }
    Ok(decoder.stats())
}

/// Runs `vestnav nmea decode`.
pub fn run_decode(args: &DecodeArgs) -> anyhow::Result<()> {
    let mut total = DecodeStats::default();
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::with_capacity(256 * 1024, stdout.lock());
    for path in &args.files {
        let stats = if path.as_os_str() == "-" {
            decode_stream(std::io::stdin().lock(), &mut out, args.json)
        } else {
            let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
            decode_stream(file, &mut out, args.json)
        }
        .with_context(|| format!("decoding {}", path.display()))?;
        out.flush()?;
        if let Some(p) = stats.undecoded_protocol {
            bail!("{}: {}", path.display(), p.advice());
        }
        if stats.recognised() == 0 {
            bail!(
                "{}: not an NMEA log: no NMEA sentence or GPS binary frame in its {} bytes",
                path.display(),
                stats.bytes
            );
        }
        eprintln!("{}: {stats}", path.display());
        total.merge(&stats);
    }
    if args.files.len() > 1 {
        eprintln!("total: {total}");
    }
    Ok(())
}

/// Runs `vestnav nmea record`.
pub fn run_record(args: &RecordArgs) -> anyhow::Result<()> {
    let stop = std::sync::atomic::AtomicBool::new(false);
    let (baud, first) = if let Some(b) = args.baud {
        (b, Vec::new())
    } else {
        let (b, bytes) = detect_baud(&args.port, Duration::from_millis(1500), &stop)
            .map_err(|e| anyhow::anyhow!("baud detection on {}: {e}", args.port))?;
        eprintln!("{}: NMEA found at {b} baud", args.port);
        (b, bytes)
    };
    let mut port = vestnav_device::serial::open(&args.port, baud, Duration::from_millis(200))?;
    let file =
        std::fs::File::create(&args.file).with_context(|| format!("creating {}", args.file.display()))?;
    let mut rec = Recorder::new(std::io::BufWriter::new(file));
    rec.write(&first, unix_ms_now())?;
    let start = Instant::now();
    let mut buf = [0u8; 4096];
    let mut total = first.len();
    eprintln!("recording {} at {baud} baud to {} (Ctrl-C to stop)", args.port, args.file.display());
    let marks = args.marks.then(spawn_mark_reader);
    if marks.is_some() {
        eprintln!("press Enter to mark a cone (type a label first to name the mark)");
    }
    loop {
        if args.duration_s.is_some_and(|d| start.elapsed().as_secs_f64() >= d) {
            break;
        }
        while let Some(label) = marks.as_ref().and_then(|rx| rx.try_recv().ok()) {
            let now = unix_ms_now();
            let n = rec.mark(&label, now)?;
            rec.flush()?;
            eprintln!("mark {n} {}", if label.is_empty() { "(cone)" } else { label.as_str() });
        }
        match port.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                rec.write(&buf[..n], unix_ms_now())?;
                // Flush every chunk: an interrupted recording keeps everything received so far.
                rec.flush()?;
                total += n;
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => {
                rec.flush()?;
                return Err(e).with_context(|| format!("reading {}", args.port));
            }
        }
    }
    rec.flush()?;
    eprintln!("recorded {total} bytes");
    Ok(())
}

/// Reads operator mark labels, one per line of standard input, on a thread of their own (a blocking read
/// must not stall the recording). An empty line becomes `cone <n>` in the recording.
fn spawn_mark_reader() -> std::sync::mpsc::Receiver<String> {
    let (tx, rx) = std::sync::mpsc::sync_channel(64);
    let spawned = std::thread::Builder::new().name("marks-stdin".into()).spawn(move || {
        let mut count = 0u32;
        for line in std::io::stdin().lines() {
            let Ok(line) = line else { break };
            count += 1;
            let label = line.trim();
            let label = if label.is_empty() { format!("cone {count}") } else { label.to_owned() };
            if tx.send(label).is_err() {
                break;
            }
        }
    });
    if let Err(e) = spawned {
        eprintln!("cannot read marks from standard input: {e}");
    }
    rx
}
