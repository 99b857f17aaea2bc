"""One evaluation of the BB2 reduced-order model (SPEC 12): state + held actuators -> state derivative, loads.

State vector (12, native frames): ``[x, y, z, phi, theta, psi, u, v, w, p, q, r]`` — earth position of the
CG (z up), ZYX Euler angles, body velocities (x aft, y starboard, z up) and body rates.

Order of evaluation: waves and rotation -> flow angles at the CG and the planes -> pressure integral with
the deflected planes -> added mass (numerical derivative of the section relative velocities) -> propeller
-> X..N -> rigid-body equations and kinematics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .actuators import ActuatorOutputs
from .added_mass import DerivativeMemory, moment_of_forces, section_relative_velocity
from .frames import euler_rate_matrix, rotation_native
from .hull_forces import hull_loads
from .hydrostatics import PressureIntegrator
from .parameters import RomParameters, load_parameters
from .planes import plane_flow, plane_loads
from .profiles import Profile, get_profile
from .propeller import PropellerLoad, propeller_load
from .rigid_body import rigid_body_acceleration
from .tables import RomTables, load_tables
from .waves import Wave, orbital_velocity_earth, wave_for_sea_state

RAD2DEG = 180.0 / math.pi


@dataclass
class Evaluation:
    """What one model evaluation produces (all native body axes, SI; angles of the flow in degrees)."""

    xdot: np.ndarray          # (12,)
    forces: np.ndarray        # (6,) F = [X, Y, Z, K, M, N] total external load
    urel_sections: np.ndarray  # (15, 3) relative velocities fed to the added-mass Derivative block
    alpha_deg: float
    beta_deg: float
    U: float
    prop: PropellerLoad
    hydrostatic: np.ndarray   # (6,) pressure-integral loads B_FM
    added_mass: np.ndarray    # (6,)
    planes_eff_deg: np.ndarray  # (5,) effective deflections dX + aX


class BB2Model:
    """The ROM: parameters, tables, hull surfaces, physics profile and sea state."""

    def __init__(self, surfaces=None, profile: "str | Profile" = "iowa", sea_state: float = 0,
                 params: RomParameters | None = None, tables: RomTables | None = None,
                 trim_to_buoyancy: bool | None = None, strict_sea_state: bool = True, *,
                 sea=None, current=None, wave_load_method: str = "grid"):
        """``sea`` (a :class:`bb2_sim.sea.Sea`) replaces the sea state's regular wave (give one or the other);
        an :class:`bb2_sim.sea.AuthorsTableSea` runs today's code path, any other sea the component sums
        (wave loads by ``wave_load_method``, see :meth:`PressureIntegrator.loads`). ``current`` (a
        :class:`bb2_sim.current.Current`): the hull, planes, propeller and added mass see the velocity
        relative to the water, the kinematics the velocity over ground. Both None: today's model exactly."""
        from .geometry import load_hull  # trimesh only when a model is built
        from .sea.sea import AuthorsTableSea

        self.params = params or load_parameters()
        self.tables = tables or load_tables()
        self.profile = get_profile(profile)
        self.surfaces = surfaces if surfaces is not None and not isinstance(surfaces, (str, bytes)) \
            else load_hull(surfaces)
        self.hydro = PressureIntegrator(self.surfaces, self.params.rho, self.params.g)
        self.wave: Wave = wave_for_sea_state(sea_state, self.params, strict=strict_sea_state)
        self.sea = None
        if sea is not None:
            if not self.wave.calm:
                raise ValueError("give either a sea state or a sea, not both")
            if isinstance(sea, AuthorsTableSea):
                self.wave = sea.wave
            elif not sea.calm:
                self.sea = sea
        self.current = current if current is not None and not current.calm else None
        if wave_load_method not in ("grid", "direct"):
            raise ValueError(f"wave_load_method must be 'grid' or 'direct', got {wave_load_method!r}")
        self.wave_load_method = wave_load_method
        self.volume = self.hydro.volume()
        self.buoyancy_mass = self.params.rho * self.volume
        # The paper trims the weight to the integrated buoyancy. The authors' Mb equals rho V of their
        # surfaces to 0.05 kg and is kept as it is (None = auto: trim unless within the data's tolerance);
        # any other surface set (the generated hull: -53 kg) is trimmed at start.
        if trim_to_buoyancy is None:
            trim_to_buoyancy = abs(self.buoyancy_mass - self.params.Mb) > self.params.trim_tolerance_kg
        self.trimmed = bool(trim_to_buoyancy)
        self.Mb = self.buoyancy_mass if trim_to_buoyancy else self.params.Mb
        p = self.params
        self._h = p.h
        # where the flow is sampled (body axes, m): the CG, the 5 planes and the 15 added-mass sections
        self._flow_points_body = np.vstack([np.zeros((1, 3)), p.plane_points_body, p.section_points_body])

    # -------------------------------------------------------------------------------------------
    def flow_points_earth(self, pos: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The 21 flow points (the CG, the 5 planes, the 15 sections) in earth axes (21, 3), m, for the CG at
        ``pos`` (earth) and the body->earth rotation ``R``."""
        return pos + self._flow_points_body @ R.T

    def sea_on_grid(self, sea) -> bool:
        """Whether ``sea`` (or None) is a component sea whose pressure integral and orbital velocities come from one
        pass of its wave-load grid (:meth:`flow_in_environment`): the grid method, no free-surface clipping."""
        return sea is not None and sea.components is not None and self.wave_load_method == "grid" \
            and not self.profile.free_surface_clipping

    def flow_in_environment(self, t: float, x: np.ndarray, R: np.ndarray, planes_deg: np.ndarray, sea, current,
                            wave: Wave, grid=None) -> tuple[np.ndarray, tuple[float, float, float], np.ndarray | None]:
        """What a component sea and/or a current do at the flow points of state ``x`` (R: its body->earth rotation):
        the water's velocity (21, 3) body axes at the CG, the 5 planes and the 15 sections (orbital velocity plus
        current), the boat's velocity relative to the water (u, v, w) for the loads, and the pressure-integral
        loads (6,) when a component sea on the grid gives them from the same exponentials (else None).

        ``sea`` (a component :class:`bb2_sim.sea.Sea` or None), ``current`` (or None) and ``wave`` (the regular
        wave when there is no sea) are the model's own in :meth:`evaluate`; the batch ROM passes each boat's
        (``grid``: the boat's own wave-load grid, :meth:`PressureIntegrator.new_wave_grid`; None: the model's)."""
        prof = self.profile
        pos = x[0:3]
        u, v, w = float(x[6]), float(x[7]), float(x[8])
        BFM = None
        # a component sea on the grid: the pressure integral (7) and the orbital velocities from one evaluation
        fused = self.sea_on_grid(sea)
        e = None if fused and current is None else self.flow_points_earth(pos, R)
        if fused:
            BFM, uw_e = self.hydro.loads_and_orbital_velocity(pos, R, t, planes_deg, sea, self._flow_points_body,
                                                              q12=not prof.wave_velocity_in_phase, grid=grid)
        elif sea is not None:
            uw_e = sea.orbital_velocity(e, t, q12=not prof.wave_velocity_in_phase)
        elif not wave.calm:
            uw_e = orbital_velocity_earth(wave, e[:, 0], e[:, 2], t, prof.wave_velocity_in_phase)
        else:
            uw_e = np.zeros((len(e), 3))
        if current is not None:
            uc, (u, v, w) = self.current_flow(e, R, current, u, v, w)
            uw_e = uw_e + uc
        return uw_e @ R, (u, v, w), BFM

    @staticmethod
    def current_flow(e: np.ndarray, R: np.ndarray, current, u: float, v: float, w: float
                     ) -> tuple[np.ndarray, tuple[float, float, float]]:
        """The ``current``'s velocity (P, 3) earth axes at the earth flow points ``e`` (P, 3) (row 0 the CG), and
        the body velocity (u, v, w) relative to the water at the CG (R: the body->earth rotation)."""
        uc = current.velocity_earth(e[:, 2])
        uc_cg = uc[0] @ R
        return uc, (u - float(uc_cg[0]), v - float(uc_cg[1]), w - float(uc_cg[2]))

    def evaluate(self, t: float, x: np.ndarray, act: ActuatorOutputs, dmem: DerivativeMemory) -> Evaluation:
        """Full model evaluation at (t, x) with the held actuator outputs and the derivative memory."""
        P, prof, wave = self.params, self.profile, self.wave
        pos = x[0:3]
        phi, theta, psi = x[3], x[4], x[5]
        V = x[6:9]
        omega = x[9:12]
        u, v, w = float(V[0]), float(V[1]), float(V[2])
        p_, q, r = float(omega[0]), float(omega[1]), float(omega[2])
        z = float(pos[2])
        R = rotation_native(phi, theta, psi)

        # wave velocities (body axes) at the CG, the 5 planes and the 15 sections, in one call
        uh, vh, wh = u, v, w                     # velocity relative to the water (current) for the loads
        BFM = None
        if self.sea is not None or self.current is not None:
            uw, (uh, vh, wh), BFM = self.flow_in_environment(t, x, R, act.planes_deg, self.sea, self.current, wave)
            uw_cg, uw_planes, uw_sec = uw[0], uw[1:6], uw[6:]
        elif wave.calm:
            uw_cg = np.zeros(3)
            uw_planes = np.zeros((5, 3))
            uw_sec = np.zeros((15, 3))
        else:
            e = self.flow_points_earth(pos, R)
            uw = orbital_velocity_earth(wave, e[:, 0], e[:, 2], t, prof.wave_velocity_in_phase) @ R
            uw_cg, uw_planes, uw_sec = uw[0], uw[1:6], uw[6:]

        # flow at the CG (3.1)
        ue, ve, we = uw_cg[0] - u, uw_cg[1] - v, uw_cg[2] - w
        if abs(ue) <= 1e-8:
            alpha = -90.0 if we < 0 else 90.0
            beta = -90.0 if ve < 0 else 90.0
        else:
            beta = -math.atan(ve / ue) * RAD2DEG
            alpha = math.atan(we / ue) * RAD2DEG
        U = math.sqrt(ue * ue + ve * ve + we * we)

        # planes (3.2, 3.3, 5.x)
        UeX, aX = plane_flow(V, omega, uw_planes, P, guard=prof.zero_speed_guard)
        dXe = act.planes_deg + aX
        Fp = plane_loads(dXe, UeX, uh, q, z, P, self.tables, n_clamped_depth=prof.n_planes_clamped_depth)

        # hull (5.x)
        Xh, Yh, Zh, Kh, Mh, Nh, T_wq = hull_loads(uh, vh, wh, p_, q, r, z, alpha, beta, U, P, self.tables,
                                                   zuvw_b_abs_beta=prof.zuvw_b_abs_beta,
                                                   kpp_once=prof.kpp_once, sign_u_guard=prof.zero_speed_guard)

        # pressure integral (7)
        if BFM is None:
            BFM = self.hydro.loads(pos, R, t, wave, act.planes_deg, clip_emerged=prof.free_surface_clipping,
                                   sea=self.sea, wave_load_method=self.wave_load_method)

        # added mass (8)
        urel = section_relative_velocity(V, omega, uw_sec, P.section_points_body)
        acc = dmem.derivative(t, urel)
        dF = P.Cvm * acc
        F_vm = np.concatenate([dF.sum(axis=0), moment_of_forces(P.section_points_body, dF)])

        # propeller (6)
        prop = propeller_load(uh, z, act.rps, P, self.tables.thrust_deduction,
                              wired_correctly=prof.thrust_deduction_wired)

        # statics (7.5)
        W = (self.Mb + act.dmass_kg) * P.g
        st, ct = math.sin(theta), math.cos(theta)
        sphi, cphi = math.sin(phi), math.cos(phi)
        X_stat = BFM[0] + W * st
        if prof.static_forces_correct:
            Y_stat = BFM[1] - W * ct * sphi
            Z_stat = BFM[2] - W * ct * cphi
        else:
            Y_stat = W * ct * sphi - BFM[1]
            Z_stat = BFM[2] - W * ct
        K_stat = BFM[3] + P.cg_offset[0] * W * ct * sphi

        F = np.array([
            Fp[0] + Xh + X_stat - (prop.thrust + T_wq) + F_vm[0],
            Fp[1] + Yh + Y_stat + F_vm[1],
            Fp[2] + Zh + Z_stat + F_vm[2],
            Kh + Fp[3] + K_stat + F_vm[3] + prop.torque,
            Fp[4] + Mh + BFM[4] + F_vm[4],
            Nh + Fp[5] + BFM[5] + F_vm[5],
        ])

        vdot = rigid_body_acceleration(F, V, omega, self.params, euler_roll=prof.euler_roll_inertia)
        xdot = np.empty(12)
        xdot[0:3] = R @ V
        xdot[3:6] = euler_rate_matrix(phi, theta) @ omega
        xdot[6:12] = vdot
        return Evaluation(xdot, F, urel, alpha, beta, U, prop, BFM, F_vm, dXe)
