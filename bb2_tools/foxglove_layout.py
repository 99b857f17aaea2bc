"""The Foxglove layout shipped with the project: ``config/foxglove_layout.json`` (foxglove-sdk's layout JSON).

A 3-D view following ``base_link`` (the hull, the terrain, the sea from ``/bb2/scene/*``, the path, the sensor
frames) beside three plots on the header stamps (sim time): the path errors (``/bb2/guidance/path_error``), the
plane commands (``/bb2/planes/cmd``, delta1..delta5, rad) and the CG height (``/bb2/odom``, ENU z: minus the
depth).  The same layout serves a bag (*Open local file*) and the live bridge (``bb2-launch --foxglove``).
In Foxglove: *Layouts* -> *Import from file* -> the JSON.

The file is made by :func:`layout` with :mod:`foxglove.layouts`; regenerate it after a change::

    python -m bb2_tools.foxglove_layout            # writes config/foxglove_layout.json
    python -m bb2_tools.foxglove_layout --check    # exit 1 when the shipped file is not what layout() makes
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Sequence

from bb2_msgs_py.contract import SCENE_TOPIC, SEA_SURFACE_TOPIC

LAYOUT_FILE = Path(__file__).resolve().parents[1] / "config" / "foxglove_layout.json"

PATH_ERROR = "/bb2/guidance/path_error"
PLANES_CMD = "/bb2/planes/cmd"
ODOM = "/bb2/odom"
PATH = "/bb2/path"


def layout():
    """The layout (a :class:`foxglove.layouts.Layout`)."""
    from foxglove import layouts as fl

    def plot(title: str, series: list[tuple[str, str]], y_label: str):
        return fl.PlotPanel(title=title, config=fl.PlotConfig(
            paths=[fl.PlotSeries(value=v, label=label, timestamp_method="headerStamp") for v, label in series],
            y_axis_label=y_label, show_legend=True, legend_display="top", is_synced=True))

    markers = fl.BaseRendererRosMarkerTopicSettings(visible=True)
    view = fl.ThreeDeePanel(title="BB2: hull, terrain, sea, path", config=fl.ThreeDeeConfig(
        follow_tf="base_link", follow_mode="follow-position",
        topics={SCENE_TOPIC: markers, SEA_SURFACE_TOPIC: fl.BaseRendererRosMarkerTopicSettings(visible=True),
                PATH: fl.BaseRendererPosesTopicSettings(visible=True, type="line", line_width=0.5)},
        camera_state=fl.ThreeDeeCameraState(distance=160.0, perspective=True, phi=60.0, theta_offset=45.0)))
    plots = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(content=plot("path errors", [(f"{PATH_ERROR}.vector.y", "cross track (m, left)"),
                                                  (f"{PATH_ERROR}.vector.z", "vertical (m, up)")], "m")),
        fl.SplitItem(content=plot("plane commands", [(f"{PLANES_CMD}.position[{i}]", f"delta{i + 1} (rad)")
                                                     for i in range(5)], "rad")),
        fl.SplitItem(content=plot("depth", [(f"{ODOM}.pose.pose.position.z", "CG z (m, up: -depth)")], "m")),
    ])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=0.6, content=view), fl.SplitItem(proportion=0.4, content=plots)]))


def layout_json() -> str:
    """The layout as the file holds it (indented, one trailing newline)."""
    return json.dumps(json.loads(layout().to_json()), indent=2) + "\n"


def layout_topics(text: str) -> set[str]:
    """Every topic a layout JSON names (topic settings and message paths)."""
    doc = json.loads(text)
    found: set[str] = set()

    def walk(o) -> None:
        if isinstance(o, dict):
            for k, v in o.items():
                if k == "topics" and isinstance(v, dict):
                    found.update(v)
                walk(v)
        elif isinstance(o, list):
            for v in o:
                walk(v)
        elif isinstance(o, str) and o.startswith("/"):
            m = re.match(r"(/[A-Za-z0-9_/]+?)(?:\.|$)", o)
            if m:
                found.add(m.group(1))

    walk(doc)
    return found


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bb2_tools.foxglove_layout", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=LAYOUT_FILE, help=f"where to write it (default {LAYOUT_FILE})")
    p.add_argument("--check", action="store_true", help="only compare the file with what layout() makes")
    args = p.parse_args(argv)
    text = layout_json()
    if args.check:
        current = args.out.read_text() if args.out.is_file() else None
        if current != text:
            print(f"{args.out} is not the layout bb2_tools.foxglove_layout makes: regenerate it with "
                  f"`python -m bb2_tools.foxglove_layout`", file=sys.stderr)
            return 1
        print(f"{args.out}: up to date")
        return 0
    try:
        args.out.write_text(text)
    except OSError as exc:
        print(f"cannot write {args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
