"""``bb2-launch``, the command: a mission file flies one boat's graph (:mod:`bb2_tools.launcher`), a fleet file
(:mod:`bb2_mission.fleet`) every boat of the fleet beside one recorder for all (:mod:`bb2_tools.fleet_launcher`).

``python -m bb2_tools.launch_cli`` is the same command; ``python -m bb2_tools.launcher`` takes a mission file only.
"""
from __future__ import annotations

import sys
from typing import Sequence

from bb2_sim.outputs import run_cli

from bb2_tools import launcher


def main(argv: Sequence[str] | None = None) -> int:
    """Console script ``bb2-launch`` (exit codes as :func:`bb2_tools.launcher.main`)."""
    from bb2_mission.fleet import is_fleet_file

    argv = list(sys.argv[1:] if argv is None else argv)
    args = launcher.parse_args(argv)  # --help and option errors: the launcher's
    if args.mission is not None and not args.install_ros_ws and is_fleet_file(args.mission):
        return run_cli("bb2-launch", lambda: _fleet(args))
    return launcher.main(argv)


def _fleet(args) -> int:
    from bb2_msgs_py.ros_env import ros_environment_or_error

    from bb2_tools.fleet_launcher import run_fleet

    if (bad := ros_environment_or_error("bb2-launch")) is not None:  # called directly: find ROS itself
        return bad
    return run_fleet(args)


if __name__ == "__main__":
    sys.exit(main())
