#!/usr/bin/env python3
"""One-off: carry the published BB2 surface particulars into the project's own data files.

Reads (read-only) ``../shared/bb2_rom/data/{offsets,geometry,constants}.json`` and writes

* ``bb2_sim/data/hull_offsets.json``  - table of offsets (hull ring grid, hub profile, lofts, placements)
* ``bb2_sim/data/hull_geometry.json`` - STL import rule, authors' file -> part mapping, hinge data and
  the authors' per-part STL volumes / centroids (for checks)

in the project's own layout (rows instead of column dicts, grouped by ROM part).  Numbers are copied
unchanged; only the structure differs.  Usage::

    python tools/convert_offsets.py [--shared ../shared]
"""
from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bb2_sim" / "data"

SOURCE = ("Martin, Hammond, Rober, Kim, Cichella, Carrica, 'Reduced Order Model of a Generic Submarine for "
          "Maneuvering Near the Surface' (arXiv 2212.09821); surfaces and hinge data of the authors' IowaBB2model "
          "Simulink repository (caslabuiowa/IowaBB2model), Model_6DOF.slx / load_data.m / surface/*.stl, as "
          "documented in shared/bb2_rom (SPEC.md 1.2, 7.1-7.2; data/geometry.json, data/constants.json, "
          "data/offsets.json measured from the STL files by offsets_extract.py). Converted by tools/convert_offsets.py.")

# ROM part -> (group, offsets.json part name); group order = concatenation order of HullSurfaces
PARTS = [("hull", "fixed"), ("sail", "fixed"), ("prop_hub", "fixed"), ("stern_plane_roots", "fixed"),
         ("stern_plane_1", "plane1"), ("stern_plane_2", "plane2"), ("stern_plane_3", "plane3"),
         ("stern_plane_4", "plane4"), ("sail_planes", "plane5")]


def _rows(station: dict) -> list[list[float]]:
    return [[x, s, h] for x, s, h in zip(station["x"], station["s"], station["h"])]


def convert(shared: Path) -> tuple[dict, dict]:
    data = shared / "bb2_rom" / "data"
    off = json.loads((data / "offsets.json").read_text())
    geo = json.loads((data / "geometry.json").read_text())
    const = json.loads((data / "constants.json").read_text())

    h = off["parts"]["hull"]
    hub = off["parts"]["prop_hub"]
    parts = {}
    for name, group in PARTS:
        p = off["parts"][name]
        entry = {"group": group, "builder": p["type"]}
        if p["type"] == "loft":
            entry["loft"] = p["loft"]
            entry["placements"] = [{"matrix": c["matrix"], "offset_m": c["offset"]} for c in p["copies"]]
        entry["authors_stl_triangles"] = p["stl_reference"]["triangles"]
        parts[name] = entry

    offsets = {
        "_about": "Table of offsets of the Joubert BB2 surfaces (full scale). bb2_sim.geometry builds one closed, "
                  "outward-oriented triangle mesh per part from it (generate_bb2_surfaces).",
        "provenance": SOURCE,
        "units": "metres",
        "frame": "ROM body frame (SPEC 1.2): origin at the CG on the shaft axis, x aft, y starboard, z up",
        "precision_m": 1e-4,
        "resolution_note": "Keep exactly this resolution: the ROM's mass is trimmed to the faceted volume "
                           "(the hull's 31-gon sections are 0.69 % smaller than circles).",
        "parts": parts,
        "hull_ring_grid": {
            "description": "ring of n_theta points per station at theta_k = k*360/n_theta deg, k = -(n-1)/2..(n-1)/2, "
                           "from +z towards +y: (x, r sin theta, r cos theta); stations with casing replace k = 0..4 "
                           "by the listed (x, y, z) and k = -1..-4 by (x, -y, z). Quads split on the shorter "
                           "diagonal; fans to the nose tip and tail centre on the axis.",
            "n_theta": h["n_theta"],
            "nose_tip_x_m": h["nose_tip_x"],
            "tail_centre_x_m": h["tail_centre_x"],
            "station_columns": ["x_m", "r_m"],
            "stations": [[s["x"], s["r"]] for s in h["stations"]],
            "casing_points_k0_to_k4_by_station": {
                str(i): s["casing"] for i, s in enumerate(h["stations"]) if s.get("casing")},
        },
        "prop_hub_revolution": {
            "description": "(x, r) profile revolved about the x axis with n_theta segments, first vertex at theta0 "
                           "from +z towards +y; r = 0 is a pole (fan).",
            "n_theta": hub["n_theta"],
            "theta0_deg": hub["theta0_deg"],
            "profile_columns": ["x_m", "r_m"],
            "profile": hub["profile_x_r"],
        },
        "lofts": {
            "description": "symmetric lofts in a local frame (x chordwise, s spanwise, t thickness): each station is "
                           "a list of chord points [x, s, h] from leading to trailing edge; the skins pass through "
                           "(x, s, +h) and (x, s, -h). Consecutive stations are joined by quads split on the shorter "
                           "diagonal; an end station with some h > 0 is closed by a ruled face. Coincident vertices "
                           "are merged, degenerate and zero-thickness triangles dropped. Placed with "
                           "v_body = matrix . v_local + offset (winding reversed when det(matrix) < 0).",
            "point_columns": ["x_m", "s_m", "h_m"],
            **{name: [_rows(st) for st in lo["stations"]]
               for name, lo in off["lofts"].items() if isinstance(lo, dict)},
        },
    }

    author_files = {"fixed": []}
    for f in ("Hull.stl", "Sail.stl", "PropHub.stl", "TailPlaneRoots.stl"):
        author_files["fixed"].append(f)
    planes = {}
    for k in ("1", "2", "3", "4", "5"):
        p = geo["planes"][k]
        author_files[f"plane{k}"] = p["stl_files"]
        planes[f"plane{k}"] = {
            "name": p["name"],
            "hinge_origin_nondim": p["hinge_origin_nondim"],
            "hinge_euler_deg_phi_theta_psi": p["hinge_euler_deg_phi_theta_psi"],
        }
    ref = off["parts_and_closure"]["volumes_m3_from_stl"]
    geometry = {
        "_about": "Geometry of the BB2 hydrostatic surfaces used by bb2_sim.geometry: how the authors' STL files are "
                  "imported and grouped, and the control-plane hinges (SPEC 7.1-7.2).",
        "provenance": SOURCE,
        "stl_import": {
            "rule": "vertex_body_m = vertex_file * L_m - xcg_m (non-dimensional STL coordinates: x aft from the bow, "
                    "y starboard, z up from the shaft axis, divided by L)",
            "L_m": const["L_m"],
            "xcg_m": const["Xcg_m"],
            "xcg_note": "32.3114 * 1.0005364451: puts the CG exactly above the centre of buoyancy of the surfaces",
        },
        "plane_pivot": {
            "rule": "P_i = hinge_origin_nondim * L_m - [x_ref_m, 0, 0]; RX_i = Rz(psi) Ry(theta) Rx(phi) from "
                    "hinge_euler_deg (SPEC 1.3); the hinge axis is RX_i e_z",
            "x_ref_m": const["plane_pivot_reference_x_m"],
            "x_ref_note": "the authors' model uses 32.3114 here, without the 1.0005364451 factor (SPEC Q18)",
        },
        "planes": planes,
        "authors_stl_files": author_files,
        "authors_stl_reference": {
            "note": "enclosed volume per part of the authors' STL surfaces (offsets.json, measured by offsets_extract.py)",
            "volumes_m3": {name: ref[name] for name, _ in PARTS},
            "total_volume_m3": off["parts_and_closure"]["total_volume_m3_from_stl"],
            "total_centroid_m": off["parts_and_closure"]["total_centroid_m_from_stl"],
            "total_triangles": geo["surfaces"]["total_triangles"],
        },
    }
    return offsets, geometry


def _dump(obj: dict) -> str:
    """JSON with every innermost list of numbers on one line."""
    text = json.dumps(obj, indent=1)
    return re.sub(r"\[\s*([-0-9.eE+,\s]+?)\s*\]",
                  lambda m: "[" + ", ".join(t.strip() for t in m.group(1).split(",")) + "]", text) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--shared", type=Path, default=REPO.parent / "shared")
    args = ap.parse_args()
    offsets, geometry = convert(args.shared)
    (OUT / "hull_offsets.json").write_text(_dump(offsets))
    (OUT / "hull_geometry.json").write_text(_dump(geometry))
    print(f"wrote {OUT / 'hull_offsets.json'} and {OUT / 'hull_geometry.json'}")


if __name__ == "__main__":
    main()
