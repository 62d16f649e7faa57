# Writes tests/data/osm/rules.osm: the hand-made fixture for access rules, barriers, steps, trunks, oneway
# and rendering (see README.md in that folder for what each part tests).
nodes = {
  # access: a private footway 1-2 and a detour 1-3-2
  1: (60.0000, 25.0000, {}), 2: (60.0000, 25.0040, {}), 3: (60.0010, 25.0020, {}),
  # barrier: a locked gate 12 on 11-12-13; detour 11-15-14-13 through a bollard 15
  11: (60.0030, 25.0000, {}), 12: (60.0030, 25.0020, {"barrier": "gate", "locked": "yes"}),
  13: (60.0030, 25.0040, {}), 14: (60.0040, 25.0020, {}), 15: (60.0035, 25.0010, {"barrier": "bollard"}),
  # steps 21-22; detour path 21-23-22
  21: (60.0060, 25.0000, {}), 22: (60.0060, 25.0040, {}), 23: (60.0072, 25.0020, {}),
  # trunk without sidewalk 31-32; detour footway 31-33-32
  31: (60.0090, 25.0000, {}), 32: (60.0090, 25.0040, {}), 33: (60.0100, 25.0020, {}),
  # a oneway footway 41 -> 42
  41: (60.0120, 25.0000, {}), 42: (60.0120, 25.0040, {}),
  # a building and a pond
  51: (60.0150, 25.0000, {}), 52: (60.0150, 25.0010, {}), 53: (60.0155, 25.0010, {}), 54: (60.0155, 25.0000, {}),
  61: (60.0150, 25.0030, {}), 62: (60.0150, 25.0045, {}), 63: (60.0158, 25.0045, {}), 64: (60.0158, 25.0030, {}),
}
ways = [
  (101, [1, 2], {"highway": "footway", "access": "private"}),
  (102, [1, 3, 2], {"highway": "footway"}),
  (111, [11, 12, 13], {"highway": "footway"}),
  (112, [11, 15, 14, 13], {"highway": "footway"}),
  (121, [21, 22], {"highway": "steps"}),
  (122, [21, 23, 22], {"highway": "path"}),
  (131, [31, 32], {"highway": "trunk", "name": "Fixture Trunk Road"}),
  (132, [31, 33, 32], {"highway": "footway"}),
  (141, [41, 42], {"highway": "footway", "oneway": "yes"}),
  (201, [51, 52, 53, 54, 51], {"building": "yes"}),
  (202, [61, 62, 63, 64, 61], {"natural": "water", "name": "Pond"}),
]
out = ['<?xml version="1.0" encoding="UTF-8"?>', '<osm version="0.6" generator="vestnav fixture (hand-made)">']
for i, (lat, lon, tags) in nodes.items():
    if tags:
        out.append(f'  <node id="{i}" version="1" lat="{lat:.7f}" lon="{lon:.7f}">')
        out += [f'    <tag k="{k}" v="{v}"/>' for k, v in tags.items()]
        out.append('  </node>')
    else:
        out.append(f'  <node id="{i}" version="1" lat="{lat:.7f}" lon="{lon:.7f}"/>')
for i, nds, tags in ways:
    out.append(f'  <way id="{i}" version="1">')
    out += [f'    <nd ref="{n}"/>' for n in nds]
    out += [f'    <tag k="{k}" v="{v}"/>' for k, v in tags.items()]
    out.append('  </way>')
out.append('</osm>')
open("rules.osm", "w").write("\n".join(out) + "\n")
