"""The one factory of a mission's pieces, shared by the library runner and the ROS nodes (no ROS).

:func:`mission_components` builds everything an in-process run needs (the ROM, the simulator at its initial
state, the control stack and the hull probes for the terrain checks).  A ROS node builds only its own piece
with the builders below, from the very same code, so both worlds start from identical objects:

=================  =====================================  =========================================
piece              builder                                who uses it
=================  =====================================  =========================================
ROM + simulator    :func:`build_model`, :func:`build_simulator`   simulator node, runner, replay
control stack      :func:`build_mission_stack`             path_following and l1_autopilot nodes
X-plane mixer      :func:`build_mixer`                     mixer node
initial state      :func:`initial_state`                   simulator node, runner
=================  =====================================  =========================================
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bb2_planner.terrain import Terrain

from bb2_mission.schema import RPS_PATH_MEAN_SPEED, Mission, MissionError, _resolve_stack, initial_state

__all__ = ["MissionComponents", "HullProbes", "mission_components", "check_initial_state", "stack_overrides",
           "initial_state", "terrain_elevation", "build_model", "build_simulator", "build_mission_stack", "build_mixer",
           "build_sensor_suite", "sensor_spec", "cg_clearance", "step_truths",
           "build_navigation_filter", "nominal_rps", "substeps_warning", "expected_speed",
           "mission_warnings"]


def stack_overrides(m: Mission, speed: bool = True) -> dict[str, Any]:
    """Overrides the mission applies to its stack: ``adaptation`` and, when ``rps`` is set, the speed.

    ``rps`` becomes the stack's feed-forward speed reference (v_ref = rps * advance) so that the stack's
    own output carries the propeller command, in-process and in ROS alike.  Build the stack with
    ``build_stack(m.stack, m.path, stack_overrides(m))``.  ``speed`` False: without it, for a piece that has no
    speed (the mixer: the path's mean speed is a quadrature whose scipy imports cost its process ~0.35 s of CPU).
    """
    over: dict[str, Any] = {"adaptation": bool(m.adaptation)}
    if m.rps is not None and speed:
        _, cfg = _resolve_stack(m.stack, m.adaptation, None)
        advance = float(cfg["speed"].get("advance_m_per_rev", 4.0))
        v_ref = m.path.arc_length() / m.path.span if m.rps == RPS_PATH_MEAN_SPEED else float(m.rps) * advance
        over["speed"] = {"v_ref_mps": float(v_ref)}
    return over


def terrain_elevation(terrain: Terrain, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear elevation of ``terrain`` at native (x, y), NaN off the grid (:meth:`Terrain.elevation_or_nan`):
    the per-tick clearance check uses it."""
    return terrain.elevation_or_nan(x, y)


class HullProbes:
    """Probe points of the hull (native body frame) for vertical clearance and broaching checks.

    The vertices of the convex hull of all surfaces (hull, sail, planes undeflected), thinned to one per
    ``cell_m`` cube; the sail top is the highest vertex.
    """

    def __init__(self, surfaces: Any, cell_m: float = 2.0) -> None:
        from scipy.spatial import ConvexHull

        V = np.concatenate([np.asarray(surfaces.fixed_vertices).reshape(-1, 3)]
                           + [np.asarray(v).reshape(-1, 3) for v in surfaces.plane_vertices])
        P = V[ConvexHull(V).vertices]
        _, keep = np.unique(np.floor(P / cell_m), axis=0, return_index=True)
        self.points_body = P[np.sort(keep)]                 #: (n, 3) m, native body
        self.sail_top_m = float(V[:, 2].max())              #: highest point above the CG, m
        self.keel_m = float(-V[:, 2].min())                 #: lowest point below the CG, m

    def world(self, x12: np.ndarray) -> np.ndarray:
        """Probe positions (n, 3) in the native earth frame for state x12; for states (N, 12) of N boats (N, n, 3),
        each boat's bit for bit its own call's (one matrix product per boat)."""
        from bb2_sim.frames import rotation_native

        R = rotation_native(x12[..., 3], x12[..., 4], x12[..., 5])
        if x12.ndim == 1:
            return x12[0:3] + self.points_body @ R.T
        return x12[:, None, 0:3] + np.matmul(self.points_body, R.transpose(2, 1, 0))


_PROBES: dict[int, tuple[Any, HullProbes]] = {}


def hull_probes(surfaces: Any) -> HullProbes:
    """The :class:`HullProbes` of ``surfaces``, built once per surfaces object (a convex hull: ~15 ms) and shared,
    read-only, by the missions on that model: a batch of missions then checks its clearances together."""
    hit = _PROBES.get(id(surfaces))
    if hit is not None and hit[0] is surfaces:
        return hit[1]
    probes = HullProbes(surfaces)
    probes.points_body.setflags(write=False)
    if len(_PROBES) >= 8:
        _PROBES.pop(next(iter(_PROBES)))
    _PROBES[id(surfaces)] = (surfaces, probes)
    return probes


@dataclass
class MissionComponents:
    """Everything an in-process run is built from (:class:`~bb2_mission.runner.MissionRunner`).

    ``model``/``simulator`` (at ``x0``, t = 0); ``stack`` (fresh, :func:`build_mission_stack`); the hull probes
    and the broaching limit.  The ROS nodes build the same pieces one at a time with the builders below.
    """

    mission: Mission
    model: Any
    simulator: Any
    stack: Any
    x0: np.ndarray
    probes: HullProbes
    max_cg_z_m: float


def mission_components(m: Mission, model: Any = None) -> MissionComponents:
    """Build the ROM (unless given), the simulator at x0, the stack and the hull probes for mission ``m``."""
    from bb2_sim.integrator import Simulator

    if model is None:
        model = build_model(m)
    stack = build_mission_stack(m)
    x0 = initial_state(m)
    probes = hull_probes(model.surfaces)
    max_z = check_initial_state(m, model.surfaces, probes)
    return MissionComponents(m, model, Simulator(model, x0, substeps=m.substeps), stack, x0, probes, float(max_z))


def broaching_limit(m: Mission, probes: HullProbes) -> float:
    """The highest CG z (native, m) before the mission broaches: ``limits.max_cg_z_m``, else the sail top at the calm
    surface."""
    return float(m.limits.max_cg_z_m if m.limits.max_cg_z_m is not None else -probes.sail_top_m)


def check_initial_state(m: Mission, surfaces: Any = None, probes: HullProbes | None = None) -> float:
    """Refuse a physically impossible start with one :class:`MissionError` line: the CG above the broaching
    limit (``limits.max_cg_z_m``; default the sail top at the calm surface, as the runner's broaching check) or
    a hull point inside the sea floor (the runner's hull clearance below zero).  Returns the broaching limit
    (max CG z, native, m).  ``surfaces`` default: the mission's hull (:func:`bb2_sim.geometry.load_hull`)."""
    if probes is None:
        if surfaces is None:
            from bb2_sim.geometry import load_hull

            surfaces = load_hull(m.hull)
        probes = hull_probes(surfaces)
    x0 = initial_state(m)
    where = str(m.source_file) if m.source_file else m.name
    max_z = broaching_limit(m, probes)
    if x0[2] > max_z:
        what = (f"puts the sail top {x0[2] + probes.sail_top_m:.2f} m above the calm surface (the sail top is "
                f"{probes.sail_top_m:.2f} m above the CG)" if m.limits.max_cg_z_m is None
                else f"is above limits.max_cg_z_m = {max_z:g} m")
        raise MissionError(f"{where}: the initial CG z = {x0[2]:.2f} m (depth {-x0[2]:.2f} m) {what}")
    if m.terrain is not None:
        pts = probes.world(x0)
        cl = pts[:, 2] - terrain_elevation(m.terrain, pts[:, 0], pts[:, 1])
        if np.isfinite(cl).any() and float(np.nanmin(cl)) < 0:
            raise MissionError(f"{where}: the initial state puts the hull {-float(np.nanmin(cl)):.2f} m inside "
                               f"the sea floor (CG at native x = {x0[0]:.1f}, y = {x0[1]:.1f}, z = {x0[2]:.1f} m)")
    return max_z




# ------------------------------------------------------------------------------------------ one piece each
def build_model(m: Mission, environment: Any = None) -> Any:
    """The ROM of mission ``m`` (hull, profile, sea and current; ``environment`` overrides the mission's)."""
    from bb2_sim.model import BB2Model
    from bb2_sim.parameters import load_parameters

    env = m.environment if environment is None else environment
    return BB2Model(m.hull, profile=m.profile, **env.model_kwargs(load_parameters()))


def build_simulator(m: Mission, model: Any = None) -> Any:
    """The ROM's fixed-step simulator at the mission's initial state (t = 0)."""
    from bb2_sim.integrator import Simulator

    model = build_model(m) if model is None else model
    check_initial_state(m, model.surfaces)
    return Simulator(model, initial_state(m), substeps=m.substeps)


def build_mission_stack(m: Mission) -> Any:
    """The mission's control stack (fresh), as the runner builds it."""
    from bb2_control.stacks import build_stack

    return build_stack(m.stack, m.path, stack_overrides(m))


def build_mixer(m: Mission) -> Any:
    """Only the X-plane mixer of the mission's stack (the mixer node's one piece)."""
    from bb2_control.stacks import build_mixer as stack_mixer

    return stack_mixer(m.stack, stack_overrides(m, speed=False))  # (the mixer has no speed)


def sensor_spec(m: Mission, suite: str = "") -> Any:
    """The sensors a run uses: the mission's ``sensors:`` block (``suite`` ""), none (``suite`` "none"), or the
    suite ``suite`` (tactical | mems | FILE) with the mission's seed and faults (a node's parameter)."""
    from bb2_sim.sensors.config import SensorSpec, load_suite_config

    if not suite:
        return m.sensors
    if suite.lower() == "none":
        return None
    base = m.source_file.parent if m.source_file is not None else None
    cfg = load_suite_config(suite, base_dir=base)
    spec = SensorSpec(cfg, m.sensors.seed if m.sensors else 0, m.sensors.faults if m.sensors else (), suite)
    present = cfg.sensors()
    for f in spec.faults:
        if f.sensor not in present:
            raise MissionError(f"sensors.faults names the {f.sensor}, which the suite {cfg.name!r} does not have")
    return spec


def build_sensor_suite(m: Mission, model: Any, sensors: Any = None) -> Any:
    """The mission's sensor suite (:class:`bb2_sim.sensors.SensorSuite`) in the sea and current of ``model``, or
    None without a ``sensors:`` block.  ``sensors`` (a :class:`bb2_sim.sensors.config.SensorSpec`) replaces the
    mission's (the simulator node's ``sensor_suite`` parameter)."""
    from bb2_sim.sensors import SensorSuite

    spec = m.sensors if sensors is None else sensors
    if spec is None:
        return None
    return SensorSuite.for_model(spec.suite, model, seed=spec.seed, faults=spec.faults)


def build_navigation_filter(suite: Any, simulator: Any) -> Any:
    """The vehicle's navigation filter (:class:`bb2_control.navigation.NavigationFilter`) on ``suite``'s sensors,
    started at the simulator's state and time, in its ROM's sea-water density and gravity (``navigation:
    sensors``; the simulator node and the runner alike)."""
    from bb2_control.navigation import NavigationFilter

    p = simulator.model.params
    return NavigationFilter(suite.config, simulator.x, t0=simulator.t, rho=float(p.rho), g=float(p.g))


def cg_clearance(terrain: Terrain | None, p_native: np.ndarray) -> float:
    """The CG's vertical clearance above ``terrain`` (m): the altimeter's truth; NaN without terrain or off its
    grid."""
    if terrain is None:
        return float("nan")
    try:
        return float(terrain.clearance(p_native))
    except ValueError:  # off the terrain grid
        return float("nan")


def step_truths(t_n: float, x_n: np.ndarray, xdot_n: np.ndarray, t_next: float, x_next: np.ndarray,
                terrain: Terrain | None, g: float) -> tuple[Any, Any]:
    """The truth the sensor suite samples over the ROM step ``[t_n, t_next)``: the state and its derivative at
    ``t_n`` (``StepRecord.ev.xdot``), the state at ``t_next``, the CG clearances (the simulator node and the
    runner alike)."""
    from bb2_sim.sensors.truth import truth_from_step

    return (truth_from_step(t_n, x_n, xdot_n, cg_clearance(terrain, np.asarray(x_n)[0:3]), g),
            truth_from_step(t_next, x_next, None, cg_clearance(terrain, np.asarray(x_next)[0:3]), g))


def substeps_warning(m: Mission, rps: float | None = None) -> str:
    """Before the flight: '' or one line when the mission's speed (its start, or the steady cruise of its nominal
    propeller command) is faster than its ``substeps`` fly steadily (:func:`bb2_sim.step_stability.speed_warning`).
    ``rps``: :func:`nominal_rps` of ``m`` when the caller has it already (rev/s); computed when None."""
    from bb2_sim.step_stability import speed_warning

    rps = nominal_rps(m) if rps is None else float(rps)
    return speed_warning(expected_speed(m, rps), m.substeps, "the mission's substeps:",
                         f"mission {m.name} ({rps:.2f} rps)")


def expected_speed(m: Mission, rps: float | None = None) -> float:
    """The speed mission ``m`` is expected to hold, m/s: its start, or the steady cruise of its nominal propeller
    command when faster (:func:`bb2_sim.step_stability.cruise_speed`; ``rps`` as in :func:`substeps_warning`)."""
    from bb2_sim.step_stability import cruise_speed

    rps = nominal_rps(m) if rps is None else float(rps)
    return max(float(np.linalg.norm(initial_state(m)[6:9])), cruise_speed(rps))


def mission_warnings(m: Mission, rps: float | None = None) -> list[str]:
    """What to say before mission ``m`` flies, one line each: faster than its sub-steps fly
    (:func:`substeps_warning`, ``rps`` as there) and a sea steeper than any deep-water wave
    (``bb2_sim.environment.SeaSpec.steepness_warning``).  ``[]`` when nothing is to be said."""
    return [w for w in (substeps_warning(m, rps), m.environment.sea.steepness_warning()) if w]


def nominal_rps(m: Mission) -> float:
    """The stack's feed-forward propeller command for mission ``m`` (rev/s): what the simulator holds
    before any propeller command has arrived."""
    from bb2_control.stacks import build_speed_command

    return float(build_speed_command(m.stack, stack_overrides(m)).step())
