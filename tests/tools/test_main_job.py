"""The main job (``bash run.sh main``: ``python -m bb2_tools.main_job``): a mission through the whole graph,
recorded, analysed, and where everything is -- run here on a short mission named from another folder."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from rosenv import ros_env  # noqa: E402  (tests/rosenv.py)


@pytest.mark.ros
def test_the_main_job_flies_records_and_analyses_a_mission_named_from_the_callers_folder(tmp_path):
    """The launcher and the analysis run from the repository: a mission file and a bag folder named relative to
    the caller's folder were looked for there (the launcher: 'mission file short.yaml does not exist')."""
    pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) not installed")
    (tmp_path / "short.yaml").write_text("extends: straight\nname: straight_short\nduration_s: 4.0\n")
    p = subprocess.run([sys.executable, "-m", "bb2_tools.main_job", "--mission", "short.yaml", "--bag-dir", "runs"],
                       cwd=tmp_path, env=ros_env(), capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, (p.stdout[-3000:], p.stderr[-3000:])
    runs = list((tmp_path / "runs").glob("short_*"))
    assert len(runs) == 1, list((tmp_path / "runs").iterdir())
    run = runs[0]
    assert list(run.glob("*.mcap")) and (run / "metadata.yaml").is_file()
    (analysed,) = json.loads((run / "analysis" / "figures.json").read_text()).values()
    assert analysed["figures"]["mission_time_s"] == pytest.approx(4.0, abs=0.06), analysed
    assert "mission time 4.0" in p.stdout, p.stdout   # the summary printed from it
    assert (run / "analysis" / "report.html").is_file()
    assert f"bag (rosbag2 / MCAP): {run}" in p.stdout and "launcher exit 0, analysis exit 0" in p.stdout, p.stdout
