"""The irregular seas and currents of a batch's boats (one :class:`bb2_sim.sea.Sea` and one
:class:`bb2_sim.current.Current`, or None, per boat).

A boat in a component sea or a current takes the scalar code's own flow (the water's velocity at the CG, the planes
and the sections, the velocity relative to the water, and in a component sea the pressure integral from the same
exponentials as :meth:`bb2_sim.model.BB2Model.flow_in_environment` gives them), bit for bit. In a component sea on
the wave-load grid (the default) each boat's grid pass is its own, everything around it is done for all such boats
at once (:meth:`bb2_sim.batch.pressure.BatchPressure.sea_loads_and_orbital_velocity`); a current, and a sea on the
direct method or with free-surface clipping, go through the scalar method boat by boat. Each sea keeps its own
wave-load grid (:meth:`bb2_sim.hydrostatics.PressureIntegrator.new_wave_grid`), so boats in different seas do not
rebuild each other's grid levels (30-80 ms each) at every evaluation.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..waves import Wave, wave_for_sea_state


@dataclass
class BatchEnvironment:
    """Per boat: its regular wave (calm for a boat in a component sea), component sea or None, current or None."""

    waves: tuple[Wave, ...]
    seas: tuple[Any, ...]
    currents: tuple[Any, ...]
    _grids: dict[int, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def of_boats(cls, waves: Sequence[Wave], seas: Sequence | None, currents: Sequence | None) -> "BatchEnvironment":
        """The boats' environments as :class:`bb2_sim.model.BB2Model` takes one (``sea``: an
        :class:`~bb2_sim.sea.AuthorsTableSea` is its regular wave, a calm sea or current is none); ``seas`` and
        ``currents`` None: none."""
        from ..sea.sea import AuthorsTableSea

        lengths = {name: len(a) for name, a in (("waves", waves), ("seas", seas), ("currents", currents))
                   if a is not None}
        if len(set(lengths.values())) > 1:
            raise ValueError("batch: " + ", ".join(f"{k} for {v} boats" for k, v in lengths.items())
                             + " (one each per boat)")
        n = len(waves)
        ws = list(waves)
        ss: list[Any] = [None] * n
        for i, sea in enumerate(seas if seas is not None else ()):
            if sea is None:
                continue
            if not isinstance(ws[i], Wave) or not ws[i].calm:
                raise ValueError(f"batch: boat {i}: give either a sea state (a wave) or a sea, not both")
            if isinstance(sea, AuthorsTableSea):
                ws[i] = sea.wave
            elif not sea.calm:
                ss[i] = sea
        cs = [None if c is None or c.calm else c for c in (currents if currents is not None else [None] * n)]
        return cls(tuple(ws), tuple(ss), tuple(cs))

    def __len__(self) -> int:
        return len(self.waves)

    @property
    def sea_mask(self) -> np.ndarray:
        """Boats in a component sea (N,)."""
        return np.array([s is not None for s in self.seas], dtype=bool)

    @property
    def mask(self) -> np.ndarray:
        """Boats whose flow is the scalar code's (a component sea or a current) (N,)."""
        return self.sea_mask | np.array([c is not None for c in self.currents], dtype=bool)

    def grid(self, model: Any, boat: int) -> Any:
        """The wave-load grid of boat ``boat``'s sea (one per sea object, made on first use)."""
        sea = self.seas[boat]
        g = self._grids.get(id(sea))
        if g is None:
            g = self._grids[id(sea)] = (sea, model.hydro.new_wave_grid(model._flow_points_body))
        return g[1]

    def flows(self, model: Any, pressure: Any, t, x: np.ndarray, R: np.ndarray, act: Any, boats: np.ndarray,
              rows: np.ndarray, uw: np.ndarray, uvw_rel: np.ndarray, BFM: np.ndarray) -> None:
        """For the rows ``rows`` (positions in x) of boats ``boats`` (their indices in the batch), the scalar
        code's flow: uw[:, :, j] (3, 21) body axes, uvw_rel[:, j] (3,) the velocity relative to the water and, for a
        boat in a component sea, BFM[j] (6,) its pressure-integral loads, bit for bit
        :meth:`BB2Model.flow_in_environment`'s. The boats in a component sea on the wave-load grid (the default,
        without clipping) take it in one pass (:meth:`.pressure.BatchPressure.sea_loads_and_orbital_velocity`: the
        grid boat by boat, the rest together), the others the scalar method boat by boat.
        x (n, 12); R (3, 3, n); t scalar or (n,); act: the held actuator outputs (planes (n, 5), their rotations);
        pressure: the batch's :class:`.pressure.BatchPressure`."""
        prof = model.profile
        on_grid = [model.sea_on_grid(self.seas[b]) for b in boats.tolist()]
        fused = [k for k, g in enumerate(on_grid) if g]
        for k in (k for k, g in enumerate(on_grid) if not g):
            j, b = int(rows[k]), int(boats[k])
            sea, current = self.seas[b], self.currents[b]
            tj = t if np.ndim(t) == 0 else float(t[j])
            Rj = np.ascontiguousarray(R[:, :, j])
            xj = x[j]
            uw_j, rel, loads = model.flow_in_environment(tj, xj, Rj, act.planes_deg[j], sea, current, self.waves[b])
            uw[:, :, j] = uw_j.T
            uvw_rel[:, j] = rel
            if sea is not None:
                BFM[j] = loads if loads is not None else model.hydro.loads(
                    xj[0:3], Rj, tj, self.waves[b], act.planes_deg[j], clip_emerged=prof.free_surface_clipping,
                    sea=sea, wave_load_method=model.wave_load_method)
        if not fused:
            return
        jf, bf = rows[fused], boats[fused]
        Rf = np.ascontiguousarray(R[:, :, jf].transpose(2, 0, 1))                  # (m, 3, 3)
        tf = t if np.ndim(t) == 0 else t[jf]
        pos = x[jf, 0:3]
        loads, uw_e = pressure.sea_loads_and_orbital_velocity(
            pos, Rf, tf, pressure.exact_rotations(act.rotations)[jf],
            [(self.seas[b], self.grid(model, b)) for b in bf.tolist()], model._flow_points_body,
            q12=not prof.wave_velocity_in_phase)
        BFM[jf] = loads
        for k, (j, b) in enumerate(zip(jf.tolist(), bf.tolist())):
            current = self.currents[b]
            if current is not None:                  # the scalar code's, boat by boat
                e = model.flow_points_earth(x[j, 0:3], Rf[k])
                uc, uvw_rel[:, j] = model.current_flow(e, Rf[k], current, float(x[j, 6]), float(x[j, 7]),
                                                       float(x[j, 8]))
                uw_e[k] = uw_e[k] + uc
        uw[:, :, jf] = np.matmul(uw_e, Rf).transpose(2, 1, 0)


def boat_environments(environments: Sequence[Any], params: Any, sea_states: Sequence[float] | None = None
                      ) -> dict[str, list]:
    """:class:`~bb2_sim.batch.BatchModel` keywords (``waves``, ``seas``, ``currents``) of boats each in its
    :class:`bb2_sim.environment.Environment` as :class:`~bb2_sim.model.BB2Model` takes one
    (:meth:`~bb2_sim.environment.Environment.model_kwargs`); an environment None: the authors' sea state
    ``sea_states[i]``, no current."""
    out: dict[str, list] = {"waves": [], "seas": [], "currents": []}
    for i, env in enumerate(environments):
        kw = {"sea_state": sea_states[i]} if env is None else env.model_kwargs(params)
        out["waves"].append(wave_for_sea_state(kw["sea_state"], params) if "sea_state" in kw else Wave())
        out["seas"].append(kw.get("sea"))
        out["currents"].append(kw.get("current"))
    return out
