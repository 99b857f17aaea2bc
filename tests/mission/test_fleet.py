"""Issue 13, point 4: the fleet file (bb2_mission.fleet): several boats, each with its own mission."""
from __future__ import annotations

import numpy as np
import pytest

from bb2_mission.fleet import is_fleet_file, load_fleet
from bb2_mission.schema import MISSIONS_DIR, MissionError, initial_state, load_mission


def test_the_shipped_fleet_loads_every_boat_and_writes_missions_the_nodes_load_alike(tmp_path):
    f = load_fleet(MISSIONS_DIR / "fleets" / "canyon_pair.yaml")
    assert f.name == "canyon_pair" and list(f.boats) == ["boat1", "boat2"]
    assert f.boats["boat1"].mission.name == "canyon" and f.boats["boat2"].mission.name == "straight_offset"
    files = f.write_missions(tmp_path / "missions")
    assert files["boat1"] == MISSIONS_DIR / "canyon.yaml"  # no changes: the mission file itself, nothing written
    assert sorted(p.name for p in (tmp_path / "missions").iterdir()) == ["boat2.yaml"]
    boat2, straight = load_mission(files["boat2"]), load_mission(MISSIONS_DIR / "straight.yaml")
    x2, x0 = initial_state(boat2), initial_state(straight)
    assert np.array_equal(x2[:3] - x0[:3], [0.0, 50.0, 0.0]) and np.array_equal(x2[3:], x0[3:])
    assert boat2.path.control_points.tolist() == straight.path.control_points.tolist()
    assert is_fleet_file(MISSIONS_DIR / "fleets" / "canyon_pair.yaml") and not is_fleet_file(MISSIONS_DIR / "canyon.yaml")


def test_a_boat_of_its_own_names_files_relative_to_the_fleet_file(tmp_path):
    """A path file named in a boat's changes is found beside the fleet file, also once written elsewhere."""
    import json

    d = tmp_path / "plans"
    d.mkdir()
    (d / "mine.json").write_text(json.dumps({"name": "mine", "frame": "native", "tf": 100.0,
                                             "control_points": [[0.0, 0.0, -20.0], [200.0, 0.0, -20.0],
                                                                [400.0, 0.0, -20.0]]}))
    (d / "fleet.yaml").write_text("boats:\n  a1: straight\n  a2: {mission: straight, path: mine.json, "
                                  "duration_s: 5.0}\n")
    f = load_fleet(d / "fleet.yaml")
    assert f.name == "fleet" and f.boats["a2"].mission.path.name == "mine"
    m = load_mission(f.write_missions(tmp_path / "elsewhere")["a2"])
    assert m.path.name == "mine" and m.duration_s == 5.0


@pytest.mark.parametrize("text, why", [
    ("name: x\n", r"'boats' must map each boat's name to its mission"),
    ("boats: {b1: straight}\nvehicles: 2\n", r"unknown fleet key\(s\) \['vehicles'\]"),
    ("boats: {1boat: straight}\n", r"boat '1boat': a boat's name is its ROS namespace"),
    ("boats: {b1: nowhere}\n", r"boat 'b1': no mission 'nowhere'"),
    ("boats: {b1: {mission: straight, stak: x}}\n", r"boat 'b1': .*unknown key\(s\) \['stak'\]"),
    ("boats: {b1: {mission: straight, extends: canyon}}\n", r"boat 'b1': give the mission it starts from as 'mission'"),
    ("boats: [straight]\n", r"'boats' must map"),
    ("- a\n", r"a fleet file is a mapping"),
    # the fleet's bag directory is named for it: ../ wrote the bag outside --bag-dir
    ("name: ../../escape\nboats: {b1: straight}\n", r"bad.yaml: name must be a plain name .*got '../../escape'"),
    ("name: 1e3\nboats: {b1: straight}\n", r"name must be a text, got 1000.0 \(YAML read a float: put the name in"),
    # a boat's start is checked with its mission (bb2-launch started the other boats and failed this one, exit 1),
    # and said of the boat's mission, not of the temporary file it was loaded from
    ("boats: {b1: straight, b2: {mission: straight, initial: {offset_m: [0.0, 0.0, 1.0e4]}}}\n",
     r"^\S*bad.yaml: boat 'b2': its mission \(straight.yaml with the boat's changes\): the initial CG z = 9985.00 m "
     r"\(depth -9985.00 m\) puts the sail top 9996.40 m above the calm surface"),
    ("boats: {b1: {mission: straight, duration_s: -5}}\n",
     r"^\S*bad.yaml: boat 'b1': its mission \(straight.yaml with the boat's changes\): duration_s must be > 0 s"),
])
def test_a_bad_fleet_file_is_refused_naming_the_boat(tmp_path, text, why):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(MissionError, match=why):
        load_fleet(f)


def test_an_unreadable_file_is_no_fleet_file_and_says_why(tmp_path):
    f = tmp_path / "latin1.yaml"
    f.write_bytes("boats: {b\xe9: straight}\n".encode("latin-1"))
    assert not is_fleet_file(f) and not is_fleet_file(tmp_path / "none.yaml")
    with pytest.raises(MissionError, match="not a readable YAML file"):
        load_fleet(f)


def test_a_missing_fleet_file_is_said():
    with pytest.raises(MissionError, match="no fleet file at"):
        load_fleet("/nonexistent/fleet.yaml")
