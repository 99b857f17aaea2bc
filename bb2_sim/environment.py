"""The sea and current a run is given: the ``sea:`` / ``current:`` blocks (mission file, maneuver options,
simulator node) parsed and validated, built into the ROM's :class:`~bb2_sim.sea.Sea` and
:class:`~bb2_sim.current.Current`, and described as JSON so that a run can be rebuilt from its record alone.

``sea:`` keys (all optional; SI units, degrees only for directions)::

    spectrum:     jonswap | pm | ittc | regular     (none: the authors' regular table by ``sea_state``)
    hs:           significant wave height, m (>= 0; 0 = calm)      jonswap, ittc; pm (its Tp follows from Hs)
    tp:           peak period, s (> 0)                              jonswap, ittc
    gamma:        JONSWAP peak enhancement (>= 1, default 3.3)
    amplitude_m:  regular: wave amplitude, m (default hs / 2)
    period_s:     regular: period, s (default tp)
    heading_deg:  direction the waves travel towards, native earth frame, deg (0 = +x_E, the authors' head
                  seas at psi = 0; 90 = +y_E); default 0
    spreading_s:  cos-2s spreading exponent s (> 0) about heading_deg: short-crested; none = long-crested
    components:   N components of the spectrum (integer >= 1, default 64; with no spectrum refused, as hs is,
                  since it would change nothing), or a CSV component list
                  (amplitude_m, omega_rad_s, direction_deg, phase_deg; no spectrum then), or the exact
                  mapping {amplitude_m, omega_rad_s, direction_rad, phase_rad} of lists (what a bag carries)
    seed:         seed of the random phases (and jitter, directions), integer, default 0
    sea_state:    alone: the authors' regular head-sea table (0..7, 0 and 1 calm, as ``sea_state`` always
                  was); with a spectrum: Hs and Tp from the sea-state table (bb2_sim/data/sea_state_table.yaml)

``current:`` keys: ``speed_mps`` (>= 0), ``heading_deg`` (direction the water moves towards, same
convention), optional ``profile``: ``{depths_m: [...], factors: [...]}`` (table, factor of the surface speed)
or ``{water_depth_m: d, alpha: 1/7}`` (power law).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .constants import G_M_S2
from .current import Current
from .names import unknown_keys_hint
from .sea import (AuthorsTableSea, ComponentSea, Cos2sSpreading, Sea, SeaInputError, WaveComponents, calm_sea,
                  discretise, read_components_csv, regular_components, sea_state_hs_tp, spectrum)

__all__ = ["SEA_KEYS", "CURRENT_KEYS", "SPECTRA", "DESCRIPTION_FORMAT", "SeaSpec", "CurrentSpec", "Environment",
           "sea_from_mapping", "current_from_mapping", "environment_from_description"]

SEA_KEYS = ("spectrum", "hs", "tp", "gamma", "amplitude_m", "period_s", "heading_deg", "spreading_s",
            "components", "seed", "sea_state")
CURRENT_KEYS = ("speed_mps", "heading_deg", "profile")
SPECTRA = ("jonswap", "pm", "ittc", "regular")
DEFAULT_COMPONENTS = 64
DEFAULT_GAMMA = 3.3
DESCRIPTION_FORMAT = "bb2_sea/1"
EXACT_KEYS = ("amplitude_m", "omega_rad_s", "direction_rad", "phase_rad")


def _num(v: Any, what: str, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise SeaInputError(f"{what} must be a number, got {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise SeaInputError(f"{what} must be finite, got {v!r}")
    if positive and not x > 0:
        raise SeaInputError(f"{what} must be > 0, got {v!r}")
    if nonneg and x < 0:
        raise SeaInputError(f"{what} must be >= 0, got {v!r}")
    return x


def _int(v: Any, what: str, *, minimum: int | None = None) -> int:
    x = _num(v, what)
    if x != int(x):
        raise SeaInputError(f"{what} must be an integer, got {v!r}")
    if minimum is not None and x < minimum:
        raise SeaInputError(f"{what} must be >= {minimum}, got {v!r}")
    return int(x)


# ------------------------------------------------------------------------------------------------ sea
@dataclass(frozen=True)
class SeaSpec:
    """A validated ``sea:`` block (see the module docstring); ``components`` is an int N, a CSV file path
    (str) or the exact :class:`WaveComponents`."""

    spectrum: str | None = None
    hs: float | None = None
    tp: float | None = None
    gamma: float = DEFAULT_GAMMA
    amplitude_m: float | None = None
    period_s: float | None = None
    heading_deg: float = 0.0
    spreading_s: float | None = None
    components: Any = DEFAULT_COMPONENTS
    seed: int = 0
    sea_state: float = 0
    _realised: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def authors_table(self) -> bool:
        """The authors' regular table (``sea_state``), not a component sea."""
        return self.spectrum is None and isinstance(self.components, int)

    @property
    def effective_hs_tp(self) -> tuple[float | None, float | None]:
        """(Hs, Tp) of the spectrum: the given ones or the sea-state table's."""
        if self.spectrum is not None and (self.hs is None or self.tp is None) and self.sea_state:
            hs, tp = sea_state_hs_tp(self.sea_state)
            return (self.hs if self.hs is not None else hs), (self.tp if self.tp is not None else tp)
        return self.hs, self.tp

    def wave_components(self, g: float = G_M_S2) -> WaveComponents | None:
        """The linear components of this sea (None = calm or the authors' table)."""
        if self.authors_table:
            return None
        key = float(g)
        if key not in self._realised:
            self._realised[key] = self._build_components(key)
        return self._realised[key]

    def _build_components(self, g: float) -> WaveComponents | None:
        c = self.components
        if isinstance(c, WaveComponents):
            return WaveComponents(c.amplitude, c.omega, c.direction, c.phase, g)
        if isinstance(c, str):
            try:
                return read_components_csv(c, g)
            except OSError as exc:
                raise SeaInputError(f"cannot read the wave component file {c}: {exc.strerror or exc}") from None
        hs, tp = self.effective_hs_tp
        if self.spectrum == "regular":
            a = self.amplitude_m if self.amplitude_m is not None else (hs / 2.0 if hs is not None else None)
            T = self.period_s if self.period_s is not None else tp
            if a is None or T is None:
                raise SeaInputError("a regular sea needs amplitude_m (or hs) and period_s (or tp)")
            if a == 0:
                return None
            return regular_components(a, T, self.heading_deg, 0.0, g)
        if hs is None or hs == 0:
            if hs is None:
                raise SeaInputError(f"spectrum {self.spectrum} needs hs (m) or a sea_state")
            return None
        if self.spectrum == "pm":
            spec = spectrum("pm", hs=hs, g=g)
        else:
            if tp is None:
                raise SeaInputError(f"spectrum {self.spectrum} needs tp (s) or a sea_state")
            spec = spectrum("jonswap", hs=hs, tp=tp, gamma=self.gamma) if self.spectrum == "jonswap" \
                else spectrum("ittc", hs=hs, tp=tp)
        spreading = None if self.spreading_s is None else Cos2sSpreading(math.radians(self.heading_deg),
                                                                         self.spreading_s)
        return discretise(spec, int(c), seed=self.seed, spreading=spreading, mean_direction_deg=self.heading_deg,
                          g=g)

    def build(self, params=None) -> Sea:
        """The ROM's sea (:class:`AuthorsTableSea` for the table, else a :class:`ComponentSea`)."""
        from .parameters import load_parameters

        params = params or load_parameters()
        if self.authors_table:
            return AuthorsTableSea.for_sea_state(self.sea_state, params)
        comps = self.wave_components(params.g)
        return calm_sea() if comps is None else ComponentSea(comps)

    def as_dict(self) -> dict[str, Any]:
        """The block as given (JSON-safe; components: N, the file path, or the exact lists)."""
        out: dict[str, Any] = {}
        for k in SEA_KEYS:
            v = getattr(self, k)
            if k == "components" and isinstance(v, WaveComponents):
                v = _exact(v)
            out[k] = v
        return out

    def steepness_warning(self, g: float = G_M_S2) -> str:
        """Before a run: '' or one line when this sea is steeper than any deep-water wave can be (a regular wave's
        H / L, a spectrum's Hs / Lp, with L = g T^2 / 2 pi, beyond the breaking limit of ``data/sea_spectra.yaml``):
        a typo (Hs 30 m, Tp 0.9 s) more often than a sea.  The linear model flies it all the same.  Not checked:
        the authors' table, given components, a Pierson-Moskowitz sea (its Tp follows from Hs)."""
        from .sea.data import sea_data

        if self.authors_table or not isinstance(self.components, int) or self.spectrum in (None, "pm"):
            return ""
        hs, tp = self.effective_hs_tp
        if self.spectrum == "regular":
            h = 2.0 * self.amplitude_m if self.amplitude_m is not None else hs
            period, what = (self.period_s if self.period_s is not None else tp), "H / L"
        else:
            h, period, what = hs, tp, "Hs / Lp"
        if not h or not period:
            return ""
        limit = float(sea_data()["limits"]["breaking_steepness"]["value"])
        length = g * period ** 2 / (2.0 * math.pi)
        steep = h / length
        if steep <= limit:
            return ""
        return (f"the sea ({self.summary()}) has {what} = {h:g} / {length:.3g} m = {steep:.3f}, steeper than any "
                f"deep-water wave ({limit:g}: beyond it waves break): no such sea exists; the linear model flies it "
                f"all the same")

    def summary(self) -> str:
        """One line for a printout."""
        if self.authors_table:
            return f"sea state {self.sea_state:g} (the authors' regular table)"
        c = self.components
        if isinstance(c, str):
            return f"wave components from {c}"
        if isinstance(c, WaveComponents):
            return f"{len(c)} given wave components (Hs {c.hs:.3f} m)"
        hs, tp = self.effective_hs_tp
        head = f"heading {self.heading_deg:g} deg"
        if self.spectrum == "regular":
            a = self.amplitude_m if self.amplitude_m is not None else (hs or 0.0) / 2.0
            T = self.period_s if self.period_s is not None else tp
            return f"regular wave A {a:g} m, T {T:g} s, {head}"
        spread = "long-crested" if self.spreading_s is None else f"cos-2s s = {self.spreading_s:g}"
        tps = "" if self.spectrum == "pm" or tp is None else f", Tp {tp:g} s"
        gam = f", gamma {self.gamma:g}" if self.spectrum == "jonswap" else ""
        return (f"{self.spectrum} Hs {hs:g} m{tps}{gam}, {head}, {spread}, {int(c)} components, seed {self.seed}")


def _exact(c: WaveComponents) -> dict[str, list[float]]:
    return {"amplitude_m": [float(v) for v in c.amplitude], "omega_rad_s": [float(v) for v in c.omega],
            "direction_rad": [float(v) for v in c.direction], "phase_rad": [float(v) for v in c.phase]}


def _components_value(v: Any, where: str, base_dir: Path | None) -> Any:
    if isinstance(v, Mapping):
        missing = [k for k in EXACT_KEYS if k not in v]
        extra = sorted(set(v) - set(EXACT_KEYS))
        if missing or extra:
            raise SeaInputError(f"{where}.components as a mapping needs exactly {', '.join(EXACT_KEYS)}")
        try:
            arrs = [np.asarray(v[k], dtype=float) for k in EXACT_KEYS]
        except (TypeError, ValueError):
            raise SeaInputError(f"{where}.components: non-numeric values") from None
        return WaveComponents(*arrs)
    if isinstance(v, str):
        p = Path(v).expanduser()
        if not p.is_absolute() and base_dir is not None and (base_dir / p).exists():
            p = base_dir / p
        if not p.is_file():
            raise SeaInputError(f"{where}.components: wave component file {v!r} not found")
        read_components_csv(p)   # readable and valid now, not at the first step
        return str(p)
    return _int(v, f"{where}.components (number of components)", minimum=1)


def sea_from_mapping(doc: Mapping[str, Any] | None, *, where: str = "sea", base_dir: Path | None = None) -> SeaSpec:
    """Validate a ``sea:`` block (module docstring); :class:`SeaInputError` with one message for any fault."""
    if doc is None:
        return SeaSpec()
    if not isinstance(doc, Mapping):
        raise SeaInputError(f"{where} must be a mapping of {', '.join(SEA_KEYS)}, got {doc!r}")
    bad = sorted(set(doc) - set(SEA_KEYS))
    if bad:
        raise SeaInputError(f"unknown key(s) in {where}: {bad}{unknown_keys_hint(bad, SEA_KEYS)}; "
                            f"allowed: {list(SEA_KEYS)}")
    d = {k: v for k, v in doc.items() if v is not None}
    kw: dict[str, Any] = {}
    spec = d.get("spectrum")
    if spec is not None:
        key = str(spec).lower().replace("-", "_")
        key = {"pierson_moskowitz": "pm", "bretschneider": "ittc"}.get(key, key)
        if key not in SPECTRA:
            raise SeaInputError(f"{where}.spectrum must be one of {', '.join(SPECTRA)}, got {spec!r}")
        kw["spectrum"] = key
    for k in ("hs", "amplitude_m"):
        if k in d:
            kw[k] = _num(d[k], f"{where}.{k}", nonneg=True)
    for k in ("tp", "period_s", "spreading_s"):
        if k in d:
            kw[k] = _num(d[k], f"{where}.{k}", positive=True)
    if "gamma" in d:
        kw["gamma"] = _num(d["gamma"], f"{where}.gamma")
        if kw["gamma"] < 1.0:
            raise SeaInputError(f"{where}.gamma must be >= 1, got {d['gamma']!r}")
    if "heading_deg" in d:
        kw["heading_deg"] = _num(d["heading_deg"], f"{where}.heading_deg")
    if "seed" in d:
        kw["seed"] = _int(d["seed"], f"{where}.seed", minimum=0)
    if "sea_state" in d:
        kw["sea_state"] = _num(d["sea_state"], f"{where}.sea_state", nonneg=True)
    if "components" in d:
        kw["components"] = _components_value(d["components"], where, base_dir)
    comps = kw.get("components", DEFAULT_COMPONENTS)
    given = isinstance(comps, (str, WaveComponents))
    if given and "spectrum" in kw:
        raise SeaInputError(f"{where}: give either a spectrum or a component list, not both")
    # (a count of components is a wave key too: of no spectrum it would be a calm sea)
    wave_keys = sorted(set(kw) & {"hs", "tp", "gamma", "amplitude_m", "period_s", "heading_deg", "spreading_s",
                                  *(() if given else ("components",))})
    if "spectrum" not in kw and not given and wave_keys:
        raise SeaInputError(f"{where}: {', '.join(wave_keys)} need a spectrum (jonswap, pm, ittc, regular)")
    if given and wave_keys:
        raise SeaInputError(f"{where}: a component list carries its own waves; {', '.join(wave_keys)} not used")
    if "sea_state" in kw and ("spectrum" in kw or given):
        if given:
            raise SeaInputError(f"{where}: sea_state and a component list exclude each other")
        if "hs" in kw and "tp" in kw:
            raise SeaInputError(f"{where}: sea_state gives Hs and Tp; do not give hs and tp as well")
        if kw["sea_state"] != 0:
            sea_state_hs_tp(kw["sea_state"])   # in the table
    elif "sea_state" in kw:
        from .parameters import load_parameters
        from .waves import wave_for_sea_state
        wave_for_sea_state(kw["sea_state"], load_parameters())
    s = SeaSpec(**kw)
    if s.spectrum is not None:
        s.wave_components()   # every fault (missing hs/tp, ...) now, with its message
    return s


# ------------------------------------------------------------------------------------------------ current
@dataclass(frozen=True)
class CurrentSpec:
    """A validated ``current:`` block."""

    speed_mps: float = 0.0
    heading_deg: float = 0.0
    profile: Mapping[str, Any] | None = None

    def build(self) -> Current | None:
        """The ROM's current (None when there is none)."""
        if self.speed_mps == 0.0:
            return None
        p = self.profile
        prof = None
        if p is not None:
            if "depths_m" in p:
                prof = ("table", list(p["depths_m"]), list(p["factors"]))
            else:
                prof = ("power", p["water_depth_m"], p.get("alpha", 1.0 / 7.0))
        return Current(self.speed_mps, self.heading_deg, prof)

    def as_dict(self) -> dict[str, Any]:
        return {"speed_mps": self.speed_mps, "heading_deg": self.heading_deg,
                "profile": None if self.profile is None else {k: (list(v) if isinstance(v, (list, tuple)) else v)
                                                              for k, v in self.profile.items()}}

    def summary(self) -> str:
        if self.speed_mps == 0.0:
            return "no current"
        prof = "uniform" if self.profile is None else ("table profile" if "depths_m" in self.profile
                                                       else "power-law profile")
        return f"current {self.speed_mps:g} m/s towards {self.heading_deg:g} deg, {prof}"


def current_from_mapping(doc: Mapping[str, Any] | None, *, where: str = "current") -> CurrentSpec:
    """Validate a ``current:`` block; :class:`SeaInputError` with one message for any fault."""
    if doc is None:
        return CurrentSpec()
    if not isinstance(doc, Mapping):
        raise SeaInputError(f"{where} must be a mapping of {', '.join(CURRENT_KEYS)}, got {doc!r}")
    bad = sorted(set(doc) - set(CURRENT_KEYS))
    if bad:
        raise SeaInputError(f"unknown key(s) in {where}: {bad}{unknown_keys_hint(bad, CURRENT_KEYS)}; "
                            f"allowed: {list(CURRENT_KEYS)}")
    if doc and "speed_mps" not in doc:  # a heading or profile of no current: a forgotten speed, not a calm
        raise SeaInputError(f"{where}: {', '.join(sorted(doc))} without speed_mps: give the current's speed (m/s, "
                            "0 for none)")
    speed = _num(doc.get("speed_mps", 0.0), f"{where}.speed_mps", nonneg=True)
    heading = _num(doc.get("heading_deg", 0.0), f"{where}.heading_deg")
    p = doc.get("profile")
    prof = None
    if p is not None:
        if not isinstance(p, Mapping):
            raise SeaInputError(f"{where}.profile must be a mapping, got {p!r}")
        if set(p) == {"depths_m", "factors"}:
            d, f = p["depths_m"], p["factors"]
            if not isinstance(d, (list, tuple)) or not isinstance(f, (list, tuple)):
                raise SeaInputError(f"{where}.profile depths_m and factors must be lists")
            prof = {"depths_m": [_num(v, f"{where}.profile.depths_m[{i}]", nonneg=True) for i, v in enumerate(d)],
                    "factors": [_num(v, f"{where}.profile.factors[{i}]", nonneg=True) for i, v in enumerate(f)]}
        elif "water_depth_m" in p and set(p) <= {"water_depth_m", "alpha"}:
            prof = {"water_depth_m": _num(p["water_depth_m"], f"{where}.profile.water_depth_m", positive=True),
                    "alpha": _num(p.get("alpha", 1.0 / 7.0), f"{where}.profile.alpha", positive=True)}
        else:
            raise SeaInputError(f"{where}.profile must be {{depths_m: [...], factors: [...]}} or "
                                f"{{water_depth_m: d, alpha: a}}, got {dict(p)!r}")
    spec = CurrentSpec(speed, heading, prof)
    spec.build()   # the Current's own checks (increasing depths, equal lengths)
    return spec


# ------------------------------------------------------------------------------------------------ both
@dataclass(frozen=True)
class Environment:
    """The sea and the current of a run."""

    sea: SeaSpec = SeaSpec()
    current: CurrentSpec = CurrentSpec()

    @classmethod
    def from_mappings(cls, sea: Mapping[str, Any] | None = None, current: Mapping[str, Any] | None = None, *,
                      base_dir: Path | None = None) -> "Environment":
        return cls(sea_from_mapping(sea, base_dir=base_dir), current_from_mapping(current))

    def model_kwargs(self, params=None) -> dict[str, Any]:
        """Keyword arguments of :class:`~bb2_sim.model.BB2Model` (``sea_state``, ``sea``, ``current``):
        the authors' table goes in as ``sea_state`` exactly as before."""
        if self.sea.authors_table:
            return {"sea_state": self.sea.sea_state, "current": self.current.build()}
        return {"sea": self.sea.build(params), "current": self.current.build()}

    def summary(self) -> str:
        return f"{self.sea.summary()}; {self.current.summary()}"

    def description(self, g: float = G_M_S2) -> dict[str, Any]:
        """JSON-safe record of the sea and current: the blocks as given plus the realised components in
        full precision (radians), from which :func:`environment_from_description` rebuilds the same sea."""
        comps = self.sea.wave_components(g)
        sea = self.sea.as_dict()
        realised = None
        if comps is not None:
            realised = _exact(comps)
            realised["hs_m"] = comps.hs
        return {"format": DESCRIPTION_FORMAT, "sea": sea, "current": self.current.as_dict(), "g": float(g),
                "components": realised, "summary": self.summary()}

    def description_json(self, g: float = G_M_S2) -> str:
        return json.dumps(self.description(g), allow_nan=False)


def environment_from_description(desc: str | Mapping[str, Any]) -> Environment:
    """Rebuild the :class:`Environment` of a :meth:`Environment.description` (dict or JSON text): the sea
    from its realised components (exact), or the authors' table by its sea state."""
    d = json.loads(desc) if isinstance(desc, str) else dict(desc)
    if d.get("format") != DESCRIPTION_FORMAT:
        raise SeaInputError(f"not a sea description of format {DESCRIPTION_FORMAT!r}: {d.get('format')!r}")
    cur = current_from_mapping(d.get("current"))
    comps = d.get("components")
    if comps is not None:
        sea = sea_from_mapping({"components": {k: comps[k] for k in EXACT_KEYS}})
    else:
        block = dict(d.get("sea") or {})
        if block.get("spectrum") is not None:   # a calm spectral sea (hs 0 / amplitude 0)
            sea = SeaSpec(spectrum=block["spectrum"], hs=0.0, amplitude_m=0.0)
        else:
            sea = sea_from_mapping({"sea_state": block.get("sea_state", 0)})
    return Environment(sea, cur)
