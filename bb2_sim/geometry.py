"""Hull geometry of the BB2 ROM: the triangulated surfaces integrated by the hydrostatics (SPEC 7.1-7.2).

Two sources give the same :class:`HullSurfaces`:

* :func:`generate_bb2_surfaces` builds the BB2 surfaces from the project's own table of offsets
  (``data/hull_offsets.json``), one closed, outward-oriented mesh per part, at the authors' resolution.
* :func:`load_surface_dir` reads any directory of surface files (ASCII/binary STL, OBJ).  The authors'
  file names (``Hull.stl``, ``Sail.stl``, ..., see ``data/hull_geometry.json``) are recognised; any other
  set needs a ``parts.yaml`` manifest::

      coordinates: body_m          # or stl_nondim: vertex_body = vertex_file * L - Xcg (SPEC 1.2)
      fixed: [hull.stl, sail.obj]  # fixed parts, concatenated in this order
      plane1: [fin1a.stl, fin1b.stl]   # moving planes 1..4 (stern, SPEC 3.2 order) and 5 (sail planes)
      plane2: [...]
      plane3: [...]
      plane4: [...]
      plane5: [...]

  Every group (all fixed files together, and each plane's files together) must be a closed surface with
  outward normals.  Triangles keep the exact order of the files.  ASCII STL files are read by a small
  parser of this module (float64 of the ASCII values, the file's facet normals), because trimesh
  re-computes the facet normals; binary STL and OBJ files are read with trimesh (``process=False``).

Frames: every array is in the native body frame (origin at the CG, x aft, y starboard, z up; metres).
Area vectors of fixed parts are ``dA * n`` with the file normal when an ASCII STL file supplies unit
normals (the authors' MATLAB import, SPEC 7.1), otherwise the winding normal.
"""
from __future__ import annotations

import functools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from bb2_sim.frames import rotation_native
from bb2_sim.names import unknown_keys_hint
from bb2_sim.yaml_files import load as load_yaml

__all__ = ["HullMeshError", "HullSurfaces", "generate_bb2_surfaces", "load_surface_dir", "load_hull",
           "PLANE_GROUPS"]

DATA_DIR = Path(__file__).resolve().parent / "data"
PLANE_GROUPS = ("plane1", "plane2", "plane3", "plane4", "plane5")
GROUPS = ("fixed",) + PLANE_GROUPS
MESH_SUFFIXES = (".stl", ".obj")
MANIFEST = "parts.yaml"
COORDINATES = ("body_m", "stl_nondim")

# closure tolerance: |sum of area vectors| / total area of a group (a closed polyhedron gives round-off;
# the authors' sail has 4e-8 from a T-junction, a missing face gives its own area)
CLOSURE_TOL = 1e-6
# ASCII file normals are used when every one is unit to this tolerance (otherwise winding normals)
UNIT_NORMAL_TOL = 1e-3


class HullMeshError(ValueError):
    """A surface set cannot be used: unreadable, missing, non-finite, empty or not closed."""


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class HullSurfaces:
    """Triangulated surfaces in the native body frame (origin CG, x aft, y starboard, z up; metres).

    Arrays are read-only (instances are cached and shared by :func:`load_hull`).
    """

    fixed_vertices: np.ndarray
    """(Nf, 3, 3) triangle vertices of hull + sail + prop hub + tail-plane roots."""
    fixed_area_vectors: np.ndarray
    """(Nf, 3) dA * outward unit normal (file normal for the authors' STL, SPEC 7.1)."""
    plane_vertices: tuple[np.ndarray, ...]
    """5 arrays (Ni, 3, 3): undeflected vertices of planes 1..4 (stern) and 5 (sail planes)."""
    plane_areas: tuple[np.ndarray, ...]
    """5 arrays (Ni,): triangle areas dA of the unrotated vertices."""
    plane_pivots: np.ndarray
    """(5, 3) hinge pivots P_i, body frame (SPEC 7.2)."""
    plane_hinge_rotations: np.ndarray
    """(5, 3, 3) RX_i from the hinge Euler angles (SPEC 1.3 matrix); hinge axis = RX_i e_z."""
    source: str
    """"generated:offsets" or the directory the surfaces were read from."""
    fixed_parts: tuple[tuple[str, int], ...] = field(default=())
    """(part or file name, triangle count) of the fixed triangles, in concatenation order."""

    def all_triangles(self) -> np.ndarray:
        """(N, 3, 3) every triangle: the fixed parts, then planes 1..5 undeflected (body frame, m)."""
        return np.concatenate((self.fixed_vertices,) + tuple(self.plane_vertices))

    def volume(self) -> float:
        """Enclosed volume (m^3): sum over all parts, planes undeflected."""
        import trimesh  # (here, not at import: see _signed_volume)

        return float(trimesh.triangles.mass_properties(self.all_triangles(), skip_inertia=True).volume)

    def centroid(self) -> np.ndarray:
        """Centre of buoyancy (centroid of the enclosed volume), body frame, metres."""
        import trimesh

        return np.asarray(
            trimesh.triangles.mass_properties(self.all_triangles(), skip_inertia=True).center_mass, dtype=float)

    def sail_top_m(self) -> float:
        """Highest point of all surfaces (planes undeflected) above the CG, m: the sail top; the vehicle is
        above the surface (broaching) when its CG z exceeds ``-sail_top_m()`` (mission ``limits.max_cg_z_m``)."""
        return float(self.all_triangles()[..., 2].max())

    def n_triangles(self) -> int:
        """Total number of triangles (fixed and moving)."""
        return int(len(self.fixed_vertices) + sum(len(v) for v in self.plane_vertices))

    def part_volumes(self) -> dict[str, float]:
        """Enclosed volume (m^3) of every fixed part of ``fixed_parts`` and of each plane group."""
        out, start = {}, 0
        for name, n in self.fixed_parts:
            out[name] = _volume(self.fixed_vertices[start:start + n])
            start += n
        for g, v in zip(PLANE_GROUPS, self.plane_vertices):
            out[g] = _volume(v)
        return out


# ------------------------------------------------------------------------------------------------
# data files
# ------------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=None)
def _data(name: str) -> dict:
    with open(DATA_DIR / name) as fh:
        return json.load(fh)


def _hinges() -> tuple[np.ndarray, np.ndarray]:
    """Plane pivots (5, 3) and hinge rotations (5, 3, 3), body frame (SPEC 7.2)."""
    geo = _data("hull_geometry.json")
    L = float(geo["stl_import"]["L_m"])
    x_ref = np.array([geo["plane_pivot"]["x_ref_m"], 0.0, 0.0])
    pivots, rots = [], []
    for g in PLANE_GROUPS:
        p = geo["planes"][g]
        pivots.append(np.asarray(p["hinge_origin_nondim"], dtype=float) * L - x_ref)
        phi, theta, psi = np.deg2rad(np.asarray(p["hinge_euler_deg_phi_theta_psi"], dtype=float))
        rots.append(rotation_native(phi, theta, psi))
    return np.array(pivots), np.array(rots)


def _stl_to_body(v_file: np.ndarray) -> np.ndarray:
    """Non-dimensional STL coordinates -> body metres: v * L - Xcg (SPEC 1.2, 7.1)."""
    imp = _data("hull_geometry.json")["stl_import"]
    return v_file * float(imp["L_m"]) - np.asarray(imp["xcg_m"], dtype=float)


# ------------------------------------------------------------------------------------------------
# triangle-soup helpers
# ------------------------------------------------------------------------------------------------
def _cross(T: np.ndarray) -> np.ndarray:
    return np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])


def _volume(T: np.ndarray) -> float:
    """Enclosed volume of a triangle soup, m^3: trimesh's mass properties (the volumes the surfaces report)."""
    import trimesh

    return float(trimesh.triangles.mass_properties(T, skip_inertia=True).volume) if len(T) else 0.0


def _signed_volume(T: np.ndarray) -> float:
    """Enclosed volume of a closed triangle soup by the divergence theorem (the sum of v0 . (v1 x v2) / 6), m^3:
    its sign is the winding (> 0 outward), which is what the mesh builders and the closure check need.  The
    volumes and the centroid the surfaces report are trimesh's (:func:`_volume`); importing trimesh (and the
    scipy.spatial, sparse and ndimage it imports) cost every process that builds a model -- the simulator node, the
    launcher's start check, ``bb2-sim`` -- ~0.5 s of CPU, for a sign."""
    return float(np.einsum("ij,ij->", T[:, 0], np.cross(T[:, 1], T[:, 2])) / 6.0) if len(T) else 0.0


def _check_closed(label: str, T: np.ndarray, normals: np.ndarray | None) -> None:
    """Closed surface with outward winding (and file normals agreeing with it), else HullMeshError."""
    cr = _cross(T)
    area = 0.5 * np.linalg.norm(cr, axis=1)
    total = area.sum()
    if not total > 0.0:
        raise HullMeshError(f"{label}: zero surface area")
    gap = np.linalg.norm(0.5 * cr.sum(axis=0)) / total
    if gap > CLOSURE_TOL:
        raise HullMeshError(f"{label}: surface is not closed (|sum of area vectors| / area = {gap:.2e} > "
                            f"{CLOSURE_TOL:g}); a part or a half is missing, or faces have mixed orientation")
    if _signed_volume(T) <= 0.0:
        raise HullMeshError(f"{label}: normals point inwards (enclosed volume {_signed_volume(T):.6g} m^3 <= 0)")
    if normals is not None:
        big = area > 1e-9 * area.max()
        cos = np.einsum("ij,ij->i", cr[big], normals[big]) / (2.0 * area[big])
        if np.any(cos < 0.5):
            raise HullMeshError(f"{label}: {int(np.sum(cos < 0.5))} file normals disagree with the vertex winding")


# ------------------------------------------------------------------------------------------------
# readers
# ------------------------------------------------------------------------------------------------
def _read_ascii_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """ASCII STL -> (facet normals (n, 3), triangles (n, 3, 3)), float64 of the ASCII values, file order."""
    try:
        tok = np.asarray(path.read_text(encoding="ascii").split())
    except (UnicodeDecodeError, OSError) as exc:
        raise HullMeshError(f"{path.name}: cannot read as ASCII STL ({exc})") from exc
    i_n = np.flatnonzero(tok == "normal")
    i_v = np.flatnonzero(tok == "vertex")
    if len(i_n) == 0 or len(i_v) != 3 * len(i_n) or np.count_nonzero(tok == "endfacet") != len(i_n):
        raise HullMeshError(f"{path.name}: not a valid ASCII STL ({len(i_n)} facets, {len(i_v)} vertices)")
    order = np.sort(np.concatenate([i_n, i_v]))
    pattern = np.isin(order, i_n).reshape(-1, 4)
    if not (pattern[:, 0].all() and not pattern[:, 1:].any()) or order[-1] + 3 >= len(tok):
        raise HullMeshError(f"{path.name}: malformed ASCII STL (every facet needs one normal and three vertices)")
    try:
        vals = tok[(order[:, None] + np.arange(1, 4)).ravel()].astype(np.float64).reshape(-1, 4, 3)
    except ValueError as exc:
        raise HullMeshError(f"{path.name}: unreadable number in ASCII STL ({exc})") from exc
    return vals[:, 0, :], vals[:, 1:, :]


def _is_binary_stl(path: Path) -> bool:
    size = path.stat().st_size
    if size < 84:
        return False
    with open(path, "rb") as fh:
        head = fh.read(84)
    return 84 + 50 * int(np.frombuffer(head[80:84], dtype="<u4")[0]) == size


def _read_mesh_file(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """One surface file -> (triangles (n, 3, 3) in file coordinates, unit file normals or None)."""
    if not path.is_file():
        raise HullMeshError(f"{path.name}: file not found in {path.parent}")
    suffix = path.suffix.lower()
    normals = None
    if suffix == ".stl" and not _is_binary_stl(path):
        normals, T = _read_ascii_stl(path)
        if not np.all(np.abs(np.linalg.norm(normals, axis=1) - 1.0) <= UNIT_NORMAL_TOL):
            normals = None  # e.g. exporters writing zero normals: use the winding
    elif suffix in MESH_SUFFIXES:
        import trimesh

        try:
            mesh = trimesh.load(str(path), file_type=suffix[1:], process=False, force="mesh")
            T = np.asarray(mesh.triangles, dtype=np.float64)
        except Exception as exc:  # trimesh raises many types on garbage input
            raise HullMeshError(f"{path.name}: cannot read {suffix[1:].upper()} file ({exc})") from exc
    else:
        raise HullMeshError(f"{path.name}: unsupported surface file type (use .stl or .obj)")
    if T.ndim != 3 or len(T) == 0:
        raise HullMeshError(f"{path.name}: contains no triangles")
    if not np.all(np.isfinite(T)) or (normals is not None and not np.all(np.isfinite(normals))):
        raise HullMeshError(f"{path.name}: non-finite (NaN or inf) coordinates")
    return T, normals


def _manifest(directory: Path) -> tuple[dict[str, list[str]], str]:
    """Files per group and their coordinate kind, from parts.yaml or from the authors' file names."""
    mpath = directory / MANIFEST
    if mpath.is_file():
        try:
            m = load_yaml(mpath.read_text())
        except yaml.YAMLError as exc:
            raise HullMeshError(f"{MANIFEST}: invalid YAML ({exc})") from exc
        if not isinstance(m, dict):
            raise HullMeshError(f"{MANIFEST}: expected a mapping with 'coordinates' and {', '.join(GROUPS)}")
        unknown = set(m) - set(GROUPS) - {"coordinates"}
        if unknown:
            raise HullMeshError(f"{MANIFEST}: unknown keys {sorted(unknown)}"
                                f"{unknown_keys_hint(unknown, [*GROUPS, 'coordinates'])}; allowed: coordinates, "
                                f"{', '.join(GROUPS)}")
        coords = m.get("coordinates")
        if coords not in COORDINATES:
            raise HullMeshError(f"{MANIFEST}: 'coordinates' must be one of {COORDINATES}, got {coords!r}")
        groups = {}
        for g in GROUPS:
            files = m.get(g)
            if isinstance(files, str):
                files = [files]
            if not files or not all(isinstance(f, str) for f in files):
                raise HullMeshError(f"{MANIFEST}: '{g}' must list at least one surface file")
            groups[g] = list(files)
        return groups, coords
    groups = {g: list(f) for g, f in _data("hull_geometry.json")["authors_stl_files"].items()}
    names = [f for g in GROUPS for f in groups[g]]
    present = {p.name for p in directory.iterdir() if p.suffix.lower() in MESH_SUFFIXES}
    if not present & set(names):
        raise HullMeshError(f"{directory}: no surface files of the BB2 set ({', '.join(names[:4])}, ...) and no "
                            f"{MANIFEST} manifest mapping files to parts")
    missing = [f for f in names if f not in present]
    if missing:
        raise HullMeshError(f"{directory}: missing surface files of the BB2 set: {', '.join(missing)}")
    extra = sorted(present - set(names))
    if extra:
        raise HullMeshError(f"{directory}: unrecognised surface files {extra}; add a {MANIFEST} manifest")
    return groups, "stl_nondim"


# ------------------------------------------------------------------------------------------------
# public loaders
# ------------------------------------------------------------------------------------------------
def load_surface_dir(path: str | os.PathLike) -> HullSurfaces:
    """Read a directory of surface files (the authors' STL set, or any set described by parts.yaml).

    Raises HullMeshError (naming the file or group) for a missing directory or file, unreadable files,
    non-finite vertices, empty files, and groups that are not closed with outward normals.
    """
    directory = Path(path)
    if not directory.is_dir():
        raise HullMeshError(f"{directory}: not a directory of surface files")
    groups, coords = _manifest(directory)
    to_body = _stl_to_body if coords == "stl_nondim" else (lambda v: v)

    fixed_T, fixed_A, fixed_parts = [], [], []
    plane_T, plane_dA = [], []
    for g in GROUPS:
        Ts, Ns = [], []
        for name in groups[g]:
            T_file, n_file = _read_mesh_file(directory / name)
            T = to_body(T_file)
            Ts.append(T)
            Ns.append(n_file)
            if g == "fixed":
                cr = _cross(T)
                if n_file is None:
                    fixed_A.append(0.5 * cr)
                else:  # SPEC 7.1: |cross| / 2 times the file normal
                    fixed_A.append((0.5 * np.linalg.norm(cr, axis=1))[:, None] * n_file)
                fixed_parts.append((name, len(T)))
        T = np.concatenate(Ts)
        normals = None if any(n is None for n in Ns) else np.concatenate(Ns)
        _check_closed(f"{g} ({', '.join(groups[g])})", T, normals)
        if g == "fixed":
            fixed_T.append(T)
        else:
            plane_T.append(T)
            plane_dA.append(0.5 * np.linalg.norm(_cross(T), axis=1))
    pivots, rots = _hinges()
    return HullSurfaces(
        fixed_vertices=_frozen(np.concatenate(fixed_T)),
        fixed_area_vectors=_frozen(np.concatenate(fixed_A)),
        plane_vertices=tuple(_frozen(t) for t in plane_T),
        plane_areas=tuple(_frozen(a) for a in plane_dA),
        plane_pivots=_frozen(pivots),
        plane_hinge_rotations=_frozen(rots),
        source=str(directory),
        fixed_parts=tuple(fixed_parts),
    )


def generate_bb2_surfaces() -> HullSurfaces:
    """Build the BB2 surfaces from the project's table of offsets (data/hull_offsets.json).

    One closed, outward-oriented mesh per part (hull, sail, prop hub, stern-plane roots, stern planes
    1..4, sail planes); fixed area vectors are the winding area vectors.
    """
    off = _data("hull_offsets.json")
    meshes: dict[str, list[np.ndarray]] = {g: [] for g in GROUPS}
    fixed_parts = []
    for name, part in off["parts"].items():
        builder = part["builder"]
        if builder == "ring_grid":
            V, F = _build_ring_grid(off["hull_ring_grid"])
        elif builder == "revolution":
            V, F = _build_revolution(off["prop_hub_revolution"])
        elif builder == "loft":
            V0, F0 = _build_loft(off["lofts"][part["loft"]])
            Vs, Fs, n = [], [], 0
            for pl in part["placements"]:
                V, F = _place(V0, F0, pl["matrix"], pl["offset_m"])
                Vs.append(V)
                Fs.append(F + n)
                n += len(V)
            V, F = np.vstack(Vs), np.vstack(Fs)
        else:
            raise HullMeshError(f"hull_offsets.json: part {name!r} has unknown builder {builder!r}")
        T = V[F]
        _check_closed(f"generated {name}", T, None)
        meshes[part["group"]].append(T)
        if part["group"] == "fixed":
            fixed_parts.append((name, len(T)))
    fixed = np.concatenate(meshes["fixed"])
    planes = [np.concatenate(meshes[g]) for g in PLANE_GROUPS]
    pivots, rots = _hinges()
    return HullSurfaces(
        fixed_vertices=_frozen(fixed),
        fixed_area_vectors=_frozen(0.5 * _cross(fixed)),
        plane_vertices=tuple(_frozen(t) for t in planes),
        plane_areas=tuple(_frozen(0.5 * np.linalg.norm(_cross(t), axis=1)) for t in planes),
        plane_pivots=_frozen(pivots),
        plane_hinge_rotations=_frozen(rots),
        source="generated:offsets",
        fixed_parts=tuple(fixed_parts),
    )


GENERATED = "generated:offsets"


def load_hull(source: str | os.PathLike | None = None) -> HullSurfaces:
    """Surfaces for the ROM: None (or "generated:offsets") -> generated from the offsets, else a directory.

    Cached: the same source returns the same (read-only) object.
    """
    if source is None or str(source) == GENERATED:
        return _load_cached(GENERATED)
    return _load_cached(str(Path(source).expanduser().resolve()))


@functools.lru_cache(maxsize=8)
def _load_cached(key: str) -> HullSurfaces:
    return generate_bb2_surfaces() if key == GENERATED else load_surface_dir(key)


# ------------------------------------------------------------------------------------------------
# mesh builders: table of offsets -> closed, outward triangle meshes (vertices V, faces F)
# ------------------------------------------------------------------------------------------------
def _orient_outward(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    return F[:, ::-1].copy() if _signed_volume(V[F]) < 0.0 else F


def _quad_strip(A: np.ndarray, B: np.ndarray, closed: bool) -> np.ndarray:
    """Quads (A[i], A[i+1], B[i+1], B[i]) between two index rows (closed: wrap around)."""
    A, B = np.asarray(A), np.asarray(B)
    i = np.arange(len(A) if closed else len(A) - 1)
    j = (i + 1) % len(A)
    return np.stack([A[i], A[j], B[j], B[i]], axis=1)


def _split_quads(V: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Split quads (a, b, c, d) along the shorter diagonal; near-ties go to the diagonal through the
    lowest vertex index so that coincident quads of opposite orientation split alike."""
    a, b, c, d = Q.T
    lac = np.sum((V[a] - V[c]) ** 2, axis=1)
    lbd = np.sum((V[b] - V[d]) ** 2, axis=1)
    tie = np.abs(lac - lbd) <= 1e-9 * np.maximum(lac, lbd)
    use_ac = np.where(tie, np.minimum(a, c) < np.minimum(b, d), lac < lbd)
    t1 = np.where(use_ac[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(use_ac[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return np.stack([t1, t2], axis=1).reshape(-1, 3)


def _build_ring_grid(h: dict) -> tuple[np.ndarray, np.ndarray]:
    """Hull: rings of n_theta points per station, casing points overriding k = 0..4 (and mirrors)."""
    n = int(h["n_theta"])
    ks = np.arange(-(n // 2), n // 2 + 1)
    th = np.radians(ks * 360.0 / n)
    casing = h.get("casing_points_k0_to_k4_by_station", {})
    rings = []
    for j, (x, r) in enumerate(h["stations"]):
        P = np.stack([np.full(n, x), r * np.sin(th), r * np.cos(th)], axis=1)
        for k, (cx, cy, cz) in enumerate(casing.get(str(j), [])):
            P[ks == k] = (cx, cy, cz)
            if k:
                P[ks == -k] = (cx, -cy, cz)
        rings.append(P)
    V = np.vstack([[[h["nose_tip_x_m"], 0.0, 0.0]], *rings, [[h["tail_centre_x_m"], 0.0, 0.0]]])
    idx = [np.arange(1 + j * n, 1 + (j + 1) * n) for j in range(len(rings))]
    quads = np.vstack([_quad_strip(idx[j], idx[j + 1], closed=True) for j in range(len(rings) - 1)])
    i = np.arange(n)
    tip, tail = 0, len(V) - 1
    F = np.vstack([
        _split_quads(V, quads),
        np.stack([np.full(n, tip), idx[0][(i + 1) % n], idx[0][i]], axis=1),
        np.stack([np.full(n, tail), idx[-1][i], idx[-1][(i + 1) % n]], axis=1),
    ])
    return V, _orient_outward(V, F)


def _build_revolution(p: dict) -> tuple[np.ndarray, np.ndarray]:
    """Body of revolution of an (x, r) profile about the x axis; r = 0 points are poles."""
    n = int(p["n_theta"])
    th = np.radians(p.get("theta0_deg", 0.0) + np.arange(n) * 360.0 / n)
    V, rows = [], []
    count = 0
    for x, r in p["profile"]:
        if r == 0.0:
            V.append([[x, 0.0, 0.0]])
            rows.append(np.array([count]))
            count += 1
        else:
            V.append(np.stack([np.full(n, x), r * np.sin(th), r * np.cos(th)], axis=1))
            rows.append(np.arange(count, count + n))
            count += n
    V = np.vstack(V)
    i = np.arange(n)
    F, quads = [], []
    for a, b in zip(rows[:-1], rows[1:]):
        if len(a) == 1:
            F.append(np.stack([np.full(n, a[0]), b[(i + 1) % n], b[i]], axis=1))
        elif len(b) == 1:
            F.append(np.stack([np.full(n, b[0]), a[i], a[(i + 1) % n]], axis=1))
        else:
            quads.append(_quad_strip(a, b, closed=True))
    if quads:
        F.append(_split_quads(V, np.vstack(quads)))
    F = np.vstack(F)
    return V, _orient_outward(V, F)


def _build_loft(stations: list) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric loft: stations of chord points [x, s, h] -> closed mesh in the local (x, s, t) frame."""
    V, up, lw = [], [], []
    for st in stations:
        u, lo = [], []
        for x, s, h in st:
            u.append(len(V))
            V.append((x, s, h))
            if h > 0.0:
                lo.append(len(V))
                V.append((x, s, -h))
            else:
                lo.append(u[-1])
        up.append(u)
        lw.append(lo)
    V = np.asarray(V, dtype=float)
    quads = []
    for j in range(len(stations) - 1):
        quads.append(_quad_strip(up[j], up[j + 1], closed=False))
        quads.append(_quad_strip(lw[j + 1], lw[j], closed=False))
    if any(h > 0.0 for _, _, h in stations[0]):       # ruled end face towards -s
        quads.append(_quad_strip(lw[0], up[0], closed=False))
    if any(h > 0.0 for _, _, h in stations[-1]):      # ruled end face towards +s
        quads.append(_quad_strip(up[-1], lw[-1], closed=False))
    return _clean(V, _split_quads(V, np.vstack(quads)))


def _clean(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge coincident vertices, drop degenerate triangles and coincident pairs (zero-thickness sheets),
    drop unused vertices, orient outward."""
    _, inv = np.unique(np.round(V, 9), axis=0, return_inverse=True)
    inv = inv.ravel()
    rep = np.zeros(inv.max() + 1, dtype=np.int64)
    rep[inv] = np.arange(len(V))
    V = V[rep]
    F = inv[F]
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    _, key, counts = np.unique(np.sort(F, axis=1), axis=0, return_inverse=True, return_counts=True)
    F = F[counts[key.ravel()] == 1]
    used, F = np.unique(F, return_inverse=True)
    F = F.reshape(-1, 3)
    V = V[used]
    return V, _orient_outward(V, F)


def _place(V: np.ndarray, F: np.ndarray, matrix, offset) -> tuple[np.ndarray, np.ndarray]:
    """v_body = M v_local + offset; an improper M (mirror) reverses the winding to keep normals outward."""
    M = np.asarray(matrix, dtype=float)
    W = V @ M.T + np.asarray(offset, dtype=float)
    return W, (F[:, ::-1].copy() if np.linalg.det(M) < 0 else F)
