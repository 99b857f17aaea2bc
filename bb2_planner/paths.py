"""Paths are data: Bernstein paths <-> JSON / YAML files, with validation and the shipped paths.

File format (``format: bb2_planner.bernstein_path``, ``version: 1``; JSON or YAML, same keys)::

    name: circle_r400
    description: free text
    frame: controller            # one of bernstein.FRAMES: native | controller | enu | ned
    units: {control_points: m, time: s}
    t0: 0.0                      # s
    tf: 500.0                    # s (Tf = tf - t0 > 0)
    degree: 99                   # optional; if present must equal len(control_points) - 1
    control_points: [[x, y, z], ...]   # metres, one row per point, in ``frame``
    provenance: {source: ..., construction: ..., carried_by: ...}
    facts: {...}                 # optional published figures used by tests

Every problem is reported as one :class:`PathError` (a ``ValueError``) naming the file and the fault.
Shipped paths live in ``bb2_planner/data/paths/`` and load by name: ``load_path("circle_r400")``.
"""
from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bb2_planner.bernstein import FRAMES, BernsteinPath, PathError
from bb2_sim.names import unknown_keys_hint
from bb2_sim.yaml_files import load as load_yaml

__all__ = ["PathError", "FORMAT", "DATA_DIR", "path_from_dict", "path_to_dict", "load_path",
           "save_path", "available_paths", "read_path_metadata"]

FORMAT = "bb2_planner.bernstein_path"
VERSION = 1
DATA_DIR = Path(__file__).resolve().parent / "data" / "paths"
_LENGTH_UNITS = {"m": 1.0}
_TIME_UNITS = {"s": 1.0}
_NUMBER_LIST = re.compile(r"\[\s*([-+0-9.eE]+(?:,\s*[-+0-9.eE]+)*)\s*\]")


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise PathError(f"{what} must be a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise PathError(f"{what} must be finite, got {value!r}")
    return x


PATH_KEYS = frozenset({"format", "version", "name", "description", "frame", "units", "t0", "tf", "degree",
                       "control_points", "provenance", "facts"})
"""The keys of a path document (the module docstring)."""


def path_from_dict(data: dict[str, Any], *, where: str = "path") -> BernsteinPath:
    """Validate a path document (see module docstring) and build the :class:`BernsteinPath`."""
    try:
        if not isinstance(data, dict):
            raise PathError(f"expected a mapping at the top level, got {type(data).__name__}")
        fmt = data.get("format", FORMAT)
        if fmt != FORMAT:
            raise PathError(f"format is {fmt!r}, expected {FORMAT!r}")
        if int(data.get("version", VERSION)) > VERSION:
            raise PathError(f"version {data.get('version')} is newer than this reader ({VERSION})")
        unknown = sorted(set(map(str, data)) - PATH_KEYS)
        if unknown:  # a typo (t_0, t_f) would be read as its default or as missing
            raise PathError(f"unknown key(s) {unknown}{unknown_keys_hint(unknown, PATH_KEYS)}; "
                            f"allowed: {sorted(PATH_KEYS)}")
        for key in ("frame", "tf", "control_points"):
            if key not in data:
                raise PathError(f"missing key {key!r}")
        units = data.get("units", {})
        lu, tu = units.get("control_points", "m"), units.get("time", "s")
        if lu not in _LENGTH_UNITS:
            raise PathError(f"control point unit {lu!r} not supported (use metres, 'm')")
        if tu not in _TIME_UNITS:
            raise PathError(f"time unit {tu!r} not supported (use seconds, 's')")
        frame = data["frame"]
        if frame not in FRAMES:
            raise PathError(f"unknown frame {frame!r}; expected one of {sorted(FRAMES)}")
        t0 = _number(data.get("t0", 0.0), "t0")
        tf = _number(data["tf"], "tf")
        if tf - t0 <= 0.0:
            raise PathError(f"Tf = tf - t0 must be > 0 s, got t0={t0}, tf={tf}")
        rows = data["control_points"]
        if not isinstance(rows, (list, tuple)) or len(rows) < 2:
            n = len(rows) if isinstance(rows, (list, tuple)) else rows
            raise PathError(f"control_points must be a list of at least two points, got {n!r}")
        dims = {len(r) if isinstance(r, (list, tuple)) else -1 for r in rows}
        if len(dims) != 1 or -1 in dims:
            raise PathError(f"control points have inconsistent dimensions {sorted(dims)}")
        d = dims.pop()
        if d != 3:
            raise PathError(f"control points must be 3-D (x, y, z), got {d} coordinates")
        pts = np.array([[_number(v, f"control_points[{i}][{j}]") for j, v in enumerate(r)]
                        for i, r in enumerate(rows)])
        pts *= _LENGTH_UNITS[lu]
        if "degree" in data and int(data["degree"]) != len(rows) - 1:
            raise PathError(f"degree {data['degree']} does not match {len(rows)} control points")
        return BernsteinPath(pts, t0 * _TIME_UNITS[tu], tf * _TIME_UNITS[tu], frame,
                             str(data.get("name", "")))
    except PathError as e:
        raise PathError(f"{where}: {e}") from None


def path_to_dict(path: BernsteinPath, *, provenance: dict[str, Any] | None = None,
                 description: str = "", facts: dict[str, Any] | None = None) -> dict[str, Any]:
    """The file document of a path (inverse of :func:`path_from_dict`)."""
    doc: dict[str, Any] = {
        "format": FORMAT, "version": VERSION, "name": path.name, "description": description,
        "frame": path.frame, "units": {"control_points": "m", "time": "s"},
        "t0": path.t0, "tf": path.tf, "degree": path.degree,
        "control_points": [[float(v) for v in row] for row in path.control_points],
        "provenance": dict(provenance or {}),
    }
    if facts:
        doc["facts"] = dict(facts)
    return doc


def _resolve(name_or_file: str | Path) -> Path:
    p = Path(name_or_file)
    if p.suffix in (".json", ".yaml", ".yml"):
        return p
    for ext in (".json", ".yaml", ".yml"):
        cand = DATA_DIR / f"{name_or_file}{ext}"
        if cand.exists():
            return cand
    raise PathError(f"no such path file or shipped path {str(name_or_file)!r} "
                    f"(shipped: {available_paths()})")


def read_path_metadata(name_or_file: str | Path) -> dict[str, Any]:
    """The raw document of a path file (provenance, facts...), parsed but not converted."""
    f = _resolve(name_or_file)
    try:
        text = f.read_text()
    except OSError as e:
        raise PathError(f"{f}: cannot read ({e.strerror})") from None
    try:
        return json.loads(text) if f.suffix == ".json" else load_yaml(text)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise PathError(f"{f}: not valid {f.suffix[1:].upper()} ({e})") from None


def load_path(name_or_file: str | Path, frame: str | None = None) -> BernsteinPath:
    """Load a path file (``.json``/``.yaml``) or a shipped path by name; optionally convert ``frame``."""
    f = _resolve(name_or_file)
    path = path_from_dict(read_path_metadata(f), where=str(f))
    return path if frame is None else path.to_frame(frame)


def save_path(path: BernsteinPath, file: str | Path, **meta: Any) -> Path:
    """Write ``path`` to ``file`` (format from the suffix: .json, .yaml or .yml); ``meta`` as in
    :func:`path_to_dict`.  Floats are written with full precision (round trip is exact)."""
    f = Path(file)
    doc = path_to_dict(path, **meta)
    if f.suffix == ".json":
        text = json.dumps(doc, indent=1)
        # one control point per line: collapse innermost lists of numbers
        text = _NUMBER_LIST.sub(lambda m: "[" + re.sub(r"\s*,\s*", ", ", m.group(1)) + "]", text)
        f.write_text(text + "\n")
    elif f.suffix in (".yaml", ".yml"):
        f.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))
    else:
        raise PathError(f"{f}: unknown path file type {f.suffix!r} (use .json, .yaml or .yml)")
    return f


def available_paths() -> list[str]:
    """Names of the paths shipped in ``bb2_planner/data/paths``."""
    return sorted(p.stem for p in DATA_DIR.glob("*") if p.suffix in (".json", ".yaml", ".yml"))
