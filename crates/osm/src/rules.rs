//! Who may walk where: the one reading of OpenStreetMap's tags for a pedestrian, and the classes the map
//! draws. Both the path graph and the renderer take their classes from here.
//!
//! The rules follow the OSM wiki's pages `Key:access`, `Key:foot`, `Key:highway`, `Key:sidewalk` and
//! `Key:barrier` (documented in `docs/map.md`, with the differences to pyroutelib3's stock foot profile):
//! - walkable `highway` values: footway, path, pedestrian, steps, `living_street`, residential, service,
//!   unclassified, tertiary, secondary, primary (and their `_link`s), track, bridleway, cycleway,
//!   corridor, platform (also `railway=platform` / `public_transport=platform` ways without `highway`);
//! - `motorway` and `motorway_link` are never walkable unless `foot=yes`/`designated`/`permissive`; `trunk`
//!   and `trunk_link` only with a sidewalk on the way (`sidewalk=both|left|right|yes`, or a
//!   `sidewalk:{both,left,right}=yes`) or an explicit foot permission; `motorroad=yes` is not walkable;
//! - access: the most specific tag decides (`foot`, else `access`); `no`, `private` and `use_sidepath`
//!   exclude, any other value allows;
//! - `oneway` is ignored: a pedestrian may walk both ways.
//! - a barrier node on a path blocks it when its own `foot`/`access` says `no`/`private`, when it is
//!   `locked=yes`, or when the barrier kind cannot be passed on foot (wall, fence, hedge, retaining wall,
//!   city wall, ditch); gates, bollards, stiles, turnstiles and the like can.

/// The tags of one OSM element, as read from the extract.
pub type Tags = [(String, String)];

/// The value of `key` in `tags`, if present.
pub fn tag<'a>(tags: &'a Tags, key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

/// The kind of path a pedestrian walks on: what profiles weigh and what the map draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum WayClass {
    /// `highway=motorway(_link)`.
    Motorway,
    /// `highway=trunk(_link)`.
    Trunk,
    /// `highway=primary(_link)`.
    Primary,
    /// `highway=secondary(_link)`.
    Secondary,
    /// `highway=tertiary(_link)`.
    Tertiary,
    /// `highway=unclassified|residential|road`.
    Minor,
    /// `highway=living_street`.
    LivingStreet,
    /// `highway=service`.
    Service,
    /// `highway=track`.
    Track,
    /// `highway=pedestrian`.
    Pedestrian,
    /// `highway=footway|path|bridleway|corridor|platform` (and platforms without `highway`).
    Footway,
    /// `highway=cycleway`.
    Cycleway,
    /// `highway=steps`.
    Steps,
}

impl WayClass {
    /// The class of a way's `highway` tag (platforms also from `railway`/`public_transport`), or `None` when
    /// it is not a path of any kind (construction, proposed, raceway, no `highway`).
    pub fn of(tags: &Tags) -> Option<Self> {
        let Some(highway) = tag(tags, "highway") else {
            let platform =
                tag(tags, "railway") == Some("platform") || tag(tags, "public_transport") == Some("platform");
            return platform.then_some(Self::Footway);
        };
        Some(match highway {
            "motorway" | "motorway_link" => Self::Motorway,
            "trunk" | "trunk_link" => Self::Trunk,
            "primary" | "primary_link" => Self::Primary,
            "secondary" | "secondary_link" => Self::Secondary,
            "tertiary" | "tertiary_link" => Self::Tertiary,
            "unclassified" | "residential" | "road" => Self::Minor,
            "living_street" => Self::LivingStreet,
            "service" => Self::Service,
            "track" => Self::Track,
            "pedestrian" => Self::Pedestrian,
            "footway" | "path" | "bridleway" | "corridor" | "platform" => Self::Footway,
            "cycleway" => Self::Cycleway,
            "steps" => Self::Steps,
            _ => return None,
        })
    }

    /// Whether this class is a way built for walking (what "prefer footways" prefers).
    pub fn is_footway(self) -> bool {
        matches!(
            self,
            Self::Footway
                | Self::Pedestrian
                | Self::Steps
                | Self::LivingStreet
                | Self::Track
                | Self::Cycleway
        )
    }
}

/// Access values that keep a pedestrian out.
fn denies(value: &str) -> bool {
    matches!(value, "no" | "private" | "use_sidepath")
}

/// Explicit foot permissions that open even a motorway or a trunk without sidewalk.
fn explicitly_allows(value: Option<&str>) -> bool {
    matches!(value, Some("yes" | "designated" | "permissive"))
}

/// Whether a way with a sidewalk tagged on it (not `separate`: then the sidewalk is its own way).
fn has_sidewalk(tags: &Tags) -> bool {
    matches!(tag(tags, "sidewalk"), Some("both" | "left" | "right" | "yes"))
        || ["sidewalk:both", "sidewalk:left", "sidewalk:right"].iter().any(|k| tag(tags, k) == Some("yes"))
}

/// The class of a way a pedestrian may walk, or `None` when it is not walkable (see the module doc).
pub fn walkable(tags: &Tags) -> Option<WayClass> {
    let class = WayClass::of(tags)?;
    if tag(tags, "area") == Some("yes") && class != WayClass::Pedestrian && class != WayClass::Footway {
        // An area of road surface (a square drawn as highway=service area=yes) has no path along its edge.
        return None;
    }
    let foot = tag(tags, "foot");
    if tag(tags, "motorroad") == Some("yes") && !explicitly_allows(foot) {
        return None;
    }
    match class {
        WayClass::Motorway if !explicitly_allows(foot) => return None,
        WayClass::Trunk if !explicitly_allows(foot) && !has_sidewalk(tags) => return None,
        _ => {}
    }
    let decisive = foot.or_else(|| tag(tags, "access"));
    if decisive.is_some_and(denies) {
        return None;
    }
    Some(class)
}

/// Barrier kinds nobody passes on foot, whatever their access tags say nothing about.
fn impassable_barrier(kind: &str) -> bool {
    matches!(kind, "wall" | "fence" | "hedge" | "retaining_wall" | "city_wall" | "ditch")
}

/// Whether a node stops a pedestrian: a barrier that is locked, denies foot access, or cannot be passed.
pub fn node_blocks(tags: &Tags) -> bool {
    let Some(barrier) = tag(tags, "barrier") else {
        return false;
    };
    let foot = tag(tags, "foot");
    if explicitly_allows(foot) {
        return false;
    }
    if tag(tags, "locked") == Some("yes") {
        return true;
    }
    let decisive = foot.or_else(|| tag(tags, "access"));
    if let Some(value) = decisive {
        return denies(value);
    }
    impassable_barrier(barrier)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
        pairs.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect()
    }

    #[test]
    fn access_rules_follow_the_wiki() {
        assert_eq!(walkable(&t(&[("highway", "footway")])), Some(WayClass::Footway));
        assert_eq!(walkable(&t(&[("highway", "footway"), ("access", "private")])), None);
        assert_eq!(walkable(&t(&[("highway", "footway"), ("foot", "no")])), None);
        // The more specific foot tag wins over access.
        assert_eq!(
            walkable(&t(&[("highway", "service"), ("access", "no"), ("foot", "yes")])),
            Some(WayClass::Service)
        );
        assert_eq!(
            walkable(&t(&[("highway", "residential"), ("access", "destination")])),
            Some(WayClass::Minor)
        );
        assert_eq!(walkable(&t(&[("highway", "cycleway"), ("foot", "use_sidepath")])), None);
        // Oneway means nothing on foot: the class is the same.
        assert_eq!(walkable(&t(&[("highway", "primary"), ("oneway", "yes")])), Some(WayClass::Primary));
        assert_eq!(walkable(&t(&[("highway", "motorway")])), None);
        assert_eq!(walkable(&t(&[("highway", "motorway_link"), ("foot", "yes")])), Some(WayClass::Motorway));
        assert_eq!(walkable(&t(&[("highway", "trunk")])), None);
        assert_eq!(walkable(&t(&[("highway", "trunk"), ("sidewalk", "separate")])), None);
        assert_eq!(walkable(&t(&[("highway", "trunk"), ("sidewalk", "both")])), Some(WayClass::Trunk));
        assert_eq!(walkable(&t(&[("highway", "trunk"), ("sidewalk:left", "yes")])), Some(WayClass::Trunk));
        assert_eq!(walkable(&t(&[("highway", "primary"), ("motorroad", "yes")])), None);
        assert_eq!(walkable(&t(&[("highway", "construction")])), None);
        assert_eq!(walkable(&t(&[("railway", "platform")])), Some(WayClass::Footway));
        assert_eq!(walkable(&t(&[("building", "yes")])), None);
        assert_eq!(walkable(&t(&[("highway", "service"), ("area", "yes")])), None);
        assert_eq!(walkable(&t(&[("highway", "pedestrian"), ("area", "yes")])), Some(WayClass::Pedestrian));
    }

    #[test]
    fn barriers_block_only_when_they_should() {
        assert!(!node_blocks(&t(&[("barrier", "bollard")])));
        assert!(!node_blocks(&t(&[("barrier", "gate")])));
        assert!(node_blocks(&t(&[("barrier", "gate"), ("access", "private")])));
        assert!(node_blocks(&t(&[("barrier", "gate"), ("locked", "yes")])));
        assert!(!node_blocks(&t(&[("barrier", "gate"), ("access", "no"), ("foot", "yes")])));
        assert!(node_blocks(&t(&[("barrier", "fence")])));
        assert!(!node_blocks(&t(&[("barrier", "fence"), ("foot", "yes")])));
        assert!(!node_blocks(&t(&[("highway", "crossing")])));
    }
}
