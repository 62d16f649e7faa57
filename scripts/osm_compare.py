#!/usr/bin/env python3
"""Routes node pairs on an .osm.pbf extract with pyroutelib3, an independent router, for vestnav's planner
comparison (tests/integration/osm.rs).

Usage: osm_compare.py EXTRACT.osm.pbf < request.json > answer.json

request: {"pairs": [[from_node_id, to_node_id], ...], "ways": [way ids vestnav's routes used]}
answer:  {"routes": [[[lat, lon], ...] or [] when no route, ...],
          "forbidden_ways": [way ids from "ways" that this script's rules do not let a pedestrian use],
          "unknown_ways": [way ids from "ways" not in the extract]}

pyroutelib3 reads the extract, builds its own graph and runs its own A*. The walking rules it is given are
written here a second time from docs/map.md (not imported from vestnav), with every way's penalty 1 so both
routers look for the shortest walk:
- walkable highway values, motorway/trunk/sidewalk and motorroad rules, foot-over-access;
- oneway ignored (both directions);
- a barrier node that blocks cuts its ways, and a node missing from the extract cuts its way (pyroutelib3
  itself would join the nodes on either side of a missing node with a straight edge).
Lengths are not computed here: vestnav measures both routes' polylines with the same geodesic, so only the
choice of path is compared.
"""

import json
import sys

from pyroutelib3 import find_route
from pyroutelib3.osm import Graph, reader
from pyroutelib3.osm.profile import TurnRestriction

WALKABLE = {
    "motorway", "motorway_link", "trunk", "trunk_link", "primary", "primary_link", "secondary",
    "secondary_link", "tertiary", "tertiary_link", "unclassified", "residential", "road", "living_street",
    "service", "track", "pedestrian", "footway", "path", "bridleway", "corridor", "platform", "cycleway",
    "steps",
}
DENY = {"no", "private", "use_sidepath"}
ALLOW_EXPLICIT = {"yes", "designated", "permissive"}
SOLID_BARRIERS = {"wall", "fence", "hedge", "retaining_wall", "city_wall", "ditch"}


def way_allowed(tags):
    highway = tags.get("highway")
    if highway is None:
        if tags.get("railway") == "platform" or tags.get("public_transport") == "platform":
            highway = "platform"
        else:
            return False
    if highway not in WALKABLE:
        return False
    if tags.get("area") == "yes" and highway not in ("pedestrian", "footway", "path", "bridleway", "corridor", "platform"):
        return False
    foot = tags.get("foot")
    if tags.get("motorroad") == "yes" and foot not in ALLOW_EXPLICIT:
        return False
    if highway in ("motorway", "motorway_link") and foot not in ALLOW_EXPLICIT:
        return False
    if highway in ("trunk", "trunk_link") and foot not in ALLOW_EXPLICIT:
        sidewalk = tags.get("sidewalk") in ("both", "left", "right", "yes") or any(
            tags.get(k) == "yes" for k in ("sidewalk:both", "sidewalk:left", "sidewalk:right")
        )
        if not sidewalk:
            return False
    decisive = foot if foot is not None else tags.get("access")
    return decisive not in DENY


def node_blocks(tags):
    barrier = tags.get("barrier")
    if barrier is None:
        return False
    foot = tags.get("foot")
    if foot in ALLOW_EXPLICIT:
        return False
    if tags.get("locked") == "yes":
        return True
    decisive = foot if foot is not None else tags.get("access")
    if decisive is not None:
        return decisive in DENY
    return barrier in SOLID_BARRIERS


class ShortestWalk:
    """A pyroutelib3 profile: every allowed way at penalty 1, both directions, no turn restrictions."""

    def way_penalty(self, tags):
        return 1.0 if way_allowed(tags) else None

    def way_direction(self, tags):
        return True, True

    def is_turn_restriction(self, tags):
        return TurnRestriction.INAPPLICABLE


def split(way, usable):
    """The runs of a way's nodes between unusable (blocked or missing) nodes, as separate ways."""
    run = []
    for n in way.nodes:
        if n in usable:
            run.append(n)
        else:
            if len(run) >= 2:
                yield reader.Way(way.id, run, way.tags)
            run = []
    if len(run) >= 2:
        yield reader.Way(way.id, run, way.tags)


def main():
    request = json.load(sys.stdin)
    with open(sys.argv[1], "rb") as f:
        features = list(reader.read_features(f, "pbf"))
    nodes = {ft.id: ft for ft in features if isinstance(ft, reader.Node)}
    usable = {i for i, n in nodes.items() if not node_blocks(n.tags)}
    ways = {ft.id: ft for ft in features if isinstance(ft, reader.Way)}
    graph_features = [nodes[i] for i in usable]
    for w in ways.values():
        graph_features.extend(split(w, usable))
    g = Graph.from_features(ShortestWalk(), graph_features)

    routes = []
    for a, b in request["pairs"]:
        if a not in g.nodes or b not in g.nodes:
            routes.append([])
            continue
        path = find_route(g, a, b, step_limit=None)
        routes.append([list(g.get_node(n).position) for n in path])
    forbidden = [w for w in request.get("ways", []) if w in ways and not way_allowed(ways[w].tags)]
    unknown = [w for w in request.get("ways", []) if w not in ways]
    json.dump({"routes": routes, "forbidden_ways": forbidden, "unknown_ways": unknown}, sys.stdout)


if __name__ == "__main__":
    main()
