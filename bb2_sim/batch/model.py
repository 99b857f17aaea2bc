"""One evaluation of the BB2 ROM for N boats of the same hull at once (twin of :meth:`bb2_sim.model.BB2Model.evaluate`).

The boats share the model's hull, parameters, tables, physics profile and trimmed mass; each has its own state,
held actuator outputs, Derivative-block memory and regular wave (:class:`bb2_sim.waves.Wave`, e.g. different sea
states). Every step of the scalar evaluation is followed in the same order on arrays over boats, so a boat's
results equal its single evaluation to round-off: bit for bit in the tables, flow angles, planes, hull, propeller
and the buoyancy; within an ulp where the scalar code multiplies small matrices with BLAS (kinematics) or where
the batch folds the small plane blocks of the pressure integral; to round-off in the added mass, whose Derivative
blocks (linear) differentiate the motion and the sections' wave velocities instead of the sections' relative
velocities (:class:`.memory.BatchAddedMassMemory`; ``exact``: section by section). The boats in a sea take the
scalar code's orbital velocities (on arrays over boats, bit for bit) and its pressure integral bit for bit, its
per-point pass boat by boat (that work does not vectorise over boats with profit); with free-surface clipping every
boat runs the scalar pressure code itself.

Irregular (component) seas and currents go per boat (``seas=``, ``currents=``): for those boats the water's
velocity at the flow points, the velocity relative to the water and, in a component sea, the pressure integral are
the scalar code's own (:mod:`.environment`: each sea's grid pass, and a current, boat by boat, each sea with its own
wave-load grid), everything else is the batch's: bit for bit the single runs in the exact mode, as for the authors'
seas. The model
itself must be calm (``BB2Model(sea=...)`` or a current on it is refused: give them per boat).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..frames import rotation_native
from ..model import BB2Model
from ..propeller import PropellerLoad
from ..waves import Wave, wave_for_sea_state
from . import libm
from .actuators import BatchActuatorOutputs
from .environment import BatchEnvironment
from .hull import hull_loads
from .lookup import BatchRomTables, Segments
from .memory import AddedMassInputs, BatchAddedMassMemory, BatchDerivativeMemory
from .planes import plane_flow, plane_loads
from .pressure import BatchPressure
from .propeller import propeller_load
from .rigid_body import kinematics, rigid_body_acceleration
from .waves import BatchWaves

RAD2DEG = 180.0 / np.pi
FLOW_ANGLE_GUARD_M_S = 1e-8
"""|ue| at or below which the flow angles are +-90 deg (the guard of :meth:`BB2Model.evaluate`)."""
FLOW_ANGLE_AT_GUARD_DEG = 90.0


@dataclass
class BatchEvaluation:
    """What one batch evaluation produces, per boat (rows), native body axes, SI; flow angles in degrees."""

    xdot: np.ndarray            # (n, 12)
    forces: np.ndarray          # (n, 6) total external load [X, Y, Z, K, M, N]
    added_mass_inputs: np.ndarray | AddedMassInputs  # what the added-mass Derivative blocks differentiate
    # (exact: the sections' relative velocities (n, 15, 3), as the scalar code)
    alpha_deg: np.ndarray       # (n,)
    beta_deg: np.ndarray        # (n,)
    U: np.ndarray               # (n,)
    prop: PropellerLoad         # fields (n,)
    hydrostatic: np.ndarray     # (n, 6) pressure-integral loads
    added_mass: np.ndarray      # (n, 6)
    planes_eff_deg: np.ndarray  # (n, 5) effective deflections dX + aX


class BatchModel:
    """The ROM of ``model`` for N boats, each with its own regular wave, irregular sea and current.

    ``waves``: one :class:`Wave` per boat (calm: ``Wave()``), or None for ``n_boats`` boats in the model's own
    sea state. ``seas``: one :class:`bb2_sim.sea.Sea` or None per boat (as ``BB2Model(sea=...)``: an
    :class:`~bb2_sim.sea.AuthorsTableSea` is its regular wave, a calm sea none; a boat with a sea has a calm
    ``waves`` entry); ``currents``: one :class:`bb2_sim.current.Current` or None per boat. The model's hull,
    parameters, tables, profile (every switch is supported) and mass are shared; the model itself is calm.
    ``exact``: the pressure integral's plane blocks follow the scalar code's kernels too, and the flow angles, plane
    incidences and weight components take the C library's functions as the scalar code does (:mod:`.libm`): bit
    for bit the single evaluation (about twice the cost per boat).
    """

    def __init__(self, model: BB2Model, waves: Sequence[Wave] | None = None, *, n_boats: int | None = None,
                 exact: bool = False, seas: Sequence | None = None, currents: Sequence | None = None):
        if model.sea is not None:
            raise ValueError("batch: the model must be calm: give each boat its sea (seas=[...])")
        if model.current is not None:
            raise ValueError("batch: the model must have no current: give each boat its current (currents=[...])")
        if waves is None and n_boats is None:
            n_boats = next((len(a) for a in (seas, currents) if a is not None), None)
        if waves is None:
            if n_boats is None or int(n_boats) < 1:
                raise ValueError("batch: give the waves of the boats or n_boats >= 1")
            waves = [model.wave] * int(n_boats)
        else:
            waves = list(waves)
            if not waves or (n_boats is not None and len(waves) != n_boats):
                raise ValueError(f"batch: {len(waves)} waves for {n_boats} boats")
        self.model = model
        self.params = model.params
        self.profile = model.profile
        self.environment = BatchEnvironment.of_boats(waves, seas, currents)
        self.waves = BatchWaves.from_waves(self.environment.waves)
        self._env_mask, self._sea_mask = self.environment.mask, self.environment.sea_mask
        self.n_boats = len(self.waves)
        self.tables = BatchRomTables(model.tables)
        self.pressure = BatchPressure(model.hydro, exact)
        P = self.params
        self._points_body = np.vstack([np.zeros((1, 3)), P.plane_points_body, P.section_points_body])  # (21, 3)
        self.exact = bool(exact)
        rs = P.section_points_body                   # (45, 6): section forces dF (15 x 3, flattened) -> F_vm
        K = np.zeros((len(rs), 3, 6))
        for c in range(3):
            K[:, c, c] = 1.0
        K[:, 2, 3], K[:, 1, 3] = rs[:, 1], -rs[:, 2]
        K[:, 0, 4], K[:, 2, 4] = rs[:, 2], -rs[:, 0]
        K[:, 1, 5], K[:, 0, 5] = rs[:, 0], -rs[:, 1]
        self._section_sums = K.reshape(-1, 6)
        W = np.zeros((3, len(rs), 3))                # omega -> omega x r_i (flattened over sections)
        W[1, :, 0], W[2, :, 0] = rs[:, 2], -rs[:, 1]
        W[2, :, 1], W[0, :, 1] = rs[:, 0], -rs[:, 2]
        W[0, :, 2], W[1, :, 2] = rs[:, 1], -rs[:, 0]
        # the added-mass load of the motion: urel_i = -(V + omega x r_i) so F_vm = -(d nu/dt) @ (6, 6), nu = [V, omega]
        self._added_mass_of_motion = np.vstack([np.tile(np.eye(3), len(rs)), W.reshape(3, -1)]) @ (
            np.asarray(P.Cvm, dtype=float).reshape(-1, 1) * self._section_sums)

    @classmethod
    def from_sea_states(cls, model: BB2Model, sea_states: Sequence[float], strict: bool = True,
                        exact: bool = False) -> "BatchModel":
        """Boats in the authors' sea states (one per boat; 0 and 1 calm)."""
        return cls(model, [wave_for_sea_state(s, model.params, strict=strict) for s in sea_states], exact=exact)

    def new_memory(self) -> BatchDerivativeMemory | BatchAddedMassMemory:
        """Empty Derivative-block memories for the boats: the sections' relative velocities (exact, as the scalar
        code), else the motion and the sections' wave velocities (:class:`.memory.BatchAddedMassMemory`)."""
        n_sections = len(self.params.section_points_body)
        if self.exact:
            return BatchDerivativeMemory(self.n_boats, (n_sections, 3))
        return BatchAddedMassMemory(self.n_boats, n_sections)

    # -------------------------------------------------------------------------------------------
    def _check(self, x: np.ndarray, act: BatchActuatorOutputs, boats) -> int:
        n = self.n_boats if boats is None else len(boats)
        if x.shape != (n, 12):
            raise ValueError(f"batch: states must be ({n}, 12), got {x.shape}")
        if act.planes_deg.shape != (n, 5) or np.shape(act.rps) != (n,) or np.shape(act.dmass_kg) != (n,):
            raise ValueError(f"batch: actuator outputs must be planes ({n}, 5), rps ({n},), dmass ({n},); got "
                             f"{act.planes_deg.shape}, {np.shape(act.rps)}, {np.shape(act.dmass_kg)}")
        return n

    def evaluate(self, t, x: np.ndarray, act: BatchActuatorOutputs, dmem: BatchDerivativeMemory | BatchAddedMassMemory,
                 boats: np.ndarray | None = None) -> BatchEvaluation:
        """Evaluation at (t, x) of the boats ``boats`` (indices into the batch; None: all N), rows of x and act in
        that order. t: scalar or one time per boat. A boat whose numbers break down gets NaN rows (its single
        evaluation raises): the simulator marks it diverged."""
        P, prof = self.params, self.profile
        x = np.asarray(x, dtype=float)
        n = self._check(x, act, boats)
        waves = self.waves if boats is None else self.waves.subset(boats)
        if np.ndim(t) != 0:
            t = np.asarray(t, dtype=float)
            if t.shape != (n,):
                raise ValueError(f"batch: t must be a scalar or ({n},), got {t.shape}")
        X0, _, Z0, phi, theta, psi, u, v, w, p_, q, r = np.ascontiguousarray(x.T)
        R = rotation_native(phi, theta, psi)                       # (3, 3, n)
        seg = Segments()

        # wave velocities (body axes) at the CG, the 5 planes and the 15 sections: (3, 21, n), for the boats in a
        # sea (the scalar code's products: numpy's stacked matmul calls them boat by boat); the boats in a
        # component sea or a current take the scalar code's flow boat by boat (and, in a component sea, its
        # pressure integral), with their velocity relative to the water for the loads
        if act.rotations is None:                                   # the planes' rotations: held over the step
            act.rotations = self.pressure.prepare(act.planes_deg)
        ids = np.arange(n) if boats is None else np.asarray(boats)
        env_mask = self._env_mask[ids]
        env = np.flatnonzero(env_mask)
        wavy = np.flatnonzero(waves.wavy & ~env_mask)
        flowing = np.flatnonzero(waves.wavy | env_mask)             # the boats whose water moves
        uw = np.zeros((3, len(self._points_body), n)) if len(flowing) else None
        uh, vh, wh = u, v, w
        BFM_env = None
        if len(wavy):
            Rw = np.ascontiguousarray(R[:, :, wavy].transpose(2, 0, 1))                    # (m, 3, 3)
            e = x[wavy, None, 0:3] + np.matmul(self._points_body, Rw.transpose(0, 2, 1))   # (m, 21, 3) earth
            uw_e = waves.subset(wavy).orbital_velocity_earth(np.ascontiguousarray(e[..., 0]),
                                                             np.ascontiguousarray(e[..., 2]),
                                                             t if np.ndim(t) == 0 else t[wavy],
                                                             prof.wave_velocity_in_phase)
            uw[:, :, wavy] = np.matmul(uw_e, Rw).transpose(2, 1, 0)
        if len(env):
            rel = np.array([u, v, w])
            BFM_env = np.empty((n, 6))
            self.environment.flows(self.model, self.pressure, t, x, R, act, ids[env], env, uw, rel, BFM_env)
            uh, vh, wh = rel
        uw_cg = (0.0, 0.0, 0.0) if uw is None else uw[:, 0]         # calm: the scalar code's zeros
        uw_planes = np.zeros((3, 5, 1)) if uw is None else uw[:, 1:6]

        # flow at the CG (3.1)
        ue, ve, we = uw_cg[0] - u, uw_cg[1] - v, uw_cg[2] - w
        small = np.abs(ue) <= FLOW_ANGLE_GUARD_M_S
        ue_safe = np.where(small, 1.0, ue)
        arctan = libm.arctan if self.exact else np.arctan          # the scalar code's math.atan (exact)
        beta = np.where(small, np.where(ve < 0, -FLOW_ANGLE_AT_GUARD_DEG, FLOW_ANGLE_AT_GUARD_DEG),
                        -arctan(ve / ue_safe) * RAD2DEG)
        alpha = np.where(small, np.where(we < 0, -FLOW_ANGLE_AT_GUARD_DEG, FLOW_ANGLE_AT_GUARD_DEG),
                         arctan(we / ue_safe) * RAD2DEG)
        U = np.sqrt(ue * ue + ve * ve + we * we)

        # planes (3.2, 3.3, 5.x)
        UeX, aX = plane_flow(u, v, w, p_, q, r, uw_planes, P, guard=prof.zero_speed_guard, exact=self.exact)
        dXe = act.planes_deg + aX
        Fp = plane_loads(dXe, UeX, uh, q, Z0, P, self.tables, seg, n_clamped_depth=prof.n_planes_clamped_depth)

        # hull (5.x)
        Xh, Yh, Zh, Kh, Mh, Nh, T_wq = hull_loads(uh, vh, wh, p_, q, r, Z0, alpha, beta, U, P, self.tables, seg,
                                                   zuvw_b_abs_beta=prof.zuvw_b_abs_beta,
                                                   kpp_once=prof.kpp_once, sign_u_guard=prof.zero_speed_guard)

        # pressure integral (7)
        sea = env[self._sea_mask[ids[env]]] if len(env) else env        # rows in a component sea: loads made above
        if len(sea) == 0:
            BFM = self.pressure.loads(x[:, 0:3], R, t, waves, act.rotations, clip_emerged=prof.free_surface_clipping)
        else:
            BFM = BFM_env
            rest = np.setdiff1d(np.arange(n), sea)
            if len(rest) and waves.wavy[rest].any():
                self.pressure.exact_rotations(act.rotations)            # made once for the step, kept by subsets
            if len(rest):
                BFM[rest] = self.pressure.loads(x[rest, 0:3], R[:, :, rest], t if np.ndim(t) == 0 else t[rest],
                                                waves.subset(rest), act.rotations.subset(rest),
                                                clip_emerged=prof.free_surface_clipping)

        # added mass (8): urel_i = uw_i - (V + r_i @ skew(omega)^T), F_vm = [sum_i dF_i, sum_i r_i x dF_i] with
        # dF_i = Cvm_i d/dt urel_i (Derivative blocks). ``exact``: section by section, the products per boat with
        # the scalar code's BLAS kernels (numpy's stacked matmul calls them boat by boat). Else the blocks (linear)
        # differentiate the motion nu and, for the boats in a sea, the sections' wave velocities: F_vm is then
        # -(d nu/dt) M + the waves' part, the same loads to round-off without the (n, 15, 3) arrays in calm water
        rs = P.section_points_body
        if self.exact:
            uw_sec = 0.0 if uw is None else uw[:, 6:].T
            skew_T = np.zeros((n, 3, 3))
            skew_T[:, 0, 1], skew_T[:, 0, 2], skew_T[:, 1, 0] = r, -q, -r
            skew_T[:, 1, 2], skew_T[:, 2, 0], skew_T[:, 2, 1] = p_, q, -p_
            am_in = uw_sec - (x[:, None, 6:9] + np.matmul(rs, skew_T))      # (n, 15, 3)
            dF = P.Cvm * dmem.derivative(t, am_in, boats)
            A = np.matmul(rs.T, dF)                                         # r^T dF per boat (n, 3, 3)
            F_vm = np.empty((n, 6))
            F_vm[:, 0:3] = dF.sum(axis=1)
            F_vm[:, 3], F_vm[:, 4], F_vm[:, 5] = A[:, 1, 2] - A[:, 2, 1], A[:, 2, 0] - A[:, 0, 2], \
                A[:, 0, 1] - A[:, 1, 0]
        else:
            am_in = AddedMassInputs(x[:, 6:12].copy(), None if uw is None else
                                    np.ascontiguousarray(uw[:, 6:, flowing].transpose(2, 1, 0)), flowing)
            d_nu, d_uw = dmem.derivatives(t, am_in, boats)
            F_vm = d_nu @ self._added_mass_of_motion
            np.negative(F_vm, out=F_vm)
            if d_uw is not None:                                            # [sum_i dF_i, sum_i r_i x dF_i]
                F_vm[flowing] += (P.Cvm * d_uw).reshape(len(flowing), -1) @ self._section_sums

        # propeller (6)
        prop = propeller_load(uh, Z0, act.rps, P, self.tables.thrust_deduction, seg,
                              wired_correctly=prof.thrust_deduction_wired)

        # statics (7.5)
        W = (self.model.Mb + act.dmass_kg) * P.g
        sin, cos = (libm.sin, libm.cos) if self.exact else (np.sin, np.cos)   # the scalar code's math (exact)
        st, ct = sin(theta), cos(theta)
        sphi, cphi = sin(phi), cos(phi)
        X_stat = BFM[:, 0] + W * st
        if prof.static_forces_correct:
            Y_stat = BFM[:, 1] - W * ct * sphi
            Z_stat = BFM[:, 2] - W * ct * cphi
        else:
            Y_stat = W * ct * sphi - BFM[:, 1]
            Z_stat = BFM[:, 2] - W * ct
        K_stat = BFM[:, 3] + P.cg_offset[0] * W * ct * sphi

        F = np.stack([
            Fp[0] + Xh + X_stat - (prop.thrust + T_wq) + F_vm[:, 0],
            Fp[1] + Yh + Y_stat + F_vm[:, 1],
            Fp[2] + Zh + Z_stat + F_vm[:, 2],
            Kh + Fp[3] + K_stat + F_vm[:, 3] + prop.torque,
            Fp[4] + Mh + BFM[:, 4] + F_vm[:, 4],
            Nh + Fp[5] + BFM[:, 5] + F_vm[:, 5],
        ], axis=1)

        xdot = np.empty((n, 12))
        xdot[:, 6:12] = rigid_body_acceleration(F, u, v, w, p_, q, r, P, euler_roll=prof.euler_roll_inertia)
        xdot[:, 0:6] = kinematics(R, phi, theta, x[:, 6:9], x[:, 9:12])
        return BatchEvaluation(xdot, F, am_in, alpha, beta, U, prop, BFM, F_vm, dXe)
