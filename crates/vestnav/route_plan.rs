//! `vestnav route plan` (a walking route along an OpenStreetMap extract's paths, to GPX or JSON) and
//! `vestnav map render` (the extract drawn offline into a PNG). Both are thin: the reading, the planning and
//! the drawing are `vestnav-osm`'s.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::RoutePath;
use vestnav_device::route_file::{RouteFile, Waypoint, write_gpx};
use vestnav_osm::tile::{TILE_SIZE, TileId, mercator_from_wgs84};
use vestnav_osm::{ATTRIBUTION, Extract, Profile, Renderer, Route};

/// How the planner weighs ways, on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum ProfileArg {
    /// The shortest walk.
    #[default]
    Shortest,
    /// Steps weigh 20 times their length.
    AvoidSteps,
    /// Streets weigh 1.5 times their length, main roads twice: footways preferred.
    PreferFootways,
}

impl From<ProfileArg> for Profile {
    fn from(p: ProfileArg) -> Self {
        match p {
            ProfileArg::Shortest => Self::Shortest,
            ProfileArg::AvoidSteps => Self::AvoidSteps,
            ProfileArg::PreferFootways => Self::PreferFootways,
        }
    }
}

fn parse_point(s: &str) -> Result<LatLon, String> {
    vestnav_core::coords::parse_position(s)
}

/// `vestnav route plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// The OpenStreetMap extract (.osm.pbf).
    #[arg(long, value_name = "AREA.osm.pbf")]
    pub osm: PathBuf,
    /// Start: "lat,lon" in decimal degrees (also DMS, UTM or MGRS).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub from: LatLon,
    /// Goal, like --from.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub to: LatLon,
    /// A point to pass on the way (repeat for several, in order).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub via: Vec<LatLon>,
    /// How ways are weighed.
    #[arg(long, value_enum, default_value = "shortest")]
    pub profile: ProfileArg,
    /// Write the walk as GPX 1.1: the points planned through as the route (`<rte>`: Start, Via 1, …, Goal,
    /// each where the walk passes it) and the path along the ways as a track (`<trk>` "path", one point per
    /// node), which `nav simulate --route` and the console read back as a route following that path.
    #[arg(long, value_name = "FILE.gpx")]
    pub gpx: Option<PathBuf>,
    /// Print one JSON object (points, length, ways, timings) instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// `vestnav map render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The OpenStreetMap extract (.osm.pbf).
    #[arg(long, value_name = "AREA.osm.pbf")]
    pub osm: PathBuf,
    /// Centre of the image: "lat,lon" (default: the centre of the extract).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub center: Option<LatLon>,
    /// Zoom level (14-19 are the legible ones).
    #[arg(long, default_value_t = 17, value_parser = clap::value_parser!(u8).range(0..=22))]
    pub zoom: u8,
    /// Image width [px].
    #[arg(long, default_value_t = 768, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub width: u32,
    /// Image height [px].
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub height: u32,
    /// Draw this route (a GPX file, e.g. from `route plan --gpx`) over the map.
    #[arg(long, value_name = "FILE.gpx")]
    pub route: Option<PathBuf>,
    /// The PNG to write.
    #[arg(long, value_name = "FILE.png")]
    pub png: PathBuf,
}

fn load(path: &Path) -> anyhow::Result<(Extract, f64)> {
    let t0 = Instant::now();
    let extract = Extract::read(path)?;
    Ok((extract, t0.elapsed().as_secs_f64()))
}

/// The points a walk was planned through as its waypoints, where it passes them: `Start`, `Via 1`, …,
/// `Goal`; and its path.
pub fn planned_waypoints(route: &Route, points: &[LatLon]) -> anyhow::Result<(Vec<Waypoint>, RoutePath)> {
    let n = points.len();
    let named: Vec<Waypoint> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let name = match i {
                0 => "Start".to_owned(),
                i if i + 1 == n => "Goal".to_owned(),
                i => format!("Via {i}"),
            };
            Waypoint::at(name, *p)
        })
        .collect();
    Ok(route.guided(&named)?)
}

/// "Follow paths": the route through `waypoints` planned leg by leg along the extract's paths: the same
/// waypoints (names and radii kept) moved onto the paths where the walk passes them, and the path.
pub fn follow_paths(
    osm: &Path,
    waypoints: &[Waypoint],
    profile: Profile,
) -> anyhow::Result<(Vec<Waypoint>, RoutePath)> {
    if waypoints.len() < 2 {
        bail!("--osm needs a route of at least two points");
    }
    let (extract, _) = load(osm)?;
    let points: Vec<LatLon> = waypoints.iter().map(Waypoint::pos).collect();
    let route = extract
        .graph
        .plan_via(&points, profile)
        .with_context(|| format!("{}: following the route's paths", osm.display()))?;
    Ok(route.guided(waypoints)?)
}

/// Runs `vestnav route plan`.
#[allow(clippy::print_stdout)]
pub fn run_plan(args: &PlanArgs) -> anyhow::Result<()> {
    let (extract, load_s) = load(&args.osm)?;
    let mut points = vec![args.from];
    points.extend(&args.via);
    points.push(args.to);
    let t0 = Instant::now();
    let route = extract
        .graph
        .plan_via(&points, args.profile.into())
        .with_context(|| format!("planning on {}", args.osm.display()))?;
    let plan_s = t0.elapsed().as_secs_f64();
    let geodesic_m = Earth::Wgs84.distance_m(args.from, args.to);
    if let Some(path) = &args.gpx {
        let (waypoints, walk) = planned_waypoints(&route, &points)?;
        let file = RouteFile::with_path("Planned walk", waypoints, Some(&walk));
        write_gpx(path, &file).with_context(|| format!("writing {}", path.display()))?;
    }
    if args.json {
        let json = serde_json::json!({
            "extract": args.osm.display().to_string(),
            "profile": format!("{:?}", args.profile),
            "length_m": route.length_m,
            "cost_m": route.cost,
            "geodesic_m": geodesic_m,
            "from_snap_m": route.from_snap_m,
            "to_snap_m": route.to_snap_m,
            "points": route.points.iter().map(|p| [p.lat_deg, p.lon_deg]).collect::<Vec<_>>(),
            "ways": route.ways,
            "load_s": load_s,
            "plan_s": plan_s,
            "attribution": ATTRIBUTION,
        });
        println!("{json}");
    } else {
        println!(
            "{}: {} graph nodes, loaded in {load_s:.2} s",
            args.osm.display(),
            extract.graph.node_count()
        );
        println!(
            "route ({:?}): {:.0} m along {} ways, {} points (straight line {:.0} m; start {:.0} m and goal {:.0} m \
             from the nearest path), planned in {:.1} ms",
            args.profile,
            route.length_m,
            route.ways.len(),
            route.points.len(),
            geodesic_m,
            route.from_snap_m,
            route.to_snap_m,
            plan_s * 1e3
        );
        if let Some(path) = &args.gpx {
            println!("GPX: {}", path.display());
        }
        println!("map data {ATTRIBUTION}");
    }
    Ok(())
}

/// Runs `vestnav map render`.
#[allow(clippy::print_stdout)]
pub fn run_render(args: &RenderArgs) -> anyhow::Result<()> {
    let (extract, _) = load(&args.osm)?;
    let center = if let Some(c) = args.center {
        c
    } else {
        let Some((sw, ne)) = extract.map.bounds() else { bail!("{}: nothing to draw", args.osm.display()) };
        LatLon::new(f64::midpoint(sw.lat_deg, ne.lat_deg), f64::midpoint(sw.lon_deg, ne.lon_deg))
    };
    let route = match &args.route {
        Some(p) => match crate::nav::load_route(p)? {
            (_, Some(path)) => path.points().to_vec(),
            (waypoints, None) => waypoints.iter().map(Waypoint::pos).collect(),
        },
        None => Vec::new(),
    };
    let renderer = Renderer::new(Arc::new(extract.map));
    let mut image = tiny_skia::Pixmap::new(args.width, args.height).context("allocating the image")?;
    // World pixel of the image's top-left corner at this zoom.
    let world_px = f64::from(TILE_SIZE) * f64::from(1u32 << args.zoom);
    let c = mercator_from_wgs84(center) * world_px;
    let (left, top) = (c.x - f64::from(args.width) / 2.0, c.y - f64::from(args.height) / 2.0);
    let tile_px = f64::from(TILE_SIZE);
    let (tx0, ty0) = ((left / tile_px).floor() as i64, (top / tile_px).floor() as i64);
    let (tx1, ty1) = (
        ((left + f64::from(args.width)) / tile_px).floor() as i64,
        ((top + f64::from(args.height)) / tile_px).floor() as i64,
    );
    for ty in ty0..=ty1 {
        for tx in tx0..=tx1 {
            let id = u32::try_from(tx)
                .ok()
                .zip(u32::try_from(ty).ok())
                .and_then(|(x, y)| TileId::new(args.zoom, x, y));
            let Some(id) = id else { continue };
            let tile = renderer.tile(id);
            let mut pm = tiny_skia::Pixmap::new(TILE_SIZE, TILE_SIZE).context("allocating a tile")?;
            for (dst, src) in pm.pixels_mut().iter_mut().zip(tile.rgba.chunks_exact(4)) {
                *dst = tiny_skia::ColorU8::from_rgba(src[0], src[1], src[2], src[3]).premultiply();
            }
            let (x, y) =
                ((tx as f64 * tile_px - left).round() as i32, (ty as f64 * tile_px - top).round() as i32);
            image.draw_pixmap(
                x,
                y,
                pm.as_ref(),
                &tiny_skia::PixmapPaint::default(),
                tiny_skia::Transform::identity(),
                None,
            );
        }
    }
    if route.len() >= 2 {
        let mut pb = tiny_skia::PathBuilder::new();
        for (i, p) in route.iter().enumerate() {
            let m = mercator_from_wgs84(*p) * world_px;
            let (x, y) = ((m.x - left) as f32, (m.y - top) as f32);
            if i == 0 { pb.move_to(x, y) } else { pb.line_to(x, y) }
        }
        if let Some(path) = pb.finish() {
            let mut paint = tiny_skia::Paint { anti_alias: true, ..tiny_skia::Paint::default() };
            paint.set_color_rgba8(20, 90, 220, 200);
            let stroke = tiny_skia::Stroke {
                width: 4.0,
                line_join: tiny_skia::LineJoin::Round,
                ..tiny_skia::Stroke::default()
            };
            image.stroke_path(&path, &paint, &stroke, tiny_skia::Transform::identity(), None);
        }
    }
    let w = vestnav_plot::label_width(ATTRIBUTION, 11.0);
    vestnav_plot::draw_label(
        &mut image,
        ATTRIBUTION,
        args.width as f32 - w / 2.0 - 6.0,
        args.height as f32 - 10.0,
        11.0,
        vestnav_plot::Color::rgb(40, 40, 40),
        2.0,
    );
    let png = image.encode_png().context("encoding the PNG")?;
    vestnav_files::write_atomic(&args.png, &png)
        .with_context(|| format!("writing {}", args.png.display()))?;
    println!(
        "{}: zoom {} around {:.6}, {:.6}",
        args.png.display(),
        args.zoom,
        center.lat_deg,
        center.lon_deg
    );
    Ok(())
}
