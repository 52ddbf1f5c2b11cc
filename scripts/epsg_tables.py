#!/usr/bin/env python3
"""Generate tools/src/config/epsg_tables.rs from the EPSG dataset as PROJ ships it (pyproj).

For every CRS that the crate crs-definitions knows (its src/defs.rs, found in the cargo
registry), two facts spherecal needs and crs-definitions does not carry:

- its area of use (west, south, east, north, degrees): `site import` refuses coordinates
  outside it;
- for its geodetic datum, the transformation to WGS 84 that PROJ picks without grid files
  (the EPSG operation's code, name, accuracy, and its Helmert parameters in the position-vector
  convention of PROJ's +towgs84; none for a null transformation), or nothing when PROJ knows
  none.

Run: python3 scripts/epsg_tables.py > tools/src/config/epsg_tables.rs (pyproj >= 3.6).
"""

import glob
import os
import re
import sqlite3
import sys

import pyproj
from pyproj import CRS
from pyproj.transformer import TransformerGroup

defs = sorted(glob.glob(os.path.expanduser("~/.cargo/registry/src/*/crs-definitions-0.6.0/src/defs.rs")))[0]
text = open(defs).read()
codes = sorted({int(m) for m in re.findall(r"^EPSG_(\d+)\|", text, re.M)})

areas = []
datum_of = {}
for line in text.splitlines():
    m = re.match(r'^EPSG_(\d+)\|\d+\|"[^"]*"\|r#"(.*)"#\|$', line)
    if not m:
        continue
    code, wkt = int(m.group(1)), m.group(2)
    try:
        crs = CRS.from_epsg(code)
    except Exception:
        continue
    a = crs.area_of_use
    if a is not None:
        areas.append((code, a.west, a.south, a.east, a.north))
    # The datum as crs-definitions' WKT names it (what the Rust side reads), and its
    # geographic CRS.
    d = re.search(r'DATUM\["([^"]*)".*?AUTHORITY\["EPSG","(\d+)"\]\],PRIMEM', wkt)
    g = re.search(r'AUTHORITY\["EPSG","(\d+)"\]\],PROJECTION', wkt)
    if not d:
        continue
    geog = int(g.group(1)) if g else (code if wkt.startswith("GEOGCS") else None)
    if geog is None:
        continue
    gname = re.search(r'GEOGCS\["([^"]*)"', wkt)
    datum_of.setdefault(d.group(2), {})[geog] = gname.group(1) if gname else d.group(1)

# One geographic CRS per datum: a current one (not deprecated), the most used.
for dcode, geogs in list(datum_of.items()):
    def current(g):
        try:
            return not CRS.from_epsg(g).is_deprecated
        except Exception:
            return False
    best = sorted(geogs, key=lambda g: (not current(g), g))[0]
    datum_of[dcode] = (geogs[best], best)

DB = sqlite3.connect(os.path.join(pyproj.datadir.get_data_dir(), "proj.db"))


def helmert(defn):
    """Position-vector Helmert parameters (m, arc-seconds, ppm) of a PROJ pipeline, if it is
    one step of +proj=helmert (translations only or 7 parameters)."""
    steps = [s for s in defn.split(" step ") if "proj=helmert" in s]
    if len(steps) != 1:
        return None
    kv = dict(p.split("=", 1) for p in steps[0].split() if "=" in p)
    p = [float(kv.get(k, 0.0)) for k in ("x", "y", "z", "rx", "ry", "rz", "s")]
    if kv.get("convention") == "coordinate_frame":
        p[3], p[4], p[5] = -p[3], -p[4], -p[5]
    return p


rows = []
for dcode, (dname, geog) in sorted(datum_of.items(), key=lambda kv: int(kv[0])):
    if geog is None:
        continue
    if geog == 4326:
        rows.append((int(dcode), dname, geog, 0, "WGS 84", "identity", [0.0] * 7, 0.0))
        continue
    try:
        g = TransformerGroup(f"EPSG:{geog}", "EPSG:4326", always_xy=True)
    except Exception:
        continue
    chosen = None
    for t in g.transformers:
        try:
            t.transform(0.0, 0.0)
        except Exception:
            continue
        d = t.definition
        if "grid" in d or "proj=hgridshift" in d or "proj=vgridshift" in d:
            continue
        chosen = t
        break
    # PROJ's "ballpark" offsets are its guess where the EPSG dataset has no transformation:
    # no transformation is known.
    if chosen is None or "Ballpark" in chosen.description:
        continue
    desc = chosen.description
    name = " + ".join(
        part.replace("Inverse of ", "").strip()
        for part in desc.split(" + ")
        if not part.startswith(("axis order", "Conversion from", "Null geographic offset"))
    )
    op = 0
    for o in chosen.operations or []:
        ids = o.to_json_dict().get("id")
        if (
            ids
            and ids.get("authority") == "EPSG"
            and "Conversion" not in o.name
            and "axis order" not in o.name
        ):
            op = int(ids["code"])
            break
    if op == 0:
        row = DB.execute(
            "select code from coordinate_operation_view where name = ? and auth_name = 'EPSG'",
            (name,),
        ).fetchone()
        op = int(row[0]) if row else 0
    acc = chosen.accuracy if chosen.accuracy is not None and chosen.accuracy >= 0 else -1.0
    d = chosen.definition
    if "proj=noop" in d or d.strip() == "":
        rows.append((int(dcode), dname, geog, op, name, "null", [0.0] * 7, acc))
        continue
    p = helmert(d)
    if p is None:
        continue
    rows.append((int(dcode), dname, geog, op, name, "helmert", p, acc))

out = sys.stdout
out.write(f"""//! Generated by scripts/epsg_tables.py from the EPSG dataset in PROJ {pyproj.proj_version_str} (pyproj
//! {pyproj.__version__}): each CRS's area of use, and each geodetic datum's grid-free transformation to
//! WGS 84 as PROJ picks it. Do not edit; run the script again.

/// (EPSG code, west, south, east, north [deg]) of every CRS crs-definitions knows, by code.
pub const AREAS: &[(u16, [f32; 4])] = &[
""")
for code, w, s, e, n in areas:
    if code <= 65535:
        out.write(f"    ({code}, [{w:.2f}, {s:.2f}, {e:.2f}, {n:.2f}]),\n")
out.write("];\n\n")
out.write("""/// How a datum reaches WGS 84: the EPSG transformation's code (0: unknown) and name, its
/// accuracy [m] (negative: unknown), and its Helmert parameters (tx, ty, tz [m], rx, ry, rz
/// [arc-seconds], ds [ppm], position-vector convention: PROJ's `+towgs84`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DatumLink {
    /// The datum's EPSG code.
    pub datum: u16,
    /// The name of its geographic CRS (e.g. `NAD83(CSRS)`).
    pub name: &'static str,
    /// That CRS's EPSG code (its ellipsoid).
    pub geog: u16,
    /// The transformation's EPSG code.
    pub op: u32,
    /// Its name.
    pub op_name: &'static str,
    /// `identity` (WGS 84 itself), `null` (the same coordinates, to the accuracy) or `helmert`.
    pub kind: &'static str,
    /// Helmert parameters (zeros unless `helmert`).
    pub towgs84: [f64; 7],
    /// Accuracy [m].
    pub accuracy: f64,
}

/// Every datum of the CRSs crs-definitions knows with a transformation to WGS 84, by datum
/// code.
pub const DATUMS: &[DatumLink] = &[
""")
for dcode, dname, geog, op, name, kind, p, acc in rows:
    if dcode > 65535:
        continue
    ps = ", ".join(repr(round(v, 9)) if v != int(v) else f"{v:.1f}" for v in p)
    dn = dname.replace('"', '\\"')
    nn = name.replace('"', '\\"')
    out.write(
        f'    DatumLink {{ datum: {dcode}, name: "{dn}", geog: {geog}, op: {op}, op_name: "{nn}", kind: "{kind}", towgs84: [{ps}], accuracy: {acc:.2f} }},\n'
    )
out.write("];\n\n")

# Vertical CRSs (metres, current): their WKT1 for a LAS file's compound CRS.
out.write("""/// (EPSG code, WKT1) of every current vertical CRS in metres (gravity-related heights: a
/// LAS file's compound CRS names them).
pub const VERTICAL: &[(u16, &str)] = &[
""")
for code, name in DB.execute(
    "select code, name from vertical_crs where auth_name = 'EPSG' and deprecated = 0 order by cast(code as integer)"
).fetchall():
    c = CRS.from_epsg(int(code))
    if int(code) > 65535 or c.axis_info[0].unit_name != "metre":
        continue
    w = c.to_wkt("WKT1_GDAL")
    if w:
        out.write(f'    ({code}, r#"{w}"#),\n')
out.write("];\n")

# Compound CRSs (horizontal + vertical): `--crs` names its parts when given one.
out.write("""
/// (EPSG code, name, horizontal CRS code, vertical CRS code) of every current compound CRS:
/// a site's `--crs` takes the horizontal part and `--vertical-crs` the vertical one.
pub const COMPOUND: &[(u16, &str, u16, u16)] = &[
""")
for code, name, h, v in DB.execute(
    "select code, name, horiz_crs_code, vertical_crs_code from compound_crs where auth_name = 'EPSG' and deprecated = 0 and horiz_crs_auth_name = 'EPSG' and vertical_crs_auth_name = 'EPSG' order by cast(code as integer)"
).fetchall():
    if max(int(code), int(h), int(v)) > 65535:
        continue
    n = name.replace('"', '\\"')
    out.write(f'    ({code}, "{n}", {h}, {v}),\n')
out.write("];\n")
