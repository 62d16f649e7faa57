//! Target 2: gpsd's JSON protocol — the `LineFramer` and `GpsdClient::handle_line` — over gpsd's own
//! reports (the JSON lines of the `.chk` files), mutated byte by byte and structurally (extreme numbers,
//! wrong types, huge arrays and strings, deep nesting, odd times).

use std::sync::OnceLock;
use std::time::Instant;

use proptest::prelude::*;
use serde_json::{Value, json};
use vestnav_device::gps::gpsd::{GpsdClient, LineFramer, MAX_LINE_LEN};

use crate::harness::{self, Counts, Known, Rng, add, bump};
use crate::mutate::mutate;
use crate::nmea::check_fix;

/// gpsd's JSON reports from every `.chk` file, one per line.
fn corpus() -> &'static Vec<String> {
    static C: OnceLock<Vec<String>> = OnceLock::new();
    C.get_or_init(|| {
        let lines: Vec<String> = harness::gpsd_log_dirs()
            .iter()
            .flat_map(|d| harness::read_dir_files(d, ".chk"))
            .flat_map(|(_, text)| {
                String::from_utf8_lossy(&text)
                    .lines()
                    .filter(|l| l.starts_with('{'))
                    .map(str::to_owned)
                    .collect::<Vec<_>>()
            })
            .collect();
        assert!(!lines.is_empty(), "no JSON in the .chk files");
        lines
    })
}

const KEYS: &[&str] = &[
    "class",
    "time",
    "mode",
    "lat",
    "lon",
    "alt",
    "altMSL",
    "altHAE",
    "geoidSep",
    "speed",
    "track",
    "eph",
    "epv",
    "hdop",
    "pdop",
    "vdop",
    "uSat",
    "nSat",
    "satellites",
    "PRN",
    "gnssid",
    "el",
    "az",
    "ss",
    "used",
];

const TIMES: &[&str] = &[
    "9999-12-31T23:59:59.999Z",
    "0000-01-01T00:00:00Z",
    "+275760-09-13T00:00:00Z",
    "2011-03-14T11:05:60.000Z",
    "2011-13-45T11:05:00.000Z",
    "2011-03-14T11:05:00.99999999999999999999Z",
    "2011-03-14T11:05:00+25:00",
    "2011-03-14T11:05:00-23:59",
    "",
    "T",
];

fn extreme(rng: &mut Rng, depth: usize) -> Value {
    match rng.below(14) {
        0 => json!(
            *rng.pick(&[1e308, -1e308, -1e15, 1e15, 5e-324, -0.0, 0.0, 91.0, -91.0, 181.0, -181.0, 1e20])
        ),
        1 => json!(u64::MAX),
        2 => json!(i64::MIN),
        3 => json!(*rng.pick(&["NaN", "Infinity", "-Infinity", "", "1e999", "3", "TPV", "SKY"])),
        4 => json!("x".repeat(rng.size(100_000))),
        5 => json!(rng.chance(0.5)),
        6 => Value::Null,
        7 => Value::Array((0..rng.size(5000)).map(|i| json!(i)).collect()),
        8 if depth < 4 => {
            let mut m = serde_json::Map::new();
            for _ in 0..rng.size(8) {
                m.insert((*rng.pick(KEYS)).to_owned(), extreme(rng, depth + 1));
            }
            Value::Object(m)
        }
        9 => json!(*rng.pick(TIMES)),
        10 => json!(rng.next_u64().cast_signed()),
        11 => json!(f64::from_bits(rng.next_u64())),
        12 => Value::String("\u{0}\u{202e}\u{fffd}".repeat(rng.size(100))),
        _ => json!((rng.below(2000) as f64 - 1000.0) * 0.37),
    }
}

fn satellites(rng: &mut Rng) -> Value {
    let n = rng.size(6000);
    Value::Array(
        (0..n)
            .map(|_| {
                json!({
                    "PRN": if rng.chance(0.1) { extreme(rng, 4) } else { json!(rng.below(70_000)) },
                    "gnssid": rng.below(10),
                    "el": if rng.chance(0.2) { extreme(rng, 4) } else { json!(rng.below(180) as f64 - 90.0) },
                    "az": if rng.chance(0.2) { extreme(rng, 4) } else { json!(rng.below(720)) },
                    "ss": if rng.chance(0.2) { extreme(rng, 4) } else { json!(rng.below(60)) },
                    "used": rng.chance(0.5),
                })
            })
            .collect(),
    )
}

/// One report, structurally mutated.
fn structured_line(rng: &mut Rng, n: usize) -> String {
    let base = rng.pick(corpus());
    let mut v: Value = serde_json::from_str(base).unwrap_or_else(|_| json!({"class": "TPV"}));
    if let Value::Object(m) = &mut v {
        if rng.chance(0.8) {
            m.insert("time".into(), json!(format!("2011-03-14T11:{:02}:{:02}.000Z", (n / 60) % 60, n % 60)));
        }
        for _ in 0..=rng.size(6) {
            let key = (*rng.pick(KEYS)).to_owned();
            if key == "satellites" {
                m.insert(key, satellites(rng));
            } else {
                m.insert(key, extreme(rng, 0));
            }
        }
        if rng.chance(0.1) {
            m.remove(*rng.pick(KEYS));
        }
    }
    let mut s = v.to_string();
    if rng.chance(0.1) {
        // Deep nesting, spliced in as text (serde_json refuses past 128 levels; it must not overflow).
        let depth = rng.size(100_000);
        let deep = format!("{}{}", "[".repeat(depth), "]".repeat(depth));
        if let Some(at) = s.find(':') {
            s.insert_str(at + 1, &format!("{deep},\"z\":"));
        }
    }
    s
}

fn generate(rng: &mut Rng) -> Vec<u8> {
    let lines = 1 + rng.size(40);
    if rng.chance(0.5) {
        (0..lines).map(|n| structured_line(rng, n) + "\n").collect::<String>().into_bytes()
    } else {
        let c = corpus();
        let at = rng.below(c.len());
        let mut data: Vec<u8> =
            c[at..(at + lines).min(c.len())].iter().flat_map(|l| format!("{l}\n").into_bytes()).collect();
        let others: Vec<&[u8]> = (0..2).map(|_| rng.pick(c).as_bytes()).collect();
        let max_len = if harness::long_run() { 1 << 20 } else { 256 << 10 };
        let rounds = 1 + rng.size(10);
        mutate(rng, &mut data, &others, rounds, max_len);
        data
    }
}

fn check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    let now = Instant::now();
    let mut framer = LineFramer::new(MAX_LINE_LEN);
    let mut client = GpsdClient::new();
    let mut rng = Rng::new(input.len() as u64);
    let mut rest = input;
    let (mut lines, mut fixes) = (0u64, 0u64);
    let mut bad: Option<String> = None;
    while !rest.is_empty() {
        let n = (1 + rng.size(8192)).min(rest.len());
        framer.feed(&rest[..n], |line| {
            lines += 1;
            if line.len() > MAX_LINE_LEN && bad.is_none() {
                bad = Some(format!("line framer handed out {} bytes, limit {MAX_LINE_LEN}", line.len()));
            }
            let text = String::from_utf8_lossy(line);
            if let Some(fix) = client.handle_line(&text, now) {
                fixes += 1;
                if fix.received_at != Some(now) && bad.is_none() {
                    bad = Some(format!("fix not stamped with the receive time: {:?}", fix.received_at));
                }
                if let Err(e) = check_fix(&fix) {
                    bad.get_or_insert(e);
                }
                if fix.has_position() {
                    bump(counts, "fixes with position");
                }
            }
        });
        rest = &rest[n..];
        if framer.buffered() > MAX_LINE_LEN {
            return Err(format!("line framer holds {} bytes", framer.buffered()));
        }
        if framer.capacity() > 2 * MAX_LINE_LEN + 8192 {
            return Err(format!("line framer allocated {} bytes", framer.capacity()));
        }
    }
    if let Some(e) = bad {
        return Err(e);
    }
    let st = client.stats();
    if st.epochs != fixes {
        return Err(format!("epoch count: stats say {}, {fixes} fixes", st.epochs));
    }
    // Every line is counted once: a report or a passed-on NMEA sentence, malformed, or an NMEA line whose
    // checksum is wrong or missing.
    let bad_nmea = st.bad_checksum + st.missing_checksum;
    if st.sentences + st.malformed + bad_nmea != lines {
        return Err(format!(
            "line count: {} parsed + {} malformed + {bad_nmea} NMEA without a right checksum != {lines} lines",
            st.sentences, st.malformed
        ));
    }
    bump(counts, "inputs");
    add(counts, "lines", lines);
    add(counts, "fixes", fixes);
    add(counts, "overlong lines dropped", framer.overlong());
    add(counts, "malformed lines", st.malformed);
    add(counts, "invalid positions removed", st.invalid_positions);
    add(counts, "implausible values removed", st.implausible_values);
    Ok(())
}

const KNOWN: &[Known] = &[];

#[test]
fn gpsd_client_survives_mutated_reports() {
    harness::fuzz("gpsd", 2000, KNOWN, generate, check);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(harness::cases(256).min(20_000) as u32))]

    /// Any numbers at all in a TPV and a SKY (including the non-finite ones, which serde_json writes as
    /// null): whatever comes out is a valid fix.
    #[test]
    fn any_tpv_numbers_give_a_valid_fix(
        lat in any::<f64>(), lon in any::<f64>(), alt in any::<f64>(), speed in any::<f64>(),
        track in any::<f64>(), eph in any::<f64>(), epv in any::<f64>(), hdop in any::<f64>(),
        mode in any::<u64>(), usat in any::<u64>(), prns in prop::collection::vec(any::<u64>(), 0..400),
    ) {
        let mut c = GpsdClient::new();
        let now = Instant::now();
        let sats: Vec<Value> = prns.iter().map(|p| json!({"PRN": p, "el": lat, "az": lon, "ss": alt})).collect();
        let sky = json!({"class": "SKY", "hdop": hdop, "uSat": usat, "satellites": sats});
        prop_assert!(c.handle_line(&sky.to_string(), now).is_none());
        let tpv = json!({"class": "TPV", "time": "2011-03-14T11:05:00.000Z", "mode": mode, "lat": lat,
            "lon": lon, "altMSL": alt, "speed": speed, "track": track, "eph": eph, "epv": epv});
        if let Some(fix) = c.handle_line(&tpv.to_string(), now) {
            prop_assert!(check_fix(&fix).is_ok(), "{:?}: {:?}", check_fix(&fix), fix);
        }
    }
}

/// The reproducer of the known issue above; passes once the client drops half positions.
#[test]
fn tpv_with_half_a_position_gives_no_position() {
    let mut c = GpsdClient::new();
    let fix = c
        .handle_line(r#"{"class":"TPV","mode":3,"lat":50.8,"time":"2011-03-14T11:00:06Z"}"#, Instant::now())
        .unwrap();
    assert_eq!((fix.lat_deg, fix.lon_deg), (None, None), "{fix:?}");
}
