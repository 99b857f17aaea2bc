"""The fleet file: several boats in one graph, each with its own mission (no ROS).

Fleet file (YAML; ``boats`` required, unknown keys are an error)::

    name: canyon_pair                  # default: file stem; one file name (it names the bag directory)
    description: free text
    boats:                             # namespace -> its mission, in launch order
      boat1: canyon                    #   a mission: a shipped name (missions/) or a file (relative to this file)
      boat2:                           #   or a mission with what this boat changes in it:
        mission: canyon                #     the mission it starts from (as above)
        name: canyon_offset            #     then any mission key (bb2_mission.schema), merged as ``extends`` does
        initial: {offset_m: [0.0, 40.0, 0.0]}

A boat's name is its ROS namespace (``/boat1``: its nodes, ``/boat1/bb2/odom``, ``/boat1/clock``, frames
``boat1/base_link``), so it is letters, digits and ``_``, starting with a letter.  Each boat's mission is loaded and
checked when the fleet is (:func:`load_fleet`), its start too (above the surface, inside the sea floor:
:func:`bb2_mission.components.check_initial_state`): a bad boat is an error naming the boat.  Files named inside a
boat's changes (a path or terrain file) are relative to the fleet file.  :meth:`Fleet.write_missions` writes every
boat's mission as a mission file of its own (``extends`` the one it starts from), what the graph's nodes read.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bb2_mission.schema import (MISSIONS_DIR, Mission, MissionError, is_bare_name, load_mission, mission_file,
                                shipped_missions, shipped_name_hint)
from bb2_sim.names import unknown_keys_hint
from bb2_sim.outputs import plain_name
from bb2_sim.yaml_files import load as load_yaml

__all__ = ["FleetBoat", "Fleet", "load_fleet", "is_fleet_file"]

BOAT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_TOP_KEYS = {"name", "description", "boats"}
_PATH_KEYS = ("path", "terrain", "hull", "stack", "sensors")  # mission keys that may name a file


@dataclass(frozen=True)
class FleetBoat:
    """One boat of a fleet: its name (namespace), the mission file it starts from and what it changes in it."""

    name: str
    base: Path
    changes: dict[str, Any]
    mission: Mission

    def mission_document(self, fleet_dir: Path) -> dict[str, Any]:
        """The boat's mission file content (:func:`_mission_document`)."""
        return _mission_document(self.base, self.changes, fleet_dir)


def _mission_document(base: Path, changes: dict[str, Any], fleet_dir: Path) -> dict[str, Any]:
    """A boat's mission file content: ``extends`` its base; the files its changes name made absolute."""
    doc: dict[str, Any] = {"extends": str(base)}
    for key, value in changes.items():
        if key in _PATH_KEYS and isinstance(value, str) and (fleet_dir / value).exists():
            value = str((fleet_dir / value).resolve())
        doc[key] = value
    return doc


@dataclass(frozen=True)
class Fleet:
    """A fleet file, loaded: every boat's mission checked."""

    name: str
    description: str
    file: Path
    boats: dict[str, FleetBoat]

    def write_missions(self, out_dir: str | Path) -> dict[str, Path]:
        """Every boat's mission as a file of its own, ``out_dir/<boat>.yaml`` (a boat without changes: its
        mission file itself, nothing written); returns boat -> mission file."""
        out, files = Path(out_dir), {}
        for name, boat in self.boats.items():
            if not boat.changes:
                files[name] = boat.base
                continue
            out.mkdir(parents=True, exist_ok=True)
            f = out / f"{name}.yaml"
            f.write_text(f"# boat {name} of fleet {self.name} ({self.file})\n"
                         + yaml.safe_dump(boat.mission_document(self.file.parent), sort_keys=False))
            files[name] = f
        return files


def _read(file: Path) -> dict[str, Any]:
    try:
        doc = load_yaml(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MissionError(f"no fleet file at {file}") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise MissionError(f"{file}: not a readable YAML file (UTF-8): {exc}") from None
    if not isinstance(doc, dict):
        raise MissionError(f"{file}: a fleet file is a mapping with 'boats', got {type(doc).__name__}")
    return doc


FLEETS_DIR = MISSIONS_DIR / "fleets"
"""The shipped fleet files (``canyon_pair``)."""


def shipped_fleets() -> list[str]:
    """The names of the shipped fleets (``missions/fleets/*.yaml`` without .yaml)."""
    return sorted(f.stem for f in FLEETS_DIR.glob("*.yaml"))


def run_file(value: str | Path) -> Path:
    """What ``bb2-launch`` flies: a mission or fleet file, or the name of a shipped mission or fleet (``canyon``,
    ``canyon_pair``: ``bb2-sim mission canyon`` and ``ros2 launch ... mission:=canyon`` take the name too) when no
    such file is here.  A file that is not there stays as given (its check says so, with :func:`run_file_hint`)."""
    f = mission_file(value)  # a file here, else a shipped mission of that name
    if f.exists() or not is_bare_name(value):
        return f
    fleet = FLEETS_DIR / f"{value}.yaml"
    return fleet if fleet.is_file() else f


def run_file_hint(value: str | Path) -> str:
    """For a run file that does not exist: the likely shipped mission or fleet name and the shipped ones."""
    return shipped_name_hint(value, sorted({*shipped_missions(), *shipped_fleets()}), "missions and fleets")


def is_fleet_file(file: str | Path) -> bool:
    """Whether ``file`` is a fleet file (a YAML mapping with ``boats``) rather than a mission file (False for a file
    that is neither, or unreadable: the mission loader then says why)."""
    try:
        return "boats" in _read(Path(file))
    except MissionError:
        return False


def _mission_file(value: Any, base_dir: Path, where: str) -> Path:
    if not isinstance(value, str) or not value.strip():
        raise MissionError(f"{where}: a mission name or file, got {value!r}")
    for f in (base_dir / value, MISSIONS_DIR / value, MISSIONS_DIR / f"{value}.yaml"):
        if f.is_file():
            return f.resolve()
    raise MissionError(f"{where}: no mission {value!r} (neither a file beside the fleet file nor a shipped mission "
                       f"in {MISSIONS_DIR})")


def load_fleet(file: str | Path) -> Fleet:
    """Load a fleet file and every boat's mission; :class:`MissionError` naming the boat when one is wrong."""
    f = Path(file)
    doc = _read(f)
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise MissionError(f"{f}: unknown fleet key(s) {sorted(unknown)}{unknown_keys_hint(unknown, _TOP_KEYS)} "
                           f"(known: {sorted(_TOP_KEYS)})")
    boats_doc = doc.get("boats")
    if not isinstance(boats_doc, dict) or not boats_doc:
        raise MissionError(f"{f}: 'boats' must map each boat's name to its mission, got {boats_doc!r}")
    boats: dict[str, FleetBoat] = {}
    for name, value in boats_doc.items():
        where = f"{f}: boat {name!r}"
        if not isinstance(name, str) or not BOAT_NAME.fullmatch(name):
            raise MissionError(f"{where}: a boat's name is its ROS namespace: letters, digits and '_', starting with "
                               "a letter")
        if isinstance(value, dict):
            changes = dict(value)
            base = _mission_file(changes.pop("mission", None), f.parent, f"{where}: mission")
            if "extends" in changes:
                raise MissionError(f"{where}: give the mission it starts from as 'mission', not 'extends'")
        else:
            base, changes = _mission_file(value, f.parent, where), {}
        try:
            mission = _load_boat(name, base, changes, f)
        except MissionError as exc:
            raise MissionError(f"{where}: {exc}") from None
        boats[name] = FleetBoat(name, base, changes, mission)
    try:
        name = plain_name(doc.get("name", f.stem), f"{f}: name")  # the fleet's bag directory is named for it
    except ValueError as exc:
        raise MissionError(str(exc)) from None
    return Fleet(name, str(doc.get("description", "")), f.resolve(), boats)


def _load_boat(name: str, base: Path, changes: dict[str, Any], fleet_file: Path) -> Mission:
    """The boat's mission as the nodes will load it (its mission document, written beside nothing: loaded from a
    temporary file so ``extends`` and the files resolve exactly as they will)."""
    from bb2_mission.components import check_initial_state

    if not changes:
        m = load_mission(base)
        check_initial_state(m)
        return m
    import tempfile

    with tempfile.TemporaryDirectory(prefix="bb2_fleet_") as tmp:
        t = Path(tmp) / f"{name}.yaml"
        t.write_text(yaml.safe_dump(_mission_document(base, changes, fleet_file.parent), sort_keys=False))
        try:
            m = load_mission(t)
            check_initial_state(m)   # a start above the surface or in the sea floor: refused before any boat flies
        except MissionError as exc:  # the temporary file is no name for the user: the boat's changes are
            raise MissionError(str(exc).replace(f"{t}: ", f"its mission ({base.name} with the boat's changes): ")
                               .replace(str(t), f"its mission ({base.name} with the boat's changes)")) from None
        return m
