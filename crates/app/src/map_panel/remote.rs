//! The wearers of remote stations (`vestnav --broker`) on the console's map: each in its own colour with
//! its name and last contact, its recent track and its route — along the route's path when the station
//! sent one, drawn as this console's own path is ([`super::route_line`]: passed, ahead, the rest, in the
//! station's colour; all remote paths together within one budget of points a frame), else as dashed
//! straight legs. What is drawn comes from what the station
//! last published and when it arrived: a station out of contact, or whose fix is old, is drawn hollow and
//! grey with its age ("last known").

use std::fmt::Write as _;
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{Color32, Pos2, Stroke, vec2};
use vestnav_core::guidance::RoutePath;
use vestnav_remote::StationView;
use vestnav_remote::wire::RouteMsg;
use walkers::{Projector, lat_lon};

/// Colours given to stations by name (a station keeps its colour across runs and window orders).
const PALETTE: [Color32; 8] = [
    Color32::from_rgb(0, 150, 136),
    Color32::from_rgb(156, 39, 176),
    Color32::from_rgb(255, 87, 34),
    Color32::from_rgb(63, 81, 181),
    Color32::from_rgb(139, 195, 74),
    Color32::from_rgb(233, 30, 99),
    Color32::from_rgb(121, 85, 72),
    Color32::from_rgb(0, 188, 212),
];
/// Grey for a position that is no longer current.
const STALE_GREY: Color32 = Color32::from_gray(140);

/// One remote wearer as the map draws it.
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteWearer {
    /// The station's name.
    pub name: String,
    /// Its colour.
    pub colour: Color32,
    /// Its last position `(lat, lon)` [deg], if it ever reported one.
    pub position: Option<(f64, f64)>,
    /// The position is not current: no contact within the fleet's bound, offline, or the fix is old.
    pub stale: bool,
    /// The label beside the marker: name and contact ("alpha · 0.4 s ago", "alpha · no contact 12 s").
    pub label: String,
    /// Its recent track, oldest first.
    pub track: Vec<(f64, f64)>,
    /// Its route's waypoints and the next one's index.
    pub route: Vec<(f64, f64)>,
    /// Index of the next waypoint in `route`.
    pub next: usize,
    /// The station's route message, shared with the station's view (never copied: its path may hold
    /// 40,000 points); [`Self::path`] is the path the route follows, when the message carried it.
    pub route_msg: Option<Arc<RouteMsg>>,
    /// How many points the station's path has (0: straight legs); more than the path carried when the
    /// station's path was too long for the broker (the label says it is not shown).
    pub path_points: usize,
}

/// A stable colour for `name` (FNV-1a over its bytes).
pub fn colour_of(name: &str) -> Color32 {
    let h = name
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    PALETTE[(h % PALETTE.len() as u64) as usize]
}

impl RemoteWearer {
    /// The wearer of station `v` at `now`: stale when silent for longer than `stale_after` (or offline),
    /// or when its fix is older than `fix_stale_s`. Takes the view (its route message is shared, uncopied).
    pub fn from_view(v: StationView, now: Instant, stale_after: Duration, fix_stale_s: f64) -> Self {
        let snapshot = v.state.as_ref().map(|s| &s.station);
        let position = snapshot
            .and_then(|s| s.fix.as_ref())
            .and_then(|f| f.lat_deg.zip(f.lon_deg))
            .filter(|(la, lo)| la.is_finite() && lo.is_finite());
        let offline = v.hello.as_ref().is_some_and(|h| !h.online);
        let fix_age = snapshot.and_then(|s| s.fix_age_s);
        let old_fix = fix_age.is_none_or(|a| a.is_nan() || a > fix_stale_s);
        let stale = offline || v.is_stale(now, stale_after) || old_fix;
        let mut label = format!("{} · {}", v.name, v.contact_label(now, stale_after));
        if offline {
            label.push_str(" · offline");
        }
        if let (Some(a), true) = (fix_age, old_fix) {
            let _ = write!(label, " · fix {a:.0} s old");
        }
        let (route, next, path_points) = v.route.as_ref().map_or_else(Default::default, |r| {
            (r.waypoints.iter().map(|w| (w.lat_deg, w.lon_deg)).collect(), r.next, r.path_points)
        });
        if v.route.as_ref().is_some_and(|r| r.path.is_none()) && path_points > 0 {
            let _ = write!(label, " · its path of {path_points} points not shown (too long for the broker)");
        }
        Self {
            colour: colour_of(&v.name),
            name: v.name,
            position,
            stale,
            label,
            track: v.track.into_iter().collect(),
            route,
            next,
            route_msg: v.route,
            path_points,
        }
    }

    /// The path its route follows, when the station's route message carried it.
    pub fn path(&self) -> Option<&RoutePath> {
        self.route_msg.as_ref()?.path.as_ref()
    }
}

/// Draws `wearers` (their routes, tracks, then markers and labels).
pub(super) fn draw(painter: &egui::Painter, projector: &Projector, wearers: &[RemoteWearer], ui: &egui::Ui) {
    let project = |(la, lo): (f64, f64)| {
        let v = projector.project(lat_lon(la, lo));
        Pos2::new(v.x, v.y)
    };
    // The remote paths share one budget of points, so the frame stays bounded whatever the stations send.
    let with_path = wearers.iter().filter(|w| w.path().is_some()).count();
    let budget = super::route_line::PATH_DRAWN_MAX / with_path.max(1);
    for w in wearers {
        let pts: Vec<Pos2> = w.route.iter().copied().map(project).collect();
        if let Some(path) = w.path() {
            let style = super::route_line::PathStyle::remote(w.colour);
            super::route_line::draw(painter, projector, path, w.next, &style, budget);
        } else if pts.len() >= 2 {
            painter.add(egui::Shape::dashed_line(
                &pts,
                Stroke::new(2.0, w.colour.gamma_multiply(0.7)),
                8.0,
                5.0,
            ));
        }
        for (i, p) in pts.iter().enumerate() {
            let r = if i == w.next { 5.0 } else { 3.5 };
            painter.circle(*p, r, w.colour.gamma_multiply(0.5), Stroke::new(1.0, w.colour));
        }
        let track: Vec<Pos2> = w.track.iter().copied().map(project).collect();
        if track.len() >= 2 {
            painter.line(track, Stroke::new(2.0, w.colour));
        }
    }
    let font = egui::FontId::proportional(12.0);
    for w in wearers {
        let Some(p) = w.position.map(project) else { continue };
        if w.stale {
            // Hollow and grey: where the wearer was, not where they are.
            painter.circle_stroke(p, 7.0, Stroke::new(2.5, STALE_GREY));
        } else {
            painter.circle(p, 7.0, w.colour, Stroke::new(2.0, Color32::WHITE));
        }
        let text = if w.stale { format!("{} (last known)", w.label) } else { w.label.clone() };
        super::paint::halo_text(
            painter,
            p + vec2(10.0, -10.0),
            egui::Align2::LEFT_BOTTOM,
            text,
            font.clone(),
            if w.stale { STALE_GREY } else { ui.visuals().strong_text_color() },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_remote::wire::Hello;

    #[test]
    fn silent_offline_or_positionless_wearers_are_stale_and_say_why() {
        let now = Instant::now();
        let v = StationView {
            name: "alpha".into(),
            last_contact: Some(now.checked_sub(Duration::from_secs(9)).unwrap()),
            ..StationView::default()
        };
        let w = RemoteWearer::from_view(v.clone(), now, Duration::from_secs(2), 5.0);
        assert!(w.stale);
        assert_eq!(w.position, None);
        assert!(w.label.contains("no contact 9 s"), "{}", w.label);
        let off = StationView {
            last_contact: Some(now),
            hello: Some(Hello {
                name: "alpha".into(),
                online: false,
                schema: "v1".into(),
                link_bound_s: 3.0,
            }),
            ..v
        };
        let w = RemoteWearer::from_view(off, now, Duration::from_secs(2), 5.0);
        assert!(w.stale && w.label.ends_with("offline"), "{}", w.label);
        assert_eq!(colour_of("alpha"), w.colour, "a station keeps its colour");
    }
}
