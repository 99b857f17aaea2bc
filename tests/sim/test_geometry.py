"""Hull geometry: generated BB2 surfaces, the authors' STL import, user surface sets, bad input."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from bb2_sim.frames import rotation_native
from bb2_sim.geometry import (PLANE_GROUPS, HullMeshError, HullSurfaces, generate_bb2_surfaces,
                              load_hull, load_surface_dir)

DATA = Path(__file__).resolve().parents[2] / "bb2_sim" / "data"
RHO, G = 1025.0, 9.81  # only to express the pressure check in newtons


# ------------------------------------------------------------------------------------------------
# helpers (test-only)
# ------------------------------------------------------------------------------------------------
def calm_water_buoyancy(s: HullSurfaces, z_cg: float, R: np.ndarray = np.eye(3),
                        deltas=(0.0,) * 5) -> np.ndarray:
    """[F, M] in body axes, moment about the CG: edge-midpoint pressure rule of SPEC 7.3, calm water,
    planes deflected by deltas (rad) as SPEC 7.2."""
    tris, areas = [s.fixed_vertices], [s.fixed_area_vectors]
    for i, (T, dA) in enumerate(zip(s.plane_vertices, s.plane_areas)):
        d = deltas[i]
        Rz = np.array([[np.cos(d), -np.sin(d), 0.0], [np.sin(d), np.cos(d), 0.0], [0.0, 0.0, 1.0]])
        RX, P = s.plane_hinge_rotations[i], s.plane_pivots[i]
        W = P + (T - P) @ (RX @ Rz @ RX.T).T
        cr = np.cross(W[:, 1] - W[:, 0], W[:, 2] - W[:, 0])
        tris.append(W)
        areas.append(dA[:, None] * cr / np.linalg.norm(cr, axis=1)[:, None])
    T, nA = np.concatenate(tris), np.concatenate(areas)
    mids = (0.5 * (T[:, 0] + T[:, 1]), 0.5 * (T[:, 0] + T[:, 2]), 0.5 * (T[:, 1] + T[:, 2]))
    p = [-RHO * G * (z_cg + m @ R[2]) for m in mids]
    F = -(nA * (p[0] + p[1] + p[2])[:, None]).sum(0) / 3.0
    M = np.cross(-(p[0][:, None] * mids[0] + p[1][:, None] * mids[1] + p[2][:, None] * mids[2]), nA).sum(0) / 3.0
    return np.concatenate([F, M])


def parts_of(s: HullSurfaces) -> dict[str, np.ndarray]:
    out, start = {}, 0
    for name, n in s.fixed_parts:
        out[name] = s.fixed_vertices[start:start + n]
        start += n
    out.update(zip(PLANE_GROUPS, s.plane_vertices))
    return out


def reference_stl_read(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Independent line-by-line ASCII STL reader (Python float of every token)."""
    rows = []
    for line in path.read_text().splitlines():
        tok = line.split()
        if tok and tok[0] in ("facet", "vertex"):
            rows.append([float(t) for t in tok[-3:]])
    raw = np.array(rows).reshape(-1, 4, 3)
    return raw[:, 0], raw[:, 1:]


@pytest.fixture(scope="module")
def generated() -> HullSurfaces:
    return generate_bb2_surfaces()


@pytest.fixture
def authors(shared) -> HullSurfaces:
    return load_hull(shared("bb2_rom", "surface"))


# ------------------------------------------------------------------------------------------------
# generated surfaces (no ../shared needed)
# ------------------------------------------------------------------------------------------------
def test_generated_parts_are_watertight_and_outward(generated):
    for name, T in parts_of(generated).items():
        m = trimesh.Trimesh(vertices=T.reshape(-1, 3), faces=np.arange(3 * len(T)).reshape(-1, 3), process=True)
        assert m.is_watertight and m.is_winding_consistent, name
        assert m.volume > 0.0, name


def test_generated_area_vectors_close_and_match_winding(generated):
    T = generated.fixed_vertices
    np.testing.assert_array_equal(generated.fixed_area_vectors, 0.5 * np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]))
    assert np.linalg.norm(generated.fixed_area_vectors.sum(0)) < 1e-9 * np.abs(generated.fixed_area_vectors).sum()
    for T, dA in zip(generated.plane_vertices, generated.plane_areas):
        assert T.shape == (len(dA), 3, 3) and np.all(dA > 0.0)


def test_generated_volume_matches_published_stl_figures(generated):
    ref = json.loads((DATA / "hull_geometry.json").read_text())["authors_stl_reference"]
    assert generated.volume() == pytest.approx(ref["total_volume_m3"], rel=2e-3)
    assert np.linalg.norm(generated.centroid() - ref["total_centroid_m"]) < 5e-3
    names = {"plane1": "stern_plane_1", "plane2": "stern_plane_2", "plane3": "stern_plane_3",
             "plane4": "stern_plane_4", "plane5": "sail_planes"}
    for part, v in generated.part_volumes().items():
        assert v == pytest.approx(ref["volumes_m3"][names.get(part, part)], rel=2e-3), part


def test_calm_water_buoyancy_is_rho_g_v_at_the_centroid(generated):
    """Divergence theorem check of the arrays as the ROM uses them: any depth, attitude and deflection."""
    V, c = generated.volume(), generated.centroid()
    for z, (phi, th, psi), dl in [(-60.0, (0.0, 0.0, 0.0), (0.0,) * 5),
                                  (-20.0, (0.2, -0.3, 1.0), (0.3, -0.2, 0.1, 0.35, -0.25))]:
        R = rotation_native(phi, th, psi)
        FM = calm_water_buoyancy(generated, z, R, dl)
        up = RHO * G * V * R[2]                      # earth +z in body axes
        # deflected planes rotate about their hinges: their volume is unchanged, the centroid moves
        np.testing.assert_allclose(FM[:3], up, rtol=0, atol=1e-9 * RHO * G * V)
        if not any(dl):
            np.testing.assert_allclose(FM[3:], np.cross(c, up), rtol=0, atol=1e-8 * RHO * G * V * 70.0)


def test_hinges_from_data(generated):
    geo = json.loads((DATA / "hull_geometry.json").read_text())
    L, x_ref = geo["stl_import"]["L_m"], geo["plane_pivot"]["x_ref_m"]
    for i, g in enumerate(PLANE_GROUPS):
        p = geo["planes"][g]
        np.testing.assert_array_equal(generated.plane_pivots[i],
                                      np.array(p["hinge_origin_nondim"]) * L - np.array([x_ref, 0.0, 0.0]))
        RX = generated.plane_hinge_rotations[i]
        np.testing.assert_allclose(RX @ RX.T, np.eye(3), atol=1e-15)
        axis = RX[:, 2]
        if g == "plane5":
            np.testing.assert_allclose(axis, [0.0, 1.0, 0.0], atol=1e-15)   # sail planes: +y
        else:   # stern planes: mirror images of each other, theta = -20 deg tilt of the X-tail axis
            assert abs(axis[0]) == pytest.approx(np.sin(np.radians(20.0)) * np.cos(np.radians(45.0)))
        # the pivot lies at the root of the moving surface, inside its bounding box (same frame and units)
        pts = generated.plane_vertices[i].reshape(-1, 3)
        assert np.all(generated.plane_pivots[i] > pts.min(0) - 0.1) and np.all(generated.plane_pivots[i] < pts.max(0) + 0.1)


def test_load_hull_caches_read_only_arrays():
    a = load_hull()
    assert load_hull(None) is a and load_hull("generated:offsets") is a
    assert a.source == "generated:offsets"
    with pytest.raises(ValueError):
        a.fixed_vertices[0, 0, 0] = 1.0


# ------------------------------------------------------------------------------------------------
# the authors' STL surfaces (../shared)
# ------------------------------------------------------------------------------------------------
def test_authors_import_is_bit_exact(shared, authors):
    """SPEC 7.1 import: float64 of the ASCII values x 70.2 - Xcg, file order, groups of geometry.json,
    fixed area vectors = |cross|/2 x file normal, plane areas = |cross|/2."""
    surf = shared("bb2_rom", "surface")
    geo = json.loads(shared("bb2_rom", "data", "geometry.json").read_text())
    const = json.loads(shared("bb2_rom", "data", "constants.json").read_text())
    L, xcg = const["L_m"], np.array(const["Xcg_m"])

    def read(files):
        n, t = zip(*(reference_stl_read(surf / f) for f in files))
        T = np.concatenate(t) * L - xcg
        return np.concatenate(n), T, 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)

    fixed_files = ["Hull.stl", "Sail.stl", "PropHub.stl", "TailPlaneRoots.stl"]
    n, T, dA = read(fixed_files)
    np.testing.assert_array_equal(authors.fixed_vertices, T)
    np.testing.assert_array_equal(authors.fixed_area_vectors, dA[:, None] * n)
    assert [c for _, c in authors.fixed_parts] == [2914, 564, 550, 904]
    for i in range(5):
        _, T, dA = read(geo["planes"][str(i + 1)]["stl_files"])
        np.testing.assert_array_equal(authors.plane_vertices[i], T)
        np.testing.assert_array_equal(authors.plane_areas[i], dA)
        P = np.array(geo["planes"][str(i + 1)]["hinge_origin_nondim"]) * L - [const["plane_pivot_reference_x_m"], 0, 0]
        np.testing.assert_array_equal(authors.plane_pivots[i], P)
    assert authors.n_triangles() == geo["surfaces"]["total_triangles"]
    assert authors.volume() == pytest.approx(4311.049, abs=1e-3)      # SPEC 7.1
    assert authors.centroid()[0] == pytest.approx(0.0, abs=1e-6)       # CG above CB (SPEC 1.2)


def test_generated_matches_authors_surfaces(generated, authors):
    """offsets_check.py targets: volume 0.2 %, centre of buoyancy 5 mm; per-part volumes; same hinges."""
    assert generated.volume() == pytest.approx(authors.volume(), rel=2e-3)
    assert np.linalg.norm(generated.centroid() - authors.centroid()) < 5e-3
    va, vg = authors.part_volumes(), generated.part_volumes()
    names = {"Hull.stl": "hull", "Sail.stl": "sail", "PropHub.stl": "prop_hub", "TailPlaneRoots.stl": "stern_plane_roots"}
    for part, v in va.items():
        assert vg[names.get(part, part)] == pytest.approx(v, rel=2e-3), part
    np.testing.assert_array_equal(generated.plane_pivots, authors.plane_pivots)
    np.testing.assert_array_equal(generated.plane_hinge_rotations, authors.plane_hinge_rotations)
    R = rotation_native(0.15, 0.2, 0.7)
    dl = (0.35, -0.35, 0.35, -0.35, -0.26)
    Fa, Fg = calm_water_buoyancy(authors, -30.0, R, dl), calm_water_buoyancy(generated, -30.0, R, dl)
    B = np.linalg.norm(Fa[:3])
    assert np.linalg.norm(Fg[:3] - Fa[:3]) < 2e-3 * B
    assert np.linalg.norm(Fg[3:] - Fa[3:]) < 5e-3 * B                   # lever arm within 5 mm


def test_authors_set_with_missing_plane_file(shared, tmp_path):
    surf = shared("bb2_rom", "surface")
    for p in surf.glob("*.stl"):
        if p.name != "SailPlanes1-mirrored.stl":
            (tmp_path / p.name).symlink_to(p)
    with pytest.raises(HullMeshError, match="SailPlanes1-mirrored.stl"):
        load_surface_dir(tmp_path)


def test_manifest_with_one_plane_half_is_not_closed(shared, tmp_path):
    surf = shared("bb2_rom", "surface")
    for p in surf.glob("*.stl"):
        (tmp_path / p.name).symlink_to(p)
    geo = json.loads((DATA / "hull_geometry.json").read_text())["authors_stl_files"]
    geo["plane3"] = geo["plane3"][:1]
    (tmp_path / "parts.yaml").write_text(json.dumps({"coordinates": "stl_nondim", **geo}))
    with pytest.raises(HullMeshError, match="plane3.*not closed"):
        load_surface_dir(tmp_path)


# ------------------------------------------------------------------------------------------------
# user surface sets (parts.yaml) and bad input
# ------------------------------------------------------------------------------------------------
def _write_set(generated: HullSurfaces, d: Path, fmt: str, scale: float = 1.0, shift=(0.0, 0.0, 0.0)) -> None:
    """Export the generated parts (one file per part) and a parts.yaml manifest."""
    groups: dict[str, list[str]] = {"fixed": []}
    for name, T in parts_of(generated).items():
        fn = f"{name}.{fmt}"
        W = (T + np.asarray(shift)) * scale
        trimesh.Trimesh(vertices=W.reshape(-1, 3), faces=np.arange(3 * len(T)).reshape(-1, 3),
                        process=False).export(str(d / fn))
        groups.setdefault(name if name.startswith("plane") else "fixed", []).append(fn)
    coords = "body_m" if scale == 1.0 else "stl_nondim"
    (d / "parts.yaml").write_text(json.dumps({"coordinates": coords, **groups}))


@pytest.mark.parametrize("fmt", ["stl", "obj"])
def test_user_set_with_manifest_round_trips(generated, tmp_path, fmt):
    _write_set(generated, tmp_path, fmt)
    s = load_surface_dir(tmp_path)
    assert s.source == str(tmp_path)
    assert s.n_triangles() == generated.n_triangles()
    assert [n for n, _ in s.fixed_parts] == [f"{n}.{fmt}" for n, _ in generated.fixed_parts]
    tol = 1e-5 if fmt == "stl" else 1e-9   # binary STL stores float32
    np.testing.assert_allclose(s.fixed_vertices, generated.fixed_vertices, atol=tol * 40)
    assert s.volume() == pytest.approx(generated.volume(), rel=tol)
    np.testing.assert_array_equal(s.plane_pivots, generated.plane_pivots)


def test_user_set_in_stl_coordinates(generated, tmp_path):
    xcg = json.loads((DATA / "hull_geometry.json").read_text())["stl_import"]["xcg_m"]
    _write_set(generated, tmp_path, "obj", scale=1.0 / 70.2, shift=xcg)
    s = load_surface_dir(tmp_path)
    # OBJ export keeps 8 decimals of the non-dimensional coordinates
    np.testing.assert_allclose(s.fixed_vertices, generated.fixed_vertices, atol=70.2e-8)
    assert s.volume() == pytest.approx(generated.volume(), rel=1e-6)


def _ascii_stl(T: np.ndarray, normals=None) -> str:
    out = ["solid t"]
    for i, t in enumerate(T):
        n = normals[i] if normals is not None else (0.0, 0.0, 0.0)
        out.append("facet normal {} {} {}\n outer loop".format(*n))
        out += ["  vertex {} {} {}".format(*v) for v in t]
        out.append(" endloop\nendfacet")
    return "\n".join(out + ["endsolid t\n"])


def _tetra() -> np.ndarray:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    return V[[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]]


def _manifest_dir(d: Path, fixed: str) -> None:
    T = _tetra()
    for i in range(1, 6):
        (d / f"p{i}.stl").write_text(_ascii_stl(T + [0.0, 0.0, 2.0 * i]))
    m = {"coordinates": "body_m", "fixed": [fixed], **{f"plane{i}": [f"p{i}.stl"] for i in range(1, 6)}}
    (d / "parts.yaml").write_text(json.dumps(m))


def test_small_manifest_set_loads_with_winding_normals(tmp_path):
    (tmp_path / "body.stl").write_text(_ascii_stl(_tetra() * 3.0))   # zero file normals -> winding
    _manifest_dir(tmp_path, "body.stl")
    s = load_surface_dir(tmp_path)
    assert s.volume() == pytest.approx(27.0 / 6.0 + 5.0 / 6.0)
    T = s.fixed_vertices
    np.testing.assert_allclose(s.fixed_area_vectors, 0.5 * np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]))


@pytest.mark.parametrize("content, match", [
    ("this is not a mesh", "body.stl"),
    (_ascii_stl(_tetra()).replace("vertex 1.0 0.0 0.0", "vertex nan 0.0 0.0", 1), "body.stl: non-finite"),
    (_ascii_stl(_tetra()).replace("vertex 1.0 0.0 0.0", "vertex 1.0 zero 0.0", 1), "body.stl"),
    ("solid empty\nendsolid empty\n", "body.stl"),
    (_ascii_stl(_tetra()[:3]), "fixed.*not closed"),
    (_ascii_stl(_tetra()[:, ::-1]), "fixed.*inwards"),
    (_ascii_stl(_tetra(), normals=-np.ones((4, 3)) / np.sqrt(3.0)), "disagree"),
])
def test_bad_files_raise_hull_mesh_error(tmp_path, content, match):
    (tmp_path / "body.stl").write_text(content)
    _manifest_dir(tmp_path, "body.stl")
    with pytest.raises(HullMeshError, match=match):
        load_surface_dir(tmp_path)


def test_bad_directories_raise_hull_mesh_error(tmp_path):
    with pytest.raises(HullMeshError, match="no surface files"):
        load_surface_dir(tmp_path)                                   # empty
    with pytest.raises(HullMeshError, match="not a directory"):
        load_surface_dir(tmp_path / "nope")
    (tmp_path / "Hull.stl").write_text(_ascii_stl(_tetra()))
    with pytest.raises(HullMeshError, match="missing surface files.*Sail.stl"):
        load_surface_dir(tmp_path)                                   # partial authors' set
    _manifest_dir(tmp_path, "body.stl")
    with pytest.raises(HullMeshError, match="body.stl: file not found"):
        load_surface_dir(tmp_path)
    (tmp_path / "parts.yaml").write_text("coordinates: body_m\nfixed: [Hull.stl]\n")
    with pytest.raises(HullMeshError, match="plane1"):
        load_surface_dir(tmp_path)                                   # manifest without planes
    (tmp_path / "parts.yaml").write_text("coordinates: inches\n")
    with pytest.raises(HullMeshError, match="coordinates"):
        load_surface_dir(tmp_path)
    assert issubclass(HullMeshError, ValueError)


def test_the_winding_sign_is_the_enclosed_volume_and_a_model_is_built_without_importing_trimesh(generated):
    """The mesh builders orient each part and the closure check tests the winding by the sign of the divergence
    theorem's sum (``_signed_volume``), which is trimesh's volume to rounding for every part, flipped with the
    winding.  Building the ROM (generated hull) then imports no trimesh: its import (scipy.spatial, sparse,
    ndimage ...) cost every simulator, launcher and ``bb2-sim`` process ~0.5 s of CPU, for a sign."""
    import subprocess
    import sys

    from bb2_sim.geometry import _signed_volume, _volume

    start = 0
    for _name, n in generated.fixed_parts:
        T = generated.fixed_vertices[start:start + n]
        start += n
        assert _signed_volume(T) > 0 and _signed_volume(T) == pytest.approx(_volume(T), rel=1e-9, abs=1e-9)
        assert _signed_volume(T[:, ::-1]) == pytest.approx(-_volume(T), rel=1e-9, abs=1e-9)
    for T in generated.plane_vertices:
        assert _signed_volume(T) == pytest.approx(_volume(T), rel=1e-9) and _signed_volume(T) > 0
    code = ("import sys\nfrom bb2_sim.model import BB2Model\nBB2Model()\n"
            "print(sorted(n for n in sys.modules if n.split('.')[0] == 'trimesh'))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "[]", (p.stdout, p.stderr)
