//! `vestnav tiles prefetch`: the console's "Make this area available offline", headless. The checks, the
//! download workers and the writers are the console's own (`vestnav_tiles::prefetch`, no GUI linked for
//! them); this file only turns the command line into a `PrefetchRequest` and reports progress on stderr.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, bail};
use clap::Args;
use vestnav_tiles::prefetch::{
    self, DEFAULT_PARALLELISM, MAX_PARALLELISM, Prefetch, PrefetchRequest, PrefetchTarget, Snapshot,
};
use vestnav_tiles::{BBox, MAX_ZOOM, TileSourceConfig, cache, parse_tiles_spec, redact_url, url_host};

/// `vestnav tiles prefetch`.
#[derive(Debug, Args)]
pub struct PrefetchArgs {
    /// The XYZ tile server: a URL template with {z}, {x}, {y} (an API key may be in the query). The public
    /// OpenStreetMap server (`osm`) is refused: its usage policy forbids bulk download.
    #[arg(long, value_name = "URL_TEMPLATE")]
    pub source: String,
    /// Confirms that the source's terms allow bulk/offline download (the console's "terms allow bulk
    /// download" tick); required.
    #[arg(long)]
    pub allow_bulk: bool,
    /// Attribution the provider requires, written into an MBTiles file's metadata.
    #[arg(long, value_name = "TEXT")]
    pub attribution: Option<String>,
    /// The area: the box around every point of this GPX file (waypoints, routes, tracks).
    #[arg(long, value_name = "FILE.gpx", conflicts_with = "bbox", required_unless_present = "bbox")]
    pub route: Option<PathBuf>,
    /// The area: south,west,north,east [deg].
    #[arg(long, value_name = "S,W,N,E", value_parser = parse_bbox, allow_hyphen_values = true)]
    pub bbox: Option<BBox>,
    /// Margin added around the area on every side [m].
    #[arg(long, value_name = "M", default_value_t = 300.0)]
    pub margin_m: f64,
    /// Zoom levels: MIN-MAX, or one level.
    #[arg(long, value_name = "MIN-MAX", value_parser = parse_zoom)]
    pub zoom: (u8, u8),
    /// Parallel downloads (1-8).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_PARALLELISM)]
    pub parallel: usize,
    /// Where the tiles go: FILE.mbtiles (created, or resumed), or a tile cache folder (the console's
    /// `tile_cache_dir`; default: the platform's, where the console looks).
    #[arg(long, value_name = "DIR|FILE.mbtiles")]
    pub out: Option<PathBuf>,
    /// Print the tile count and size estimate only; download nothing.
    #[arg(long)]
    pub dry_run: bool,
}

fn parse_bbox(s: &str) -> Result<BBox, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: expected S,W,N,E in degrees ({e})"))?;
    let [s_, w, n, e] = v[..] else { return Err(format!("{s:?}: expected four numbers S,W,N,E")) };
    if !(-90.0..=90.0).contains(&s_) || !(-90.0..=90.0).contains(&n) || s_ > n {
        return Err(format!("{s:?}: latitudes must satisfy -90 <= S <= N <= 90"));
    }
    if !(-180.0..=180.0).contains(&w) || !(-180.0..=180.0).contains(&e) || w > e {
        return Err(format!("{s:?}: longitudes must satisfy -180 <= W <= E <= 180"));
    }
    Ok(BBox { min_lat: s_, min_lon: w, max_lat: n, max_lon: e })
}

fn parse_zoom(s: &str) -> Result<(u8, u8), String> {
    let z = |p: &str| {
        p.trim()
            .parse::<u8>()
            .ok()
            .filter(|z| *z <= MAX_ZOOM)
            .ok_or_else(|| format!("{s:?}: zoom must be 0-{MAX_ZOOM}"))
    };
    let (a, b) = match s.split_once('-') {
        Some((a, b)) => (z(a)?, z(b)?),
        None => (z(s)?, z(s)?),
    };
    if a > b {
        return Err(format!("{s:?}: MIN must not exceed MAX"));
    }
    Ok((a, b))
}

fn mb(bytes: u64) -> String {
    format!("{:.1} MB", bytes as f64 / 1e6)
}

/// The request the arguments describe; refused here exactly as the console refuses it.
fn request(args: &PrefetchArgs) -> anyhow::Result<PrefetchRequest> {
    let source = match parse_tiles_spec(&args.source).map_err(anyhow::Error::msg)? {
        TileSourceConfig::Xyz { url, attribution, .. } => TileSourceConfig::Xyz {
            attribution: args.attribution.clone().unwrap_or(attribution),
            url,
            allows_bulk: args.allow_bulk,
        },
        other => other,
    };
    if let Err(why) = source.bulk_download_allowed() {
        let hint = if matches!(source, TileSourceConfig::Xyz { allows_bulk: false, .. }) {
            " On the command line that is --allow-bulk."
        } else {
            ""
        };
        bail!("{}: {why}{hint}", source.url_template().map_or_else(|| args.source.clone(), redact_url));
    }
    if !(args.margin_m.is_finite() && (0.0..=100_000.0).contains(&args.margin_m)) {
        bail!("--margin-m must be between 0 and 100000");
    }
    if !(1..=MAX_PARALLELISM).contains(&args.parallel) {
        bail!("--parallel must be between 1 and {MAX_PARALLELISM}");
    }
    let bbox = match (&args.route, &args.bbox) {
        (Some(path), _) => {
            let f = vestnav_device::route_file::read_gpx(path)?;
            let points = f
                .waypoints
                .iter()
                .chain(f.routes.iter().flat_map(|r| r.points.iter()))
                .map(|w| (w.lat_deg, w.lon_deg))
                .chain(f.tracks.iter().flat_map(|t| t.points().map(|p| (p.lat_deg, p.lon_deg))))
                .collect::<Vec<_>>();
            BBox::around(points, args.margin_m).with_context(|| format!("{}: no points", path.display()))?
        }
        (None, Some(b)) => BBox::around([(b.min_lat, b.min_lon), (b.max_lat, b.max_lon)], args.margin_m)
            .context("the box is empty")?,
        (None, None) => bail!("give the area: --route FILE.gpx or --bbox S,W,N,E"),
    };
    let target = PrefetchTarget::from_path(args.out.clone().unwrap_or_else(cache::default_root));
    Ok(PrefetchRequest { source, bbox, z0: args.zoom.0, z1: args.zoom.1, parallelism: args.parallel, target })
}

fn progress_line(s: &Snapshot) -> String {
    format!(
        "{}/{} tiles: {} downloaded ({}), {} already there, {} absent on the server, {} failed",
        s.done(),
        s.total,
        s.fetched,
        mb(s.bytes),
        s.skipped,
        s.missing,
        s.failed
    )
}

/// Runs `vestnav tiles prefetch`.
#[allow(clippy::print_stdout)]
pub fn run_prefetch(args: &PrefetchArgs) -> anyhow::Result<()> {
    let req = request(args)?;
    let est = prefetch::estimate(&req.bbox, req.z0, req.z1);
    let where_to = match &req.target {
        PrefetchTarget::MbTiles(p) => format!("MBTiles file {}", p.display()),
        PrefetchTarget::Cache(root) => {
            format!("tile cache {}", cache::source_dir(root, &req.source).display())
        }
    };
    let line = format!(
        "{} tiles at zooms {}-{} from {}, about {} (estimated at {} kB a tile), into the {where_to}",
        est.tiles,
        req.z0,
        req.z1,
        req.source.url_template().map_or_else(String::new, |u| url_host(u).to_owned()),
        mb(est.bytes),
        prefetch::EST_TILE_BYTES / 1000
    );
    if args.dry_run {
        println!("{line}");
        return Ok(());
    }
    eprintln!("{line}");
    let job = Prefetch::start(&req, None).map_err(anyhow::Error::msg)?;
    let mut last = String::new();
    let s = loop {
        let s = job.snapshot();
        if s.finished {
            break job.join();
        }
        let now = progress_line(&s);
        if now != last {
            eprint!("\r{now}");
            let _ = std::io::stderr().flush();
            last = now;
        }
        std::thread::sleep(Duration::from_millis(250));
    };
    eprintln!("\r{}", progress_line(&s));
    if let Some(e) = &s.last_error {
        eprintln!("last error: {e}");
    }
    if s.failed > 0 || s.done() < s.total {
        bail!("{} of {} tiles not stored", s.total - s.fetched - s.skipped - s.missing, s.total);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers() {
        assert_eq!(parse_zoom("12-16"), Ok((12, 16)));
        assert_eq!(parse_zoom("15"), Ok((15, 15)));
        assert!(parse_zoom("16-12").is_err() && parse_zoom("3-25").is_err());
        let b = parse_bbox("42.35,-71.11,42.36,-71.09").unwrap();
        assert_eq!((b.min_lat, b.min_lon, b.max_lat, b.max_lon), (42.35, -71.11, 42.36, -71.09));
        assert!(parse_bbox("42.36,-71.11,42.35,-71.09").is_err());
        assert!(parse_bbox("1,2,3").is_err());
    }
}
