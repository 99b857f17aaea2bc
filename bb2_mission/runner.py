"""The closed-loop mission runner without ROS: ROM + Bernstein path + guidance/autopilot stack + terrain checks.

The tick (``Ts = 0.05 s``, the ROM's major step), which a ROS graph in lockstep reproduces exactly::

    state_n = VehicleState.from_vector(sim.t, sim.x)        # simulator -> odometry (native frames)
    out_n   = stack.step(state_n)                            # guidance -> L1 + autopilot -> mixer
    rec_n   = sim.step(out_n.planes_deg, out_n.rps)          # ROM ode3 step, commands held over [t_n, t_n+1)

The commands reach the ROM clamped to its plane and rps limits by the lockstep gate's rule
(:func:`~bb2_mission.lockstep_gate.clamp_planes_deg`), exactly as they do through the graph; the CSV keeps the
stack's own commands (``cmd_d*_deg``, ``rps_cmd``) and the actuator outputs (``d*_deg``, ``n_rps``).

The terrain checks (grounding, broaching) look at ``state_n`` before the ROM step; they never feed back
into the loop, so a ROS graph that omits them still produces the same trajectory.

With ``navigation: sensors`` the stack flies on the estimate of :class:`bb2_control.navigation.NavigationFilter`
instead of ``state_n``: the mission's sensor suite samples the truth of every step (as the simulator node does),
and the filter takes the samples of ``[t_n, t_n+1)`` after the ROM step, for the estimate at ``t_n+1``::

    est_n   = nav.state(t_n)                                 # from the samples out of the sensors before t_n
    out_n   = stack.step(est_n)
    rec_n   = sim.step(...)
    nav.update(suite.step(truth_n, truth_n+1))
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from bb2_planner.bernstein import BernsteinPath

from bb2_mission.components import mission_components, step_truths, terrain_elevation
from bb2_mission.lockstep_gate import clamp_planes_deg, clamp_rps
from bb2_mission.records import MissionRow, rows_to_columns
from bb2_mission.schema import Mission, load_mission
from bb2_mission.summary import EndReason, MissionEvent, MissionSummary, limit_event, navigation_errors, summarize

__all__ = ["MissionStep", "Tick", "MissionResult", "MissionRunner", "run_mission"]

RAD2DEG = 180.0 / math.pi
NAN5 = (math.nan,) * 5


@dataclass
class MissionStep:
    """One tick: the state at t_n, the stack output from it, the ROM's step record, the clearances."""

    state: Any                    #: VehicleState at t_n
    output: Any                   #: ControlOutput
    record: Any                   #: StepRecord (None if the tick stopped before the ROM step)
    terrain_z_m: float
    clearance_m: float
    hull_clearance_m: float
    row: MissionRow | None
    event: MissionEvent | None = None



@dataclass
class Tick:
    """A tick between :meth:`MissionRunner.begin_tick` and :meth:`MissionRunner.finish_tick`: the state at t_n,
    the estimate flown on, the stack's output, the clearances, the commands as the ROM takes them (clamped) and
    the event that ends the run before the ROM step (a limit; or, set by the stepper, the divergence)."""

    state: Any
    x: np.ndarray
    flown: Any
    output: Any
    terrain_z_m: float
    clearance_m: float
    hull_clearance_m: float
    planes_deg: np.ndarray
    rps: float
    event: MissionEvent | None = None


@dataclass
class MissionResult:
    mission: Mission
    traj: dict[str, np.ndarray]     #: MISSION_COLUMNS -> arrays (one entry per tick)
    summary: MissionSummary
    path_native: BernsteinPath

    @property
    def failed(self) -> bool:
        return self.summary.failed

    def divergence_hint(self, substeps_option: str) -> str:
        """'' or, after a divergence, the advice of more ROM sub-steps for a boat fast enough for the step to be
        unstable (:func:`bb2_sim.step_stability.substeps_hint`, naming ``substeps_option``, for the speed it held or
        the one it was heading for: :func:`bb2_mission.components.expected_speed`)."""
        if self.summary.end_reason is not EndReason.DIVERGED:
            return ""
        from bb2_mission.components import expected_speed
        from bb2_sim.step_stability import substeps_hint

        return substeps_hint(self.traj["t_s"], self.traj["U_m_s"], self.mission.substeps, substeps_option,
                             expected_speed(self.mission))


class MissionRunner:
    """Flies a mission tick by tick (see the module docstring for the tick).

    ``step()`` runs one tick; ``run()`` runs to the end (stack finished, duration, or a failure) and
    returns a :class:`MissionResult`.
    """

    def __init__(self, mission: Mission, model: Any = None) -> None:
        self.mission = mission
        self.c = mission_components(mission, model)
        self.sim, self.stack = self.c.simulator, self.c.stack
        self.terrain = mission.terrain
        self.n_steps = int(math.floor(mission.duration / self.sim.h + 1e-9))
        act = self.sim.model.params.act   # the commands reach the ROM clamped, as through the graph's gate
        self._plane_limit_deg = float(act["plane_limit_deg"])
        self._rps_limits = (float(act["rps_limits"][0]), float(act["rps_limits"][1]))
        self.done = False
        self.event: MissionEvent | None = None
        self.end_reason = EndReason.RUNNING
        self._last_out: Any = None
        self.suite = self.nav = None
        if mission.navigation == "sensors":
            from bb2_mission.components import build_navigation_filter, build_sensor_suite

            self.suite = build_sensor_suite(mission, self.sim.model)
            self.nav = build_navigation_filter(self.suite, self.sim)

    # -- terrain
    def _clearances(self, x: np.ndarray) -> tuple[float, float, float]:
        if self.terrain is None:
            return math.nan, math.nan, math.nan
        pts = self.probe_points(x)
        return self.clearances_at(pts, terrain_elevation(self.terrain, pts[:, 0], pts[:, 1]))

    def probe_points(self, x: np.ndarray) -> np.ndarray:
        """The CG and the hull probes (native earth, m) of state x: row 0 the CG.  For states (N, 12) of N boats
        with these probes: (N, 1 + probes, 3), each boat's its own call's."""
        return np.concatenate([x[..., None, 0:3], self.c.probes.world(x)], axis=-2)

    @staticmethod
    def clearances_at(pts: np.ndarray, zt: np.ndarray) -> tuple[Any, Any, Any]:
        """(terrain z under the CG, CG clearance, lowest hull point's clearance, NaN if none is over the terrain)
        from :meth:`probe_points` and the terrain elevation zt under them (the terrain's interpolation is point by
        point, so a batch of runners may evaluate it for all their points at once): floats, or arrays over the
        boats of stacked points (N, 1 + probes, 3) and elevations (N, 1 + probes)."""
        cl = pts[..., 2] - zt
        finite = np.isfinite(cl[..., 1:])
        hull = np.where(finite.any(axis=-1), np.where(finite, cl[..., 1:], np.inf).min(axis=-1), np.nan)
        if cl.ndim == 1:
            return float(zt[0]), float(cl[0]), float(hull)
        return zt[:, 0], cl[:, 0], hull

    def step(self) -> MissionStep:
        """One tick at t_n: stack output from the state, terrain checks, then the ROM step to t_n+1."""
        from bb2_sim.integrator import NonFiniteStateError

        tick = self.begin_tick()
        if isinstance(tick, MissionStep):
            return tick
        rec = None
        if tick.event is None:
            try:
                rec = self.sim.step(tick.planes_deg, tick.rps)
            except NonFiniteStateError as e:
                tick.event = MissionEvent(EndReason.DIVERGED, tick.state.t, tick.x[0:3].copy(), str(e))
        return self.finish_tick(tick, rec)

    def begin_tick(self, clearances: tuple[float, float, float] | None = None, state: Any = None
                   ) -> "Tick | MissionStep":
        """The tick's half before the ROM step: the state at t_n, the clearances, the stack's output and the
        limits.  Returns the :class:`Tick` (its commands clamped for the ROM, its ``event`` if a limit ends the
        run before the step), or the ended :class:`MissionStep` of a control error.  :meth:`step` is
        ``begin_tick``, the ROM step (unless ``event``), :meth:`finish_tick`; a batch of runners shares the
        middle (:mod:`bb2_mission.batch`), and may give the clearances of this state (as :meth:`_clearances`
        makes them) and the :class:`~bb2_sim.state.VehicleState` of the simulator's t and x (a new one if None)."""
        from bb2_control.errors import NonFiniteInputError, PathFollowingError
        from bb2_sim.state import VehicleState

        if self.done:
            raise RuntimeError("mission already ended")
        sim = self.sim
        x = sim.x.copy()
        if state is None:
            state = VehicleState.from_vector(sim.t, x)
        tz, cl, hull = self._clearances(x) if clearances is None else clearances
        flown = self.nav.state(sim.t) if self.nav is not None else state
        try:
            out = self.stack.step(flown)
        except (PathFollowingError, NonFiniteInputError) as e:
            event = MissionEvent(EndReason.CONTROL_ERROR, sim.t, x[0:3].copy(), str(e))
            self._end(event.kind, event)
            row = self._row(state, x, self._last_out, None, tz, cl, hull) if self._last_out else None
            return MissionStep(state, None, None, tz, cl, hull, row, self.event)
        self._last_out = out
        event = limit_event(self.mission.limits, self.c.max_cg_z_m, sim.t, x, hull, cl)
        return Tick(state, x, flown, out, tz, cl, hull, clamp_planes_deg(out.planes_deg, self._plane_limit_deg),
                    clamp_rps(out.rps, self._rps_limits), event)

    def finish_tick(self, tick: "Tick", rec: Any) -> MissionStep:
        """The tick's half after the ROM step (``rec`` its step record, None if it did not step): the sensors, the
        row, the end of the run."""
        state, x, out = tick.state, tick.x, tick.output
        if rec is not None and self.nav is not None:
            self._sense(state, x, rec)
        row = self._row(state, x, out, rec, tick.terrain_z_m, tick.clearance_m, tick.hull_clearance_m, tick.flown)
        event = tick.event
        if event is not None:
            self._end(event.kind, event)
        elif out.finished:
            self._end(EndReason.FINISHED, None)
        elif self.sim.n >= self.n_steps:
            self._end(EndReason.DURATION, None)
        return MissionStep(state, out, rec, tick.terrain_z_m, tick.clearance_m, tick.hull_clearance_m, row, event)

    def _end(self, reason: EndReason, event: MissionEvent | None) -> None:
        self.done, self.end_reason, self.event = True, reason, event

    def _sense(self, state: Any, x: np.ndarray, rec: Any) -> None:
        """The sensor samples of the step just integrated (``[t_n, t_n+1)``) into the navigation filter, from the
        truth exactly as the simulator node builds it."""
        a, b = step_truths(state.t, x, rec.ev.xdot, self.sim.t, self.sim.x, self.terrain,
                           float(self.sim.model.params.g))
        self.nav.update(self.suite.step(a, b))

    def _row(self, state: Any, x: np.ndarray, out: Any, rec: Any, tz: float, cl: float, hull: float,
             flown: Any = None) -> MissionRow:
        state_x = x
        x = x.tolist()                          # Python floats: the same values, cheaper to index
        # flight path angle of the earth velocity R v (R = Rz(psi) Ry(theta) Rx(phi)): Rz keeps its horizontal
        # norm, so atan2((R v)_z, |(Ry Rx v)_xy|)
        u_b, v_b, w_b = x[6], x[7], x[8]
        cf, sf, ct, st = math.cos(x[3]), math.sin(x[3]), math.cos(x[4]), math.sin(x[4])
        vy_rolled, vz_rolled = cf * v_b - sf * w_b, sf * v_b + cf * w_b
        fpa = math.degrees(math.atan2(-st * u_b + ct * vz_rolled, math.hypot(ct * u_b + st * vz_rolled, vy_rolled)))
        u = list(out.u_ad.values()) if out.u_ad else []
        u = (u + [math.nan, math.nan])[:2]
        cmd = out.planes_deg
        act = rec.act.planes_deg if rec is not None else NAN5
        xd, yd, zd = out.p_d_native
        nav_p = nav_psi = math.nan
        if flown is not None and flown is not state:  # the estimate's error
            e, dpsi = navigation_errors(flown.as_vector(), state_x)
            nav_p, nav_psi = float(e), float(dpsi)
        return MissionRow(
            t_s=state.t, x_m=x[0], y_m=x[1], z_m=x[2],
            phi_deg=x[3] * RAD2DEG, theta_deg=x[4] * RAD2DEG, psi_deg=x[5] * RAD2DEG,
            u_m_s=x[6], v_m_s=x[7], w_m_s=x[8],
            p_deg_s=x[9] * RAD2DEG, q_deg_s=x[10] * RAD2DEG, r_deg_s=x[11] * RAD2DEG,
            U_m_s=math.sqrt(x[6] ** 2 + x[7] ** 2 + x[8] ** 2), flight_path_angle_deg=fpa,
            q_c_rad_s=out.q_c, r_c_rad_s=out.r_c, q_up_ref_rad_s=out.q_up_ref, r_left_ref_rad_s=out.r_left_ref,
            z_ref_m=out.z_ref, psi_ref_deg=out.psi_ref * RAD2DEG, u_ad_1=u[0], u_ad_2=u[1],
            dV_deg=out.dV_deg, dH_deg=out.dH_deg,
            cmd_d1_deg=cmd[0], cmd_d2_deg=cmd[1], cmd_d3_deg=cmd[2], cmd_d4_deg=cmd[3], cmd_d5_deg=cmd[4],
            d1_deg=act[0], d2_deg=act[1], d3_deg=act[2], d4_deg=act[3], d5_deg=act[4],
            rps_cmd=out.rps, n_rps=rec.act.rps if rec is not None else math.nan,
            virtual_time_s=out.gamma, virtual_time_rate=out.gamma_dot, xd_m=xd, yd_m=yd, zd_m=zd,
            e_horizontal_m=out.e_horizontal_m, e_vertical_m=out.e_vertical_m,
            terrain_z_m=tz, clearance_m=cl, hull_clearance_m=hull,
            nav_position_error_m=nav_p, nav_heading_error_deg=nav_psi)

    def run(self, progress: Callable[[float], None] | None = None,
            on_row: Callable[[MissionRow], None] | None = None) -> MissionResult:
        """Fly to the end; ``on_row`` gets every CSV row as it is made, ``progress`` the time every 10 s."""
        rows: list[MissionRow] = []
        t0 = time.perf_counter()
        while not self.done:
            st = self.step()
            if st.row is not None:
                rows.append(st.row)
                if on_row:
                    on_row(st.row)
            if progress and self.sim.n % 200 == 0:
                progress(self.sim.t)
        wall = time.perf_counter() - t0
        traj = rows_to_columns(rows)
        path_native = self.mission.path.to_frame("native") if self.mission.path.frame != "native" \
            else self.mission.path
        return MissionResult(self.mission, traj, summarize(self, traj, path_native, wall), path_native)


def run_mission(m: Mission | str | Path, *, model: Any = None, progress: Callable[[float], None] | None = None,
                on_row: Callable[[MissionRow], None] | None = None) -> MissionResult:
    """Load (if needed) and fly a mission."""
    if not isinstance(m, Mission):
        m = load_mission(m)
    return MissionRunner(m, model).run(progress=progress, on_row=on_row)
