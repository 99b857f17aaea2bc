"""Path files: shipped paths against the reference material, round trips and bad inputs."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bb2_planner.bernstein import BernsteinPath, derivative_points, elevate_points
from bb2_planner.paths import (PathError, available_paths, load_path, path_from_dict, path_to_dict,
                               read_path_metadata, save_path)


def test_shipped_paths_are_listed_and_valid():
    names = available_paths()
    assert {"circle_r400", "straight_line_x4000"} <= set(names)
    for n in names:
        meta = read_path_metadata(n)
        assert meta["provenance"]["source"], n
        P = load_path(n)
        assert P.degree == meta["degree"] and P.frame == meta["frame"]


def test_shipped_circle_matches_reference_samples(shared):
    csv = shared("bb2_control", "paths", "circle_r400_samples.csv")
    ref = np.loadtxt(csv, delimiter=",", skiprows=1)
    P = load_path("circle_r400")
    assert P.frame == "controller"                      # the reference samples are in frame C
    np.testing.assert_allclose(P(ref[:, 0]), ref[:, 1:4], atol=1e-5)      # CSV has 9 significant digits
    np.testing.assert_allclose(P.velocity(ref[:, 0]), ref[:, 4:7], atol=1e-7)


def test_shipped_circle_matches_reference_control_points(shared):
    src = json.loads(shared("bb2_control", "paths", "circle_r400.json").read_text())
    P = load_path("circle_r400")
    np.testing.assert_array_equal(P.control_points, np.array(src["control_points_xyz"]))
    assert (P.t0, P.tf) == (src["t0"], src["tf"])
    # the authors' derivative points: derivative then elevation back to N
    d = elevate_points(derivative_points(P.control_points, P.span), 1)
    np.testing.assert_allclose(d, np.array(src["derivative_control_points_xyz_degree_elevated"]), atol=1e-12)


def test_shipped_circle_facts_and_native_start():
    P = load_path("circle_r400")
    facts = read_path_metadata("circle_r400")["facts"]
    assert P.arc_length() == pytest.approx(facts["curve_length_m"], abs=0.01)
    assert P.length_bounds()[1] == pytest.approx(facts["control_polygon_length_m"], abs=0.01)
    v0 = P.velocity(0.0)
    assert np.degrees(np.arctan2(v0[1], v0[0])) == pytest.approx(facts["tangent_heading_at_start_deg"], abs=0.01)
    N = load_path("circle_r400", frame="native")
    np.testing.assert_allclose(N(0.0), [0.0, -400.0, -100.0], atol=1e-9)


def test_straight_line_is_straight():
    P = load_path("straight_line_x4000")
    t = np.linspace(P.t0, P.tf, 101)
    np.testing.assert_allclose(P(t)[:, 1:], [[0.0, -15.0]] * 101, atol=1e-9)
    np.testing.assert_allclose(P.speed(t), 8.0, rtol=1e-9)
    np.testing.assert_allclose(P.curvature(t), 0.0, atol=1e-12)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_round_trip(tmp_path, suffix):
    rng = np.random.default_rng(3)
    P = BernsteinPath(rng.normal(scale=1e3, size=(12, 3)), 1.5, 321.25, "ned", "random")
    f = save_path(P, tmp_path / f"p{suffix}", provenance={"source": "test"}, description="d")
    Q = load_path(f)
    np.testing.assert_array_equal(Q.control_points, P.control_points)
    assert (Q.t0, Q.tf, Q.frame, Q.name) == (P.t0, P.tf, P.frame, P.name)
    assert read_path_metadata(f)["provenance"] == {"source": "test"}


def good_doc():
    return path_to_dict(BernsteinPath([[0, 0, -50], [100, 0, -50], [200, 50, -60]], 0, 60, "native", "g"))


@pytest.mark.parametrize("edit, match", [
    (lambda d: d.update(control_points=[[0, 0, 0]]), "at least two"),
    (lambda d: d.update(control_points=[]), "at least two"),
    (lambda d: d["control_points"][1].__setitem__(1, float("nan")), "finite"),
    (lambda d: d["control_points"][1].__setitem__(1, float("inf")), "finite"),
    (lambda d: d["control_points"][1].__setitem__(1, "3"), "number"),
    (lambda d: d.update(tf=0.0), "Tf"),
    (lambda d: d.update(tf=-1.0), "Tf"),
    (lambda d: d.update(t0=70.0), "Tf"),
    (lambda d: d["control_points"][2].append(1.0), "inconsistent dimensions"),
    (lambda d: d.update(control_points=[[0, 0], [1, 1]]), "3-D"),
    (lambda d: d.update(frame="body"), "unknown frame"),
    (lambda d: d.update(degree=5), "degree"),
    (lambda d: d.pop("tf"), "missing key 'tf'"),
    (lambda d: d.update(units={"control_points": "ft"}), "unit"),
    (lambda d: d.update(format="other"), "format"),
    (lambda d: d.update(t_0=5.0), r"unknown key\(s\) \['t_0'\]"),   # it started at t0 = 0 without a word
    (lambda d: d.update(extra=1), r"unknown key\(s\) \['extra'\]; allowed: \['control_points'"),
])
def test_bad_documents(edit, match):
    doc = good_doc()
    path_from_dict(doc)                       # the unedited document is fine
    edit(doc)
    with pytest.raises(PathError, match=match):
        path_from_dict(doc, where="doc.json")


def test_bad_files(tmp_path):
    f = tmp_path / "broken.json"
    f.write_text("{not json")
    with pytest.raises(PathError, match="not valid JSON"):
        load_path(f)
    with pytest.raises(PathError, match="no such path"):
        load_path("no_such_path_name")
    with pytest.raises(PathError, match="cannot read"):
        load_path(tmp_path / "missing.yaml")
    with pytest.raises(PathError, match="unknown path file type"):
        save_path(load_path("circle_r400"), tmp_path / "x.txt")
