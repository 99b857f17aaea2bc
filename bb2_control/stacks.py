"""Named guidance-and-control stacks composed from the pieces of bb2_control (SPEC 0 and 7).

``build_stack(name_or_config, path=None, overrides=None)`` returns a stack with ``reset()`` and
``step(state) -> ControlOutput``, to be called once every Ts = 0.05 s at the ROM's major steps (the
ROM holds the commands during its ode3 stages).  Stacks (``data/stacks.yaml``):

* ``rate_2022`` (default): 3-D SO(3) path following -> body-rate conversion -> rate L1 ->
  proportional rate autopilot -> X-plane mixer; constant propeller rps.
* ``los_2023``: 2-D LOS heading + path depth -> depth/heading L1 -> depth/pitch/yaw PD -> mixer.

Each piece keeps its own small ``step()`` so that separate processes can run them:
guidance (:class:`~bb2_control.path_following.PathFollowing3D` or
:class:`~bb2_control.los.LineOfSightDepth`), inner loop (:class:`RateInnerLoop` or
:class:`DepthHeadingInnerLoop`: L1 + autopilot) and :class:`~bb2_control.mixer.PlaneMixer`.

Non-finite vehicle states: ``nan_policy: raise`` (default) raises NonFiniteInputError before any state
changes; ``hold`` returns the previous output again (flagged ``held``) without changing any state, and
raises if there is no previous output.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bb2_control.autopilots import DepthHeadingPD, RateAutopilot
from bb2_control.config import deep_merge, load_data, load_mapping, require
from bb2_control.errors import ControlConfigError, NonFiniteInputError, UnknownStackError
from bb2_control.l1_adaptive import L1Augmentation
from bb2_control.los import LineOfSightDepth, LOSGains
from bb2_control.mixer import PlaneMixer
from bb2_control.path_following import PathFollowing3D, PFGains, flow_to_body_rates, prepare_steps
from bb2_sim import frames
from bb2_sim.names import close_name
from bb2_sim.state import VehicleState

__all__ = [
    "ControlOutput", "SpeedCommand", "RateInnerLoop", "DepthHeadingInnerLoop", "Stack",
    "RatePathFollowingStack", "LosDepthHeadingStack", "available_stacks", "resolve_config", "build_stack",
    "build_mixer", "build_speed_command", "mixer_from_config", "prepare_stacks",
]

_SECTION_FILES = {"guidance": "guidance", "l1": "l1_configs", "autopilot": "autopilots", "mixer": "mixer"}


@dataclass(frozen=True)
class ControlOutput:
    """Everything one stack tick produces (commands and logging).  NaN marks quantities a stack lacks."""

    t: float                   #: state time, s
    q_c: float                 #: PF rate command about w2 (bow-down positive), rad/s (NaN for LOS)
    r_c: float                 #: PF rate command about w3 (bow-to-port positive), rad/s (NaN for LOS)
    q_up_ref: float            #: bow-up body-rate reference into the inner loop, rad/s (NaN for LOS)
    r_left_ref: float          #: bow-to-port body-rate reference, rad/s (NaN for LOS)
    z_ref: float               #: depth reference (z up), m (NaN for the rate stack)
    psi_ref: float             #: heading reference (continuous, bow CCW from x of the stack frame), rad
    u_ad: Mapping[str, float]  #: L1 outputs (= references when adaptation is off)
    dV_deg: float              #: vertical command, deg (> 0 bow-up moment)
    dH_deg: float              #: horizontal command, deg (> 0 bow-to-port moment)
    planes_deg: np.ndarray     #: delta_1..delta_5, deg (ROM per-plane convention)
    rps: float                 #: propeller command, rev/s
    gamma: float               #: virtual time, s
    gamma_dot: float
    p_d_native: np.ndarray     #: desired position, native earth frame, m
    e_horizontal_m: float      #: horizontal path error (> 0: vehicle left of the path), m
    e_vertical_m: float        #: vertical path error (> 0: vehicle above the path), m
    finished: bool             #: gamma reached the end of the path
    held: bool = False         #: True when this is a repeated output (nan_policy: hold)


@dataclass
class SpeedCommand:
    """Constant feed-forward propeller command n = |v_ref| / advance, clipped to [n_min, n_max] (SPEC 4.3)."""

    v_ref_mps: float
    advance_m_per_rev: float = 4.0
    n_min_rps: float = 0.01
    n_max_rps: float = 10.0

    def __post_init__(self) -> None:
        if not (self.advance_m_per_rev > 0 and self.n_max_rps >= self.n_min_rps and math.isfinite(self.v_ref_mps)):
            raise ControlConfigError(f"speed command: invalid settings {self}")

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "SpeedCommand":
        mode = cfg.get("mode", "constant_feedforward")
        if mode != "constant_feedforward":
            raise ControlConfigError(f"speed command: unknown mode {mode!r} (only 'constant_feedforward')")
        return cls(float(require(cfg, "v_ref_mps", "speed")), float(cfg.get("advance_m_per_rev", 4.0)),
                   float(cfg.get("n_min_rps", 0.01)), float(cfg.get("n_max_rps", 10.0)))

    def reset(self) -> None:
        """Stateless."""

    def step(self) -> float:
        # np.clip's value for a float, without its overhead (the stack steps this every tick)
        return float(min(max(abs(self.v_ref_mps) / self.advance_m_per_rev, self.n_min_rps), self.n_max_rps))


class RateInnerLoop:
    """Rate L1 + proportional rate autopilot: body-rate references and measured rates -> (dV, dH) deg."""

    def __init__(self, l1: L1Augmentation, autopilot: RateAutopilot) -> None:
        if set(l1.channels) != {"q", "r"}:
            raise ControlConfigError(f"rate inner loop needs L1 channels 'q' and 'r', got {sorted(l1.channels)}")
        self.l1, self.autopilot = l1, autopilot

    def reset(self) -> None:
        self.l1.reset()
        self.autopilot.reset()

    def step(self, q_up_ref: float, r_left_ref: float, q_up: float, r_left: float
             ) -> tuple[float, float, dict[str, float]]:
        """(dV, dH, u_ad) from bow-up / bow-to-port rate references and measurements (rad/s)."""
        isfinite = math.isfinite
        if not (isfinite(q_up_ref) and isfinite(r_left_ref) and isfinite(q_up) and isfinite(r_left)):
            vals = dict(q_up_ref=q_up_ref, r_left_ref=r_left_ref, q_up=q_up, r_left=r_left)
            raise NonFiniteInputError(f"rate inner loop: non-finite input {vals}")
        ch = self.l1.channels                   # every input checked: the channels step in turn (as l1.step)
        u = {"q": ch["q"].step(q_up_ref, q_up), "r": ch["r"].step(r_left_ref, r_left)}
        dV, dH = self.autopilot.step(u["q"], u["r"], q_up, r_left)
        return dV, dH, u


class DepthHeadingInnerLoop:
    """Depth/heading L1 + depth/pitch/yaw PD: references and measurements -> (dV, dH) deg."""

    def __init__(self, l1: L1Augmentation, autopilot: DepthHeadingPD) -> None:
        if set(l1.channels) != {"depth", "heading"}:
            raise ControlConfigError(
                f"depth/heading inner loop needs L1 channels 'depth' and 'heading', got {sorted(l1.channels)}")
        self.l1, self.autopilot = l1, autopilot

    def reset(self) -> None:
        self.l1.reset()
        self.autopilot.reset()

    def step(self, z_ref: float, psi_ref: float, z: float, theta: float, psi: float
             ) -> tuple[float, float, dict[str, float]]:
        """(dV, dH, u_ad); z up (m), angles rad, psi and psi_ref continuous in the same frame."""
        vals = dict(z_ref=z_ref, psi_ref=psi_ref, z=z, theta=theta, psi=psi)
        if not all(math.isfinite(float(v)) for v in vals.values()):
            raise NonFiniteInputError(f"depth/heading inner loop: non-finite input {vals}")
        u = self.l1.step({"depth": z_ref, "heading": psi_ref}, {"depth": z, "heading": psi})
        dV, dH = self.autopilot.step(u["depth"], z, theta, u["heading"], psi)
        return dV, dH, u


# ------------------------------------------------------------------------------------------ stacks
def mixer_from_config(config: Mapping[str, Any]) -> PlaneMixer:
    """The X-plane mixer of a resolved stack configuration (``data/mixer.yaml`` + the stack's ``mixer``)."""
    return PlaneMixer.from_config(deep_merge(load_data("mixer"), config.get("mixer") or {}))


class Stack:
    """Base: frame handling, NaN policy and the shared pieces (mixer, speed)."""

    def __init__(self, name: str, config: Mapping[str, Any], path: Any) -> None:
        self.name = name
        self.config = dict(config)
        self.Ts = float(require(config, "Ts_s", f"stack {name}"))
        self.nan_policy = config.get("nan_policy", "raise")
        if self.nan_policy not in ("raise", "hold"):
            raise ControlConfigError(f"stack {name}: nan_policy must be 'raise' or 'hold', got {self.nan_policy!r}")
        frame = config.get("frame", "native")
        from bb2_planner.bernstein import frame_matrix_to_native  # control may use planner types

        M = np.asarray(frame_matrix_to_native(frame), dtype=float)
        if not (np.isclose(np.linalg.det(M), 1.0) and np.allclose(M[:, 2], [0, 0, 1]) and np.allclose(M[2], [0, 0, 1])):
            raise ControlConfigError(f"stack {name}: frame {frame!r} is not a z-up rotation of the native frame")
        self.frame = frame
        self._M = M                        # p_native = M p_frame
        self._M_signed_permutation = bool(np.isin(M, (-1.0, 0.0, 1.0)).all())   # see _inputs_together
        bow = M.T @ np.array([-1.0, 0.0, 0.0])
        self._heading_offset = math.atan2(bow[1], bow[0])   # heading_frame = psi_native + offset
        self.path = path.to_frame(frame) if getattr(path, "frame", frame) != frame else path
        self.mixer = mixer_from_config(config)
        self.speed = SpeedCommand.from_config(require(config, "speed", f"stack {name}"))
        self._last: ControlOutput | None = None
        self._prepared_inputs: tuple[VehicleState, dict[str, Any]] | None = None   # see prepare_stacks

    def reset(self) -> None:
        """Every piece back to its initial state (subclasses set ``guidance`` and ``inner``)."""
        self.guidance.reset()
        self.inner.reset()
        self.mixer.reset()
        self.speed.reset()
        self._last = None
        self._prepared_inputs = None

    # -- inputs in the stack frame
    def inputs(self, s: VehicleState) -> dict[str, Any]:
        """The vehicle state in this stack's frame, as its pieces take it: p (position), R_BI (FLU body to
        stack frame), v_flu, q_up / r_left (bow-up / bow-to-port rates), theta, heading. Nodes that run one
        piece alone use this so their conversion is the stack's own."""
        phi, theta, psi = (float(x) for x in s.euler_native)
        R_BI_native = frames.rotation_native(phi, theta, psi) @ frames.D_FLIP
        return dict(p=self._M.T @ np.asarray(s.p_native, float), R_BI=self._M.T @ R_BI_native,
                    v_flu=frames.body_native_to_flu(s.v_body_native), q_up=float(s.w_body_native[1]),
                    r_left=float(s.w_body_native[2]), theta=theta, heading=psi + self._heading_offset)

    def step(self, state: VehicleState) -> ControlOutput:
        """One control tick for the vehicle state (native frames); call every Ts."""
        prepared, self._prepared_inputs = self._prepared_inputs, None
        if prepared is not None and prepared[0] is state:
            out = self._step(state, prepared[1])        # prepared for this very state (finite: prepare checked)
            self._last = out
            return out
        vec = state.as_vector()
        if not np.isfinite(vec).all() or not math.isfinite(state.t):
            if self.nan_policy == "hold" and self._last is not None:
                return replace(self._last, held=True)
            raise NonFiniteInputError(
                f"stack {self.name}: non-finite vehicle state at t={state.t}: {state.as_vector()}"
                + (" (nan_policy 'hold' has no previous output yet)" if self.nan_policy == "hold" else ""))
        out = self._step(state, self.inputs(state))
        self._last = out
        return out

    def _step(self, state: VehicleState, x: dict[str, Any]) -> ControlOutput:  # pragma: no cover
        raise NotImplementedError

    @property
    def finished(self) -> bool:
        return self.guidance.finished

    @property
    def adaptation(self) -> bool:
        return self.inner.l1.adaptive

    @adaptation.setter
    def adaptation(self, on: bool) -> None:
        self.inner.l1.adaptive = on


class RatePathFollowingStack(Stack):
    """``rate_2022``: PathFollowing3D -> flow_to_body_rates -> RateInnerLoop -> PlaneMixer."""

    def __init__(self, name: str, config: Mapping[str, Any], path: Any) -> None:
        super().__init__(name, config, path)
        self.guidance = PathFollowing3D(self.path, PFGains.from_config(require(config, "guidance", name)))
        l1 = L1Augmentation.from_config(require(config, "l1", name), bool(config.get("adaptation", True)))
        self.inner = RateInnerLoop(l1, RateAutopilot(require(config, "autopilot", name)))
        _check_Ts(self, self.guidance.gains.Ts, l1, self.inner.autopilot.Ts)

    def _step(self, state: VehicleState, x: dict[str, Any]) -> ControlOutput:
        pf = self.guidance.step(x["p"], x["R_BI"], x["v_flu"])
        q_ref, r_ref = flow_to_body_rates(pf.q_c, pf.r_c, x["v_flu"])
        dV, dH, u = self.inner.step(q_ref, r_ref, x["q_up"], x["r_left"])
        nan = float("nan")
        return ControlOutput(
            t=float(state.t), q_c=pf.q_c, r_c=pf.r_c, q_up_ref=q_ref, r_left_ref=r_ref, z_ref=nan, psi_ref=nan,
            u_ad=u, dV_deg=dV, dH_deg=dH, planes_deg=self.mixer.step(dV, dH), rps=self.speed.step(),
            gamma=pf.gamma, gamma_dot=pf.gamma_dot, p_d_native=self._M @ pf.p_d,
            e_horizontal_m=float(pf.p_T[1]), e_vertical_m=float(pf.p_T[2]), finished=pf.finished)


class LosDepthHeadingStack(Stack):
    """``los_2023``: LineOfSightDepth -> DepthHeadingInnerLoop -> PlaneMixer."""

    def __init__(self, name: str, config: Mapping[str, Any], path: Any) -> None:
        super().__init__(name, config, path)
        self.guidance = LineOfSightDepth(self.path, LOSGains.from_config(require(config, "guidance", name)))
        l1 = L1Augmentation.from_config(require(config, "l1", name), bool(config.get("adaptation", True)))
        self.inner = DepthHeadingInnerLoop(l1, DepthHeadingPD(require(config, "autopilot", name)))
        _check_Ts(self, self.guidance.gains.Ts, l1, self.inner.autopilot.Ts)

    def _step(self, state: VehicleState, x: dict[str, Any]) -> ControlOutput:
        los = self.guidance.step(x["p"], x["heading"], float(x["v_flu"][0]))
        dV, dH, u = self.inner.step(los.z_d, los.psi_d, float(x["p"][2]), x["theta"], x["heading"])
        nan = float("nan")
        return ControlOutput(
            t=float(state.t), q_c=nan, r_c=nan, q_up_ref=nan, r_left_ref=nan, z_ref=los.z_d, psi_ref=los.psi_d,
            u_ad=u, dV_deg=dV, dH_deg=dH, planes_deg=self.mixer.step(dV, dH), rps=self.speed.step(),
            gamma=los.gamma, gamma_dot=los.gamma_dot, p_d_native=self._M @ los.p_d,
            e_horizontal_m=los.y_T, e_vertical_m=los.z_err, finished=los.finished)


def prepare_stacks(stacks: Sequence[Stack], states: Sequence[VehicleState]) -> None:
    """Prepare the next :meth:`Stack.step` of many stacks, each for its state: their inputs (:meth:`Stack.inputs`)
    computed together (:func:`_inputs_together`) and the rate stacks' path-following laws' tick together
    (:func:`~bb2_control.path_following.prepare_steps`, ~10 us per law for 64 laws against 40 us alone).  Each
    stack's ``step(state)`` then gives what it gives alone, bit for bit; a stack stepped with another state object
    computes it alone.  (The batch of missions calls this every tick.)"""
    chosen, chosen_states, vecs = [], [], []
    for stack, state in zip(stacks, states):
        stack._prepared_inputs = None
        if not isinstance(stack, RatePathFollowingStack):
            continue
        vec = state.as_vector()
        if not (np.isfinite(vec).all() and math.isfinite(state.t)):
            continue
        chosen.append(stack)
        chosen_states.append(state)
        vecs.append(vec)
    if not chosen:
        return
    xs = _inputs_together(chosen, chosen_states, np.array(vecs))
    for stack, state, x in zip(chosen, chosen_states, xs):
        stack._prepared_inputs = (state, x)
    prepare_steps([stack.guidance for stack in chosen], np.array([x["p"] for x in xs]),
                  np.array([x["R_BI"] for x in xs]), np.array([x["v_flu"] for x in xs]))


def _inputs_together(stacks: Sequence[Stack], states: Sequence[VehicleState], X: np.ndarray
                     ) -> list[dict[str, Any]]:
    """:meth:`Stack.inputs` of many stacks for their states (X (N, 12): their vectors), bit for bit each one's own
    call: the body->earth rotations of all at once (``rotation_native`` on arrays: each its own call's), the frame
    changes as products by the signed-permutation matrices D_FLIP and M (entries 0 and +-1: every output is one
    input's value, its sign or a sum of zeros, the same whatever the BLAS kernel).  A stack whose frame matrix has
    other entries takes its own call."""
    out: list[dict[str, Any] | None] = [None] * len(stacks)
    exact = [i for i, st in enumerate(stacks) if st._M_signed_permutation]
    if exact:
        Xe = X[exact]
        R = np.ascontiguousarray(frames.rotation_native(Xe[:, 3], Xe[:, 4], Xe[:, 5]).transpose(2, 0, 1))
        R_BI_native = np.matmul(R, frames.D_FLIP)
        v_flu = np.matmul(Xe[:, 6:9], frames.D_FLIP.T)
        rows = Xe.tolist()
        for j, i in enumerate(exact):
            st, r = stacks[i], rows[j]
            MT = st._M.T
            out[i] = dict(p=MT @ Xe[j, 0:3], R_BI=MT @ R_BI_native[j], v_flu=v_flu[j], q_up=r[10], r_left=r[11],
                          theta=r[4], heading=r[5] + st._heading_offset)
    for i, st in enumerate(stacks):
        if out[i] is None:
            out[i] = st.inputs(states[i])
    return out  # type: ignore[return-value]


def _check_Ts(stack: Stack, *others: Any) -> None:
    vals = [stack.Ts]
    for o in others:
        if isinstance(o, L1Augmentation):
            vals += [c.design.Ts for c in o.channels.values()]
        else:
            vals.append(float(o))
    if not np.allclose(vals, stack.Ts, rtol=0, atol=1e-12):
        raise ControlConfigError(f"stack {stack.name}: every piece must use the same Ts, got {vals}")


_TYPES = {"rate_pf_3d": RatePathFollowingStack, "los_depth_heading": LosDepthHeadingStack}


# ------------------------------------------------------------------------------------------ building
def available_stacks() -> list[str]:
    """Names of the stacks defined in ``data/stacks.yaml``."""
    return sorted(load_data("stacks")["stacks"])


def _resolve_sections(cfg: dict[str, Any]) -> dict[str, Any]:
    out = dict(cfg)
    for key, fname in _SECTION_FILES.items():
        v = out.get(key)
        if isinstance(v, str):
            table = load_data(fname)
            table = table.get("configs", table)
            if v not in table:
                raise ControlConfigError(f"{key}: no entry {v!r} in {fname}.yaml (have {sorted(table)})")
            out[key] = dict(table[v])
    return out


_OPTIONAL_KEYS: dict[str, frozenset[str]] = {
    "": frozenset({"name", "description", "source"}),
    "mixer": frozenset({"matrix_rows_planes_cols_dV_dH"}),
    "l1": frozenset({"M_ss", "M_tf", "Q"}),   # a channel's own filter and Lyapunov weight, at any depth below l1
}
"""Keys a stack reads when given though its data files do not write them (``cfg.get`` with a default): allowed in
an override besides the keys of the stack it starts from."""


_MISSING = object()


def _unknown_override_keys(over: Mapping[str, Any], base: Mapping[str, Any], where: str = "") -> list[str]:
    """Dotted keys of ``over`` (a stack file's or mapping's changes to a named stack, or ``overrides``) that the
    resolved ``base`` does not have: typos that would change nothing.  A section given by name (a string: a whole
    entry of its data file) replaces the section and is not looked into."""
    out = []
    section = where.split(".", 1)[0]
    for k, v in over.items():
        path = f"{where}.{k}" if where else str(k)
        known = base.get(k, _MISSING) if isinstance(base, Mapping) else _MISSING
        if path == "mixer":
            known = deep_merge(load_data("mixer"), known if isinstance(known, Mapping) else {})
        if known is _MISSING:
            if k in _OPTIONAL_KEYS.get(section, ()) or (not where and k in _OPTIONAL_KEYS[""]):
                continue
            close = close_name(k, base if isinstance(base, Mapping) else ())
            out.append(path + (f" (did you mean {(where + '.' if where else '') + close}?)" if close else ""))
        elif isinstance(v, Mapping) and isinstance(known, Mapping):
            out += _unknown_override_keys(v, known, path)
    return out


def _refuse_unknown_keys(over: Mapping[str, Any], base: Mapping[str, Any], label: str, what: str) -> None:
    bad = _unknown_override_keys({k: v for k, v in over.items() if k != "base"}, base)
    if bad:
        raise ControlConfigError(f"stack {label!r}: unknown key(s) {', '.join(bad)}: {what} has no such key "
                                 "(it would change nothing)")


def resolve_config(name_or_config: str | Path | Mapping[str, Any] | None = None,
                   overrides: Mapping[str, Any] | None = None) -> tuple[str, dict[str, Any]]:
    """Full configuration (every named section replaced by its data) of a stack name, file or mapping.

    A file or mapping either defines a stack (``type`` ...) or starts from a named one with ``base: <name>``
    and overrides keys (nested mappings merge).  ``overrides`` are applied last.
    """
    stacks = load_data("stacks")
    if name_or_config is None:
        name_or_config = stacks.get("default", "rate_2022")
    if isinstance(name_or_config, Mapping):
        doc, label = dict(name_or_config), str(name_or_config.get("name", "custom"))
    else:
        s = str(name_or_config)
        if Path(s).suffix.lower() in (".yaml", ".yml", ".json"):
            doc, label = load_mapping(s), Path(s).stem
        elif s in stacks["stacks"]:
            doc, label = {"base": s}, s
        else:
            raise UnknownStackError(f"unknown control stack {s!r}; available: {sorted(stacks['stacks'])} "
                                    "(or give a .yaml/.json stack file)")
    base_name = doc.pop("base", None)
    if base_name is not None:
        if base_name not in stacks["stacks"]:
            raise UnknownStackError(f"unknown base stack {base_name!r}; available: {sorted(stacks['stacks'])}")
        base_cfg = _resolve_sections(stacks["stacks"][base_name])
        _refuse_unknown_keys(doc, base_cfg, label if label != "custom" else base_name, f"stack {base_name}")
        cfg = deep_merge(base_cfg, _resolve_sections(doc))
        label = doc.get("name", base_name if label in ("custom",) else label)
    else:
        cfg = _resolve_sections(doc)
    if overrides:
        _refuse_unknown_keys(overrides, cfg, label, f"stack {label}")
        cfg = _resolve_sections(deep_merge(cfg, _resolve_sections(dict(overrides))))
    if cfg.get("type") not in _TYPES:
        raise ControlConfigError(f"stack {label!r}: type must be one of {sorted(_TYPES)}, got {cfg.get('type')!r}")
    return label, cfg


def build_stack(name_or_config: str | Path | Mapping[str, Any] | None = None, path: Any = None,
                overrides: Mapping[str, Any] | None = None) -> Stack:
    """Build a stack.

    Args:
        name_or_config: a stack name (``rate_2022``, ``los_2023``), a YAML/JSON stack file, or a mapping;
            None = the default stack (``rate_2022``).
        path: a ``bb2_planner`` BernsteinPath, a path file / shipped path name, or None for the stack's
            default ``path``.  It is converted to the stack's frame.
        overrides: nested mapping merged into the configuration (e.g. ``{"adaptation": False}``,
            ``{"guidance": {"d_m": 100.0}}``).

    Raises:
        UnknownStackError: unknown stack name.  ControlConfigError: malformed configuration.
    """
    label, cfg = resolve_config(name_or_config, overrides)
    if path is None or isinstance(path, (str, Path)):
        from bb2_planner.paths import load_path

        path = load_path(path if path is not None else require(cfg, "path", f"stack {label}"))
    return _TYPES[cfg["type"]](label, cfg, path)


def build_mixer(name_or_config: str | Path | Mapping[str, Any] | None = None,
                overrides: Mapping[str, Any] | None = None) -> PlaneMixer:
    """Only the X-plane mixer of a stack (what a mixer process needs: no path, no guidance)."""
    _, cfg = resolve_config(name_or_config, overrides)
    return mixer_from_config(cfg)


def build_speed_command(name_or_config: str | Path | Mapping[str, Any] | None = None,
                        overrides: Mapping[str, Any] | None = None) -> SpeedCommand:
    """Only the propeller feed-forward of a stack."""
    label, cfg = resolve_config(name_or_config, overrides)
    return SpeedCommand.from_config(require(cfg, "speed", f"stack {label}"))
