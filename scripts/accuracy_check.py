#!/usr/bin/env python3
"""Independent accuracy statistics of an NMEA log against a reference point, for
`tests/integration/accuracy.rs` (and by hand: `python3 scripts/accuracy_check.py LOG LAT LON HEIGHT`).

Written apart from vestnav's Rust code: its own GGA parser (checksum verified), Karney's geodesics from
the Python `geographiclib` package (pip install geographiclib) for the distance and azimuth from the
reference, and the definitions of docs/field-tests.md (bias, sigma, DRMS, nearest-rank CEP50/CEP95, the
share within 0.1/0.5/1/2/5 m, the vertical error against the height above mean sea level). Prints one JSON
object.
"""

import json
import math
import sys

from geographiclib.geodesic import Geodesic


def checksum_ok(line):
    if not line.startswith("$") or "*" not in line:
        return False
    body, _, given = line[1:].partition("*")
    value = 0
    for ch in body:
        value ^= ord(ch)
    try:
        return value == int(given[:2], 16)
    except ValueError:
        return False


def degrees(text, hemisphere, width):
    if not text:
        return None
    d = float(text[:width]) + float(text[width:]) / 60.0
    return -d if hemisphere in ("S", "W") else d


def gga_fixes(path):
    fixes = []
    with open(path, "rb") as f:
        for raw in f:
            line = raw.decode("ascii", "replace").strip()
            if not checksum_ok(line):
                continue
            fields = line.split("*")[0].split(",")
            if len(fields) < 10 or fields[0][3:] != "GGA":
                continue
            if not fields[6] or int(fields[6]) == 0:
                continue
            lat = degrees(fields[2], fields[3], 2)
            lon = degrees(fields[4], fields[5], 3)
            if lat is None or lon is None:
                continue
            alt = float(fields[9]) if fields[9] else None
            fixes.append((lat, lon, alt))
    return fixes


def nearest_rank(values, p):
    v = sorted(values)
    k = max(1, math.ceil(p / 100.0 * len(v) - 1e-9))
    return v[min(k, len(v)) - 1]


def main():
    path, lat0, lon0, h0 = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    fixes = gga_fixes(path)
    geod = Geodesic.WGS84
    east, north, radial = [], [], []
    for lat, lon, _ in fixes:
        g = geod.Inverse(lat0, lon0, lat, lon)
        az = math.radians(g["azi1"])
        east.append(g["s12"] * math.sin(az))
        north.append(g["s12"] * math.cos(az))
        radial.append(g["s12"])
    n = len(fixes)
    be, bn = sum(east) / n, sum(north) / n
    se = math.sqrt(sum((e - be) ** 2 for e in east) / n)
    sn = math.sqrt(sum((x - bn) ** 2 for x in north) / n)
    drms = math.sqrt(sum(r * r for r in radial) / n)
    dz = [alt - h0 for _, _, alt in fixes if alt is not None]
    out = {
        "fixes": n,
        "bias_en_m": [be, bn],
        "sigma_en_m": [se, sn],
        "drms_m": drms,
        "cep50_m": nearest_rank(radial, 50),
        "cep95_m": nearest_rank(radial, 95),
        "max_m": max(radial),
        "within": [sum(1 for r in radial if r <= t) / n for t in (0.1, 0.5, 1.0, 2.0, 5.0)],
        "gaussian_cep50_m": 0.589 * (se + sn),
        "vertical_bias_m": sum(dz) / len(dz) if dz else None,
        "vertical_rms_m": math.sqrt(sum(d * d for d in dz) / len(dz)) if dz else None,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
