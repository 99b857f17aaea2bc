"""bb2_mission: the mission layer, without ROS.

The mission file's schema (:mod:`~bb2_mission.schema`), the one factory of a mission's pieces shared by the
library runner and the ROS nodes (:mod:`~bb2_mission.components`), the closed-loop runner
(:mod:`~bb2_mission.runner`), the CSV record of a tick (:mod:`~bb2_mission.records`), the figures of a run
(:mod:`~bb2_mission.summary`) and the lockstep gate that the simulator node and the replayer share
(:mod:`~bb2_mission.lockstep_gate`).

It imports the numerical cores (bb2_control, bb2_planner, bb2_sim) and nothing above them: no rclpy, no
message packages.
"""
from bb2_mission.components import (HullProbes, MissionComponents, build_mission_stack, build_mixer, build_model,
                                    build_simulator, initial_state, mission_components, mission_warnings,
                                    nominal_rps, stack_overrides, substeps_warning, terrain_elevation)
from bb2_mission.records import MISSION_COLUMNS, MissionRow, read_mission_csv, rows_to_columns
from bb2_mission.runner import MissionResult, MissionRunner, MissionStep, run_mission
from bb2_mission.schema import (MISSIONS_DIR, InitialState, Limits, Mission, MissionError, load_mission,
                                mission_from_dict)
from bb2_mission.summary import EndReason, MissionEvent, MissionSummary, limit_event, path_errors_closest, summarize

__all__ = [
    "EndReason", "MissionError", "InitialState", "Limits", "Mission", "MissionComponents", "MissionStep",
    "MissionEvent", "MissionSummary", "MissionResult", "MissionRunner", "MissionRow", "HullProbes", "MISSION_COLUMNS",
    "MISSIONS_DIR", "load_mission", "mission_from_dict", "mission_components", "stack_overrides", "initial_state",
    "run_mission", "limit_event", "read_mission_csv", "rows_to_columns", "path_errors_closest", "terrain_elevation",
    "summarize",
    "build_model", "build_simulator", "build_mission_stack", "build_mixer", "nominal_rps", "substeps_warning",
    "mission_warnings",
]
