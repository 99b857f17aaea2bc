"""``bb2-campaign --graph``: each run flies the full ROS 2 graph in lockstep (``bb2-launch``) on its own
``ROS_DOMAIN_ID``, records its bag, and its figures come from ``bb2-analyze`` of that bag.

The run's mission document is written to ``GRAPH_DIR/<index>/mission.yaml`` and the launcher runs with the
original mission's directory as its working directory (so the mission's relative files are found through the
schema's working-directory fallback); the bag goes to ``GRAPH_DIR/<index>/bag`` and the analysis to
``GRAPH_DIR/<index>/analysis``.  Each run's ``bb2-launch`` claims a free domain itself (lock files shared by every
launch on the machine), so runs in flight never share one with each other or with any other launch.  This module
starts subprocesses only; it imports no ROS itself.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import yaml

from bb2_tools.campaign.figures import END_STATUS, _mission_catalogue, json_safe
from bb2_tools.campaign.spec import CampaignSpec

__all__ = ["graph_figures", "run_graph_once"]


def graph_figures(figures_json: Path, names: tuple[str, ...]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The collected names from bb2-analyze's figures.json (same names as the MissionSummary fields;
    ``end_reason`` and ``completed`` from its ``end``), and that ``end`` (reason, t_s, completed, message)."""
    run = next(iter(json.loads(figures_json.read_text()).values()))
    f = dict(run["figures"])
    end = dict(run.get("end") or {})
    f.update({"end_reason": end.get("reason"), "completed": end.get("completed")})
    cat = _mission_catalogue()
    return {n: json_safe(f.get(cat[n][0])) for n in names}, end


def _tail(p: subprocess.CompletedProcess) -> str:
    lines = [x for x in (p.stdout or "").splitlines() + (p.stderr or "").splitlines() if x.strip()]
    return " ".join(lines[-1].split()) if lines else ""


def run_graph_once(spec: CampaignSpec, index: int, doc: dict[str, Any], graph_dir: str | Path,
                   timeout_s: float = 3600.0) -> tuple[str, str, dict[str, Any]]:
    """Fly one run through the graph; returns (status, message, figures)."""
    if spec.target != "mission":
        raise ValueError("--graph flies missions only (maneuvers have no graph)")
    run = Path(graph_dir) / f"{index:06d}"
    run.mkdir(parents=True, exist_ok=True)
    mission = run / "mission.yaml"
    mission.write_text(yaml.safe_dump(doc, sort_keys=False))
    cwd = spec.base_dir or os.getcwd()
    env = dict(os.environ)
    env.pop("ROS_DOMAIN_ID", None)
    bag = run / "bag"
    launch = subprocess.run([sys.executable, "-m", "bb2_tools.launcher", str(mission), "--mode", "lockstep",
                             "--out", str(bag), "--timeout", str(timeout_s)], cwd=cwd, env=env,
                            capture_output=True, text=True,
                            timeout=timeout_s + 120)
    (run / "launch.log").write_text((launch.stdout or "") + (launch.stderr or ""))
    figures: dict[str, Any] = {n: None for n in spec.collect}
    if not bag.exists():
        return "error", f"bb2-launch exited {launch.returncode} without a bag: {_tail(launch)}", figures
    analysis = run / "analysis"
    ana = subprocess.run([sys.executable, "-m", "bb2_tools.analyze", str(bag), "--mission", str(mission),
                          "--out", str(analysis)], cwd=cwd, env=env, capture_output=True, text=True,
                         timeout=timeout_s)
    (run / "analyze.log").write_text((ana.stdout or "") + (ana.stderr or ""))
    try:
        figures, end = graph_figures(analysis / "figures.json", spec.collect)
    except (OSError, ValueError, StopIteration, KeyError) as e:
        return "error", f"bb2-analyze exited {ana.returncode}, no figures ({type(e).__name__}: {e})", figures
    status = END_STATUS.get(str(end.get("reason")), "error")
    if status not in ("ok", "error"):  # the runner's own failure message
        return status, " ".join(str(end.get("message") or end["reason"]).split()), figures
    if launch.returncode != 0:
        return "error", f"bb2-launch exited {launch.returncode}: {_tail(launch)}", figures
    if status == "error":
        return "error", f"bb2-analyze found no end of the mission ({end!r})", figures
    return "ok", "", figures
