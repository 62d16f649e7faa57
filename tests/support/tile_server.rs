//! Test support shared by the tile tests of the console (`crates/app/tests/tiles.rs`) and of
//! `vestnav tiles prefetch` (`tests/integration/tiles_cli.rs`): a generated solid-colour PNG, a tile server
//! on 127.0.0.1 that counts what it is asked for (and can redirect, to itself or to another host), and the
//! tiles of a box by the closed-form slippy-map formulas. Each test crate includes this file with
//! `#[path]`.
#![allow(dead_code, clippy::unwrap_used)]

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A tile address: zoom, column, row (XYZ).
pub type Tile = (u8, u32, u32);

/// A 256×256 PNG of one colour.
pub fn solid_png(c: [u8; 3]) -> Vec<u8> {
    solid_png_sized(c, 256)
}

/// A real PNG whose IHDR declares `side`x`side` px: a 4x4 image's encoding with the IHDR's size and
/// CRC rewritten (the header of a decompression bomb; readers that trust it allocate side² pixels).
pub fn png_declaring(side: u32) -> Vec<u8> {
    let mut b = solid_png_sized([7, 7, 7], 4);
    assert_eq!(&b[12..16], b"IHDR");
    b[16..20].copy_from_slice(&side.to_be_bytes());
    b[20..24].copy_from_slice(&side.to_be_bytes());
    let crc = crc32(&b[12..29]);
    b[29..33].copy_from_slice(&crc.to_be_bytes());
    b
}

/// CRC-32 as PNG uses it (PNG 1.2 spec, annex D: polynomial 0xEDB88320 reflected, initial and final
/// value 0xFFFFFFFF), bit by bit.
fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &byte in data {
        c ^= u32::from(byte);
        for _ in 0..8 {
            c = if c & 1 == 1 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    c ^ 0xFFFF_FFFF
}

fn solid_png_sized(c: [u8; 3], side: u32) -> Vec<u8> {
    let img = image::RgbaImage::from_pixel(side, side, image::Rgba([c[0], c[1], c[2], 255]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A tile server on 127.0.0.1: answers `GET /{z}/{x}/{y}.png` with a generated PNG after `delay` (the
/// throttle), one request per connection; records every tile requested and the most requests in flight.
/// `GET /r/{z}/{x}/{y}.png` answers `302` to `/{z}/{x}/{y}.png` on the same server; a server started with
/// [`TileServer::redirecting`] answers every tile with `302` to the same path under another base URL.
pub struct TileServer {
    /// The address it listens on.
    pub ip: &'static str,
    /// The port it listens on.
    pub port: u16,
    /// Every tile requested, in order (recorded when the request arrives, before the throttle).
    pub requests: Arc<Mutex<Vec<Tile>>>,
    in_flight: Arc<AtomicUsize>,
    /// The most requests in flight at once.
    pub max_in_flight: Arc<AtomicUsize>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
    /// The PNG every tile request gets.
    pub png: Arc<Vec<u8>>,
}

impl TileServer {
    pub fn start(delay: Duration) -> Self {
        Self::start_on("127.0.0.1", delay, None)
    }

    /// A server on `ip` that sends every tile request to `base` (e.g. `http://127.0.0.2:PORT`) with a
    /// `302 Found`, recording the request first.
    pub fn redirecting(ip: &'static str, base: String) -> Self {
        Self::start_on(ip, Duration::ZERO, Some(base))
    }

    pub fn start_on(ip: &'static str, delay: Duration, redirect_to: Option<String>) -> Self {
        let listener = TcpListener::bind((ip, 0)).unwrap();
        listener.set_nonblocking(true).unwrap();
        let port = listener.local_addr().unwrap().port();
        let requests = Arc::new(Mutex::new(Vec::new()));
        let in_flight = Arc::new(AtomicUsize::new(0));
        let max_in_flight = Arc::new(AtomicUsize::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let png = Arc::new(solid_png([250, 160, 20]));
        let (rq, inf, mx, st, png2) =
            (requests.clone(), in_flight.clone(), max_in_flight.clone(), stop.clone(), png.clone());
        let thread = std::thread::spawn(move || {
            while !st.load(Ordering::SeqCst) {
                let Ok((stream, _)) = listener.accept() else {
                    std::thread::sleep(Duration::from_millis(1));
                    continue;
                };
                let (rq, inf, mx, png) = (rq.clone(), inf.clone(), mx.clone(), png2.clone());
                let redirect_to = redirect_to.clone();
                std::thread::spawn(move || {
                    stream.set_nonblocking(false).unwrap();
                    let mut reader = BufReader::new(stream.try_clone().unwrap());
                    let mut line = String::new();
                    if reader.read_line(&mut line).is_err() {
                        return;
                    }
                    let now = inf.fetch_add(1, Ordering::SeqCst) + 1;
                    mx.fetch_max(now, Ordering::SeqCst);
                    loop {
                        let mut h = String::new();
                        if reader.read_line(&mut h).map_or(true, |n| n == 0) || h == "\r\n" {
                            break;
                        }
                    }
                    let full = line.split_whitespace().nth(1).unwrap_or("").to_owned();
                    let path = full.split('?').next().unwrap_or("");
                    let same_host = path.strip_prefix("/r");
                    let path = same_host.unwrap_or(path);
                    let parts: Vec<&str> =
                        path.trim_start_matches('/').trim_end_matches(".png").split('/').collect();
                    let key: Option<Tile> = (parts.len() == 3)
                        .then(|| {
                            Some((parts[0].parse().ok()?, parts[1].parse().ok()?, parts[2].parse().ok()?))
                        })
                        .flatten();
                    if let Some(k) = key {
                        rq.lock().unwrap().push(k);
                    }
                    std::thread::sleep(delay);
                    let mut s = stream;
                    let location = match (&redirect_to, same_host) {
                        (Some(base), _) => Some(format!("{base}{full}")),
                        (None, Some(_)) => Some(full.trim_start_matches("/r").to_owned()),
                        (None, None) => None,
                    };
                    let _ = match key {
                        Some(_) if location.is_some() => {
                            let head = format!(
                                "HTTP/1.1 302 Found\r\nLocation: {}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                                location.unwrap_or_default()
                            );
                            s.write_all(head.as_bytes())
                        }
                        Some(_) => {
                            let head = format!(
                                "HTTP/1.1 200 OK\r\nContent-Type: image/png\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
                                png.len()
                            );
                            s.write_all(head.as_bytes()).and_then(|()| s.write_all(&png))
                        }
                        None => s.write_all(
                            b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                        ),
                    };
                    let _ = s.flush();
                    inf.fetch_sub(1, Ordering::SeqCst);
                });
            }
        });
        Self { ip, port, requests, in_flight, max_in_flight, stop, thread: Some(thread), png }
    }

    pub fn url(&self) -> String {
        format!("{}/{{z}}/{{x}}/{{y}}.png?key=SECRET", self.base())
    }

    /// `http://IP:PORT`.
    pub fn base(&self) -> String {
        format!("http://{}:{}", self.ip, self.port)
    }

    pub fn requested(&self) -> Vec<Tile> {
        self.requests.lock().unwrap().clone()
    }

    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            t.join().unwrap();
        }
        let t0 = Instant::now();
        while self.in_flight.load(Ordering::SeqCst) > 0 && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for TileServer {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The tiles of a box (S, W, N, E) over zooms `z0..=z1`, by the closed-form slippy-map formulas
/// (<https://wiki.openstreetmap.org/wiki/Slippy_map_tilenames>), written out here independently.
pub fn expected_tiles(s: f64, w: f64, n: f64, e: f64, z0: u8, z1: u8) -> BTreeSet<Tile> {
    let mut out = BTreeSet::new();
    for z in z0..=z1 {
        let k = f64::from(1u32 << z);
        let col = |lon: f64| (((lon + 180.0) / 360.0 * k).floor()).clamp(0.0, k - 1.0) as u32;
        let row = |lat: f64| {
            let r = lat.to_radians();
            (((1.0 - (r.tan() + 1.0 / r.cos()).ln() / std::f64::consts::PI) / 2.0 * k).floor())
                .clamp(0.0, k - 1.0) as u32
        };
        for x in col(w)..=col(e) {
            for y in row(n)..=row(s) {
                out.insert((z, x, y));
            }
        }
    }
    out
}
