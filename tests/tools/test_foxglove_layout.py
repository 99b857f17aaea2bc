"""The shipped Foxglove layout (config/foxglove_layout.json, made by bb2_tools.foxglove_layout with foxglove-sdk):
current, naming contract topics and message fields that exist, installed by bb2_bringup."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("foxglove.layouts")

from bb2_msgs_py.contract import SCENE_TOPIC, SEA_SURFACE_TOPIC, select_topics, topic  # noqa: E402
from bb2_tools.foxglove_layout import LAYOUT_FILE, layout_json, layout_topics  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def test_the_shipped_layout_is_what_the_tool_makes(tmp_path):
    assert LAYOUT_FILE.read_text() == layout_json()
    ok = subprocess.run([sys.executable, "-m", "bb2_tools.foxglove_layout", "--check"], cwd=REPO,
                        capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0 and "up to date" in ok.stdout, ok.stderr
    stale = tmp_path / "layout.json"
    stale.write_text(LAYOUT_FILE.read_text().replace("delta1", "delta_one"))
    bad = subprocess.run([sys.executable, "-m", "bb2_tools.foxglove_layout", "--check", "--out", str(stale)],
                         cwd=REPO, capture_output=True, text=True, timeout=60)
    assert bad.returncode == 1 and "regenerate it" in bad.stderr, (bad.stdout, bad.stderr)


def _resolve(msg, path: str):
    """The value of a Foxglove message path (``.a.b[2]``) on a message instance; AttributeError/IndexError if the
    message has no such field."""
    for name, index in re.findall(r"\.([A-Za-z_]\w*)(?:\[(\d+)\])?", path):
        msg = getattr(msg, name)
        if index:
            msg = list(msg)[int(index)] if len(msg) > int(index) else None
    return msg


def test_the_layout_names_contract_topics_and_fields_that_exist():
    pytest.importorskip("rclpy")
    from bb2_msgs_py import conversions as cv
    from bb2_msgs_py.contract import message_class
    from bb2_sim.state import VehicleState

    text = LAYOUT_FILE.read_text()
    topics = layout_topics(text)
    contract = {t.name for t in select_topics()}
    assert topics <= contract and {SCENE_TOPIC, SEA_SURFACE_TOPIC, "/bb2/path", "/bb2/odom"} <= topics, topics
    # every plotted message path resolves on a message of that topic's type, to a number
    import numpy as np

    samples = {"/bb2/odom": cv.state_to_odometry(VehicleState.from_vector(1.0, np.arange(12) * 0.1)),
               "/bb2/planes/cmd": cv.planes_message(1.0, [0.1, 0.2, 0.3, 0.4, 0.5])}
    values = re.findall(r'"value": "(/[^"]+)"', text)
    assert len(values) >= 8, values
    for v in values:
        name = re.match(r"(/[A-Za-z0-9_/]+?)\.", v).group(1)
        msg = samples.get(name) or message_class(topic(name).type)()
        got = _resolve(msg, v[len(name):])
        assert isinstance(got, float), (v, got)
    assert _resolve(samples["/bb2/planes/cmd"], ".position[4]") == 0.5
    # the 3-D view follows the vehicle
    assert '"followTf": "base_link"' in text
    doc = json.loads(text)
    assert doc["content"]["type"] == "split"


def test_bb2_bringup_installs_the_layout():
    setup = (REPO / "bb2_ros_ws" / "src" / "bb2_bringup" / "setup.py").read_text()
    assert "'config/foxglove_layout.json'" in setup
    assert (REPO / "bb2_ros_ws" / "src" / "bb2_bringup" / "config" / "foxglove_layout.json").resolve() == LAYOUT_FILE
