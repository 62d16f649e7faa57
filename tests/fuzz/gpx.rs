//! Target 4: GPX routes (`vestnav_device::route_file::parse_gpx_bytes`) from the demo route and generated
//! files — extreme and malformed coordinates, huge names, many points, deep nesting, truncated XML — then
//! mutated byte by byte. A file that parses must hold only valid positions, and writing it back with
//! `to_gpx` must read back to the same content.

use std::fmt::Write as _;

use vestnav_device::route_file::{DEMO_GPX, Track, parse_gpx, parse_gpx_bytes, to_gpx};

use crate::harness::{self, Counts, Known, Rng, add, bump};
use crate::mutate::{EXTREME_NUMBERS, mutate};

fn coordinate(rng: &mut Rng, lat: bool) -> String {
    if rng.chance(0.02) {
        (*rng.pick(EXTREME_NUMBERS)).to_owned()
    } else {
        let span = if lat { 180.0 } else { 360.0 };
        format!("{}", (rng.next_u64() as f64 / u64::MAX as f64 - 0.5) * span)
    }
}

fn name(rng: &mut Rng) -> String {
    match rng.below(40) {
        0 => "N".repeat(rng.size(200_000)),
        1 => "&amp;&lt;&gt;&quot;&#x1F600;".to_owned(),
        2 => "\u{202e}évènement 東京 \u{fffd}".to_owned(),
        3 => "<![CDATA[<rtept lat=\"1\" lon=\"2\"/>]]>".to_owned(),
        4 => "  padded  ".to_owned(),
        5 => String::new(),
        _ => format!("P{}", rng.below(1000)),
    }
}

fn point(rng: &mut Rng, tag: &str, out: &mut String) {
    let _ = write!(out, "<{tag} lat=\"{}\" lon=\"{}\">", coordinate(rng, true), coordinate(rng, false));
    if rng.chance(0.5) {
        let _ = write!(out, "<ele>{}</ele>", coordinate(rng, true));
    }
    if rng.chance(0.3) {
        let t = rng.pick(&[
            "2026-11-22T18:00:12Z",
            "2026-11-22T18:00:12.123456789Z",
            "9999-12-31T23:59:59Z",
            "yesterday",
        ]);
        let _ = write!(out, "<time>{t}</time>");
    }
    if rng.chance(0.5) {
        let _ = write!(out, "<name>{}</name>", name(rng));
    }
    let _ = write!(out, "</{tag}>");
}

fn generated(rng: &mut Rng) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<gpx version=\"1.1\" creator=\"fuzz\" \
         xmlns=\"http://www.topografix.com/GPX/1/1\">\n",
    );
    if rng.chance(0.5) {
        let _ = write!(s, "<metadata><name>{}</name></metadata>", name(rng));
    }
    for _ in 0..rng.size(20) {
        point(rng, "wpt", &mut s);
    }
    for _ in 0..rng.size(3) {
        let _ = write!(s, "<rte><name>{}</name>", name(rng));
        for _ in 0..rng.size(if harness::long_run() { 20_000 } else { 200 }) {
            point(rng, "rtept", &mut s);
        }
        s.push_str("</rte>");
    }
    for _ in 0..rng.size(3) {
        s.push_str("<trk>");
        for _ in 0..rng.size(3) {
            s.push_str("<trkseg>");
            for _ in 0..rng.size(100) {
                point(rng, "trkpt", &mut s);
            }
            s.push_str("</trkseg>");
        }
        s.push_str("</trk>");
    }
    if rng.chance(0.1) {
        // Kept below 5000: deeper nesting is quadratic in the reader (see `deep_nesting_costs_linear_time`).
        let depth = rng.size(5000);
        s.push_str("<extensions>");
        for _ in 0..depth {
            s.push_str("<x>");
        }
        for _ in 0..depth {
            s.push_str("</x>");
        }
        s.push_str("</extensions>");
    }
    if rng.chance(0.05) {
        // Entity expansion ("billion laughs").
        s.insert_str(
            s.find("<gpx").unwrap_or(0),
            "<!DOCTYPE gpx [<!ENTITY a \"aaaaaaaaaa\"><!ENTITY b \"&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;\">\
             <!ENTITY c \"&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;\"><!ENTITY d \"&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;\">]>",
        );
        s.push_str("<wpt lat=\"1\" lon=\"1\"><name>&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;</name></wpt>");
    }
    s.push_str("</gpx>\n");
    s
}

fn generate(rng: &mut Rng) -> Vec<u8> {
    let mut data = if rng.chance(0.3) { DEMO_GPX.as_bytes().to_vec() } else { generated(rng).into_bytes() };
    if rng.chance(0.5) {
        let rounds = 1 + rng.size(4);
        mutate(rng, &mut data, &[DEMO_GPX.as_bytes()], rounds, 8 << 20);
    }
    data
}

/// Rough element nesting depth: opening tags minus closing tags, at the deepest point.
fn nesting_depth(input: &[u8]) -> usize {
    let (mut depth, mut max) = (0usize, 0usize);
    for (i, w) in input.windows(2).enumerate() {
        if w[0] != b'<' {
            continue;
        }
        if w[1] == b'/' {
            depth = depth.saturating_sub(1);
        } else if w[1].is_ascii_alphabetic() {
            let self_closing = input[i..]
                .iter()
                .take(4096)
                .position(|&b| b == b'>')
                .is_some_and(|e| input[i + e - 1] == b'/');
            if !self_closing {
                depth += 1;
                max = max.max(depth);
            }
        }
    }
    max
}

fn check(input: &[u8], counts: &mut Counts) -> Result<(), String> {
    bump(counts, "inputs");
    if nesting_depth(input) > vestnav_device::route_file::MAX_GPX_DEPTH {
        bump(counts, "deeper than the reader accepts");
    }
    let file = match parse_gpx_bytes(input) {
        Ok(f) => f,
        Err(e) => {
            let msg = e.to_string();
            if msg.is_empty() || msg.len() > 4096 {
                return Err(format!("unbounded error message: {} bytes", msg.len()));
            }
            bump(counts, "errors");
            return Ok(());
        }
    };
    bump(counts, "parsed");
    let mut points = 0usize;
    let ok = |lat: f64, lon: f64| {
        lat.is_finite() && lon.is_finite() && (-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon)
    };
    for w in file.waypoints.iter().chain(file.routes.iter().flat_map(|r| r.points.iter())) {
        points += 1;
        if !ok(w.lat_deg, w.lon_deg) {
            return Err(format!("invalid waypoint accepted: {} {}", w.lat_deg, w.lon_deg));
        }
    }
    for p in file.tracks.iter().flat_map(Track::points) {
        points += 1;
        if !ok(p.lat_deg, p.lon_deg) || p.ele_m.is_some_and(|e| !e.is_finite()) {
            return Err(format!("invalid track point accepted: {} {} {:?}", p.lat_deg, p.lon_deg, p.ele_m));
        }
    }
    if points > input.len() / 16 + 1 {
        return Err(format!("more points ({points}) than the input can hold"));
    }
    if file.default_route().is_some() == file.is_empty() {
        return Err("default_route disagrees with is_empty".into());
    }
    add(counts, "points", points as u64);
    let text = to_gpx(&file);
    match parse_gpx(&text) {
        Ok(back) if back == file => Ok(()),
        Ok(back) => Err(format!(
            "write-read round trip changes the file: {}",
            first_difference(&format!("{file:?}"), &format!("{back:?}"))
        )),
        Err(e) => Err(format!("write-read round trip fails to parse: {e}")),
    }
}

fn first_difference(a: &str, b: &str) -> String {
    let i = a.bytes().zip(b.bytes()).position(|(x, y)| x != y).unwrap_or(a.len().min(b.len()));
    let from = i.saturating_sub(40);
    let get = |s: &str| s.get(from..(i + 60).min(s.len())).unwrap_or("").to_owned();
    format!("read {:?} / reread {:?}", get(a), get(b))
}

const KNOWN: &[Known] = &[];

#[test]
fn gpx_reader_survives_mutated_and_hostile_files() {
    harness::fuzz("gpx", 1500, KNOWN, generate, check);
}

/// The reproducer of the known issue above; passes once the error quotes a bounded part of the value.
#[test]
fn a_huge_coordinate_gives_a_short_error() {
    let text = format!(
        "<?xml version=\"1.0\"?><gpx version=\"1.1\" creator=\"x\" xmlns=\"http://www.topografix.com/GPX/1/1\">\
         <rte><rtept lat=\"{}\" lon=\"1\"/></rte></gpx>",
        "9x".repeat(100_000)
    );
    let msg = parse_gpx(&text).unwrap_err().to_string();
    assert!(msg.len() < 4096, "{} bytes of error message", msg.len());
}

fn nested(depth: usize) -> String {
    format!(
        "<?xml version=\"1.0\"?><gpx version=\"1.1\" creator=\"x\" xmlns=\"http://www.topografix.com/GPX/1/1\">\
         <wpt lat=\"1\" lon=\"1\"/><extensions>{}{}</extensions></gpx>",
        "<x>".repeat(depth),
        "</x>".repeat(depth)
    )
}

/// Deeply nested elements must cost time linear in the file: 40 000 levels is a 280 kB file, far under
/// the 50 MB limit, and must not take much more than twice 20 000 levels.
#[test]
fn deep_nesting_costs_linear_time() {
    let time = |depth: usize| {
        let text = nested(depth);
        let start = std::time::Instant::now();
        let _ = parse_gpx(&text);
        start.elapsed()
    };
    let (small, large) = (time(20_000), time(40_000));
    eprintln!("GPX nesting: 20 000 levels {small:?}, 40 000 levels {large:?}");
    assert!(large < small * 3 + std::time::Duration::from_millis(50), "{small:?} -> {large:?}");
}
