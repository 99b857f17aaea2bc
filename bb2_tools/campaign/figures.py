"""The figures a campaign collects: names, types and values, from the same objects ``bb2-sim`` prints.

Missions: the fields of :class:`bb2_mission.summary.MissionSummary` (what ``bb2-sim mission`` prints, see
``MISSION_FIGURES``), by field name (``rms_vertical_m``) or by the name without its unit suffix
(``rms_vertical``).  Maneuvers: the fields of the maneuver's figures dataclass in :mod:`bb2_sim.metrics`
(what ``bb2-sim maneuver`` prints), in SI units and radians by field name (``steady_roll_rad``) or without the
unit suffix (``steady_roll``), and in the printed degrees as ``<stem>_deg`` / ``<stem>_deg_s``
(``steady_roll_deg``, ``steady_yaw_rate_deg_s``).  Tuples are stored as JSON text.  The column of a figure is
the name given in ``collect``.
"""
from __future__ import annotations

import json
import math
from dataclasses import fields
from typing import Any

from bb2_tools.campaign.errors import SpecError
from bb2_sim.names import unknown_keys_hint

__all__ = ["MISSION_FIGURES", "NAVIGATION_FIGURES", "END_STATUS", "MANEUVER_FIGURE_CLASSES", "resolve_collect",
           "figure_kinds", "mission_values", "maneuver_values", "json_safe"]

#: MissionSummary field -> what ``bb2-sim mission`` prints it as (the default ``collect`` of a mission, in order)
MISSION_FIGURES: dict[str, str] = {
    "mission_time_s": "mission time",
    "completed": "completed ('NOT completed' otherwise)",
    "end_reason": "end reason (finished, duration, grounded, ...)",
    "rms_vertical_m": "vertical path error RMS",
    "max_vertical_m": "vertical path error max",
    "rms_horizontal_m": "horizontal path error RMS",
    "max_horizontal_m": "horizontal path error max",
    "rms_vertical_closest_m": "vertical path error (closest point) RMS",
    "max_vertical_closest_m": "vertical path error (closest point) max",
    "rms_horizontal_closest_m": "horizontal path error (closest point) RMS",
    "max_horizontal_closest_m": "horizontal path error (closest point) max",
    "min_clearance_m": "minimum ground clearance (CG)",
    "min_clearance_t_s": "minimum ground clearance ... at t",
    "min_hull_clearance_m": "lowest hull point",
    "virtual_time_end_s": "virtual time",
}
#: MissionSummary fields a mission flown with ``navigation: sensors`` adds (collected when named; NaN on the truth)
NAVIGATION_FIGURES: dict[str, str] = {
    "rms_nav_error_m": "navigation: position estimate error RMS",
    "max_nav_error_m": "navigation: position estimate error max",
    "max_nav_heading_error_deg": "navigation: heading error max",
}
_MISSION_KINDS = {"completed": "bool", "end_reason": "str"}
#: a mission's end reason (bb2_mission.EndReason value) -> the run's status; any other end is an error
END_STATUS = {"finished": "ok", "duration": "ok", "grounded": "grounded", "broached": "broached",
              "diverged": "diverged"}

MANEUVER_FIGURE_CLASSES = {"self-propulsion": "SelfPropulsionFigures", "depth-heading": "DepthHeadingFigures",
                           "turning-circle": "TurningCircleFigures", "hzz": "ZigzagFigures",
                           "vzz": "ZigzagFigures", "open-loop": "OpenLoopFigures"}
_SUFFIX = {"rad": "_rad", "rad/s": "_rad_s", "m": "_m", "s": "_s", "m/s": "_m_s", "N": "_N", "N·m": "_Nm",
           "1/s": "_per_s"}
_DEG = {"rad": "_deg", "rad/s": "_deg_s"}


def _maneuver_catalogue(maneuver: str) -> dict[str, tuple[str, float, str]]:
    """collect name -> (field, factor, kind) for a maneuver's figures; the field names come first, in order."""
    from bb2_sim import metrics

    cls = getattr(metrics, MANEUVER_FIGURE_CLASSES[maneuver])
    primary: dict[str, tuple[str, float, str]] = {}
    alias: dict[str, tuple[str, float, str]] = {}
    for f in fields(cls):
        if not f.metadata:
            continue
        ann = str(f.type)
        kind = "json" if ann.startswith("tuple") else "str" if ann == "str" else "bool" if ann == "bool" else "float"
        primary[f.name] = (f.name, 1.0, kind)
        unit = f.metadata.get("unit", "")
        suf = _SUFFIX.get(unit)
        if suf and f.name.endswith(suf) and len(f.name) > len(suf):
            stem = f.name[: -len(suf)]
            alias.setdefault(stem, (f.name, 1.0, kind))
            if unit in _DEG:
                alias.setdefault(stem + _DEG[unit], (f.name, 180.0 / math.pi, kind))
    return {**primary, **{k: v for k, v in alias.items() if k not in primary}}


def _mission_catalogue() -> dict[str, tuple[str, float, str]]:
    out = {f: (f, 1.0, _MISSION_KINDS.get(f, "float")) for f in (*MISSION_FIGURES, *NAVIGATION_FIGURES)}
    for f in (*MISSION_FIGURES, *NAVIGATION_FIGURES):
        for suf in ("_m", "_s"):
            if f.endswith(suf):
                out.setdefault(f[: -len(suf)], (f, 1.0, _MISSION_KINDS.get(f, "float")))
    return out


def catalogue(target: str, maneuver: str | None) -> dict[str, tuple[str, float, str]]:
    return _mission_catalogue() if target == "mission" else _maneuver_catalogue(str(maneuver))


def resolve_collect(target: str, maneuver: str | None, names: list[str] | None) -> list[str]:
    """The collected figure names (validated); None = the whole summary (field names, in order)."""
    cat = catalogue(target, maneuver)
    if names is None:
        return list(MISSION_FIGURES) if target == "mission" else \
            [k for k, (f, fac, _) in cat.items() if k == f and fac == 1.0]
    bad = [n for n in names if n not in cat]
    if bad:
        what = "mission summary" if target == "mission" else f"{maneuver} figures"
        known = [k for k, (f, _, _) in cat.items() if k == f]
        raise SpecError(f"collect: unknown figure(s) {bad}{unknown_keys_hint(bad, cat)} of the {what}; known: "
                        f"{', '.join(known)}"
                        " (also without the unit suffix" + (", and *_deg for angles)" if target != "mission"
                                                             else ")"))
    return list(names)


def figure_kinds(target: str, maneuver: str | None, names: list[str] | tuple[str, ...]) -> dict[str, str]:
    cat = catalogue(target, maneuver)
    return {n: cat[n][2] for n in names}


def json_safe(v: Any) -> Any:
    """A value for the journal / table: NaN and inf become None; numpy scalars Python ones."""
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, (int,)):
        return int(v)
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    return x if math.isfinite(x) else None


def _scaled(v: Any, factor: float) -> Any:
    if isinstance(v, (tuple, list)):
        return [_scaled(x, factor) for x in v]
    if isinstance(v, (bool, str)) or v is None:
        return v
    try:
        return float(v) * factor if factor != 1.0 else float(v)
    except (TypeError, ValueError):
        return str(v)


def _value(raw: Any, factor: float, kind: str) -> Any:
    v = _scaled(raw, factor)
    if kind == "json":
        return json.dumps([json_safe(x) for x in v] if isinstance(v, list) else json_safe(v))
    if kind == "str":
        return None if v is None else str(v)
    if kind == "bool":
        return None if v is None else bool(v)
    return json_safe(v)


def mission_values(summary: Any, names: tuple[str, ...]) -> dict[str, Any]:
    cat = _mission_catalogue()
    return {n: _value(getattr(summary, cat[n][0]), cat[n][1], cat[n][2]) for n in names}


def unreached_values(maneuver: str, figures: Any, names: tuple[str, ...]) -> list[str]:
    """The collected names whose figure the run did not reach (:meth:`bb2_sim.metrics.Figures.unreached`)."""
    cat, missed = _maneuver_catalogue(maneuver), set(figures.unreached_fields())
    return [n for n in names if cat[n][0] in missed]


def maneuver_values(maneuver: str, figures: Any, names: tuple[str, ...]) -> dict[str, Any]:
    cat = _maneuver_catalogue(maneuver)
    if figures is None:
        return {n: None for n in names}
    return {n: _value(getattr(figures, cat[n][0]), cat[n][1], cat[n][2]) for n in names}
