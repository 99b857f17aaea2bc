"""The campaign SPEC: parsing, validation (one clear message naming the field) and the run design.

See :mod:`bb2_tools.campaign` for the file format.  Everything here is deterministic: the design (which
inputs run ``index`` flies, and its seed) is a function of the SPEC alone, so any process can rebuild run
``index`` without the others.
"""
from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import yaml

from bb2_sim.names import unknown_keys_hint
from bb2_sim.outputs import plain_name
from bb2_sim.yaml_files import load as load_yaml
from bb2_tools.campaign.errors import SpecError

__all__ = ["SpecError", "Vary", "CampaignSpec", "load_spec", "parse_spec", "run_seed", "set_dotted", "default_sea",
           "RESERVED_COLUMNS", "SAMPLING"]

RESERVED_COLUMNS = ("index", "seed", "status", "message", "wall_time_s")
SAMPLING = ("random", "latin_hypercube")
_TOP = {"name", "description", "mission", "maneuver", "seed", "samples", "vary", "collect", "sampling",
        "seed_key"}
_DIST_KEYS = {"uniform", "normal", "choice", "value"}
_MAX_RUNS = 10_000_000


# ------------------------------------------------------------------------------------------ helpers
def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def _num(v: Any, what: str) -> float:
    if not _is_num(v):
        raise SpecError(f"{what} must be a finite number, got {v!r}")
    return float(v)


def _kind(values: Sequence[Any]) -> str:
    """Column type of a set of input values: bool, int, float, str or json (anything else, as JSON text)."""
    if all(isinstance(v, bool) for v in values):
        return "bool"
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return "int"
    if all(_is_num(v) for v in values):
        return "float"
    if all(isinstance(v, str) for v in values):
        return "str"
    return "json"


def column_value(v: Any, kind: str) -> Any:
    """An input value as stored in the results table (JSON text for lists/mappings)."""
    if kind == "json":
        return json.dumps(v, sort_keys=True)
    if kind == "float":
        return float(v)
    return v


def run_seed(campaign_seed: int, index: int) -> int:
    """The seed of run ``index``: a 32-bit integer from ``SeedSequence([campaign_seed, index])``."""
    return int(np.random.SeedSequence([int(campaign_seed), int(index)]).generate_state(1, np.uint32)[0])


def set_dotted(doc: dict[str, Any], key: str, value: Any) -> None:
    """Set ``a.b.c`` in a nested document (mappings are created as needed; a numeric part indexes a list).

    A stack given by name (``stack: rate_2022``) becomes the inline mapping ``{base: rate_2022}`` first, so
    ``stack.guidance.d_m`` overrides one gain of the named stack.
    """
    parts = key.split(".")
    d: Any = doc
    for i, p in enumerate(parts[:-1]):
        here = ".".join(parts[: i + 1])
        if isinstance(d, list):
            d = d[_list_index(d, p, here)]
            continue
        sub = d.get(p)
        if sub is None:
            sub = {}
        elif i == 0 and p == "stack" and isinstance(sub, str):
            sub = {"base": sub}
        elif isinstance(sub, list):
            sub = list(sub)
        elif isinstance(sub, Mapping):
            sub = dict(sub)
        else:
            raise SpecError(f"{here} is {sub!r}, not a mapping: cannot set {key}")
        d[p] = sub
        d = sub
    last = parts[-1]
    if isinstance(d, list):
        d[_list_index(d, last, key)] = value
    else:
        d[last] = value


def _list_index(lst: list, part: str, where: str) -> int:
    if not part.isdigit() or int(part) >= len(lst):
        raise SpecError(f"{where}: index {part!r} into a list of {len(lst)}")
    return int(part)


# ------------------------------------------------------------------------------------------ varied inputs
@dataclass(frozen=True)
class Vary:
    """One varied dotted key: a distribution (``uniform``/``normal``/``choice``), a grid (a list) or a constant."""

    key: str
    kind: str                       #: uniform | normal | choice | grid | value
    params: tuple = ()              #: uniform (lo, hi); normal (mean, sd); choice/grid the values; value (v,)
    clip: tuple | None = None       #: normal only: (lo, hi)

    @property
    def random(self) -> bool:
        return self.kind in ("uniform", "normal", "choice")

    @property
    def column_kind(self) -> str:
        if self.kind in ("uniform", "normal"):
            return "float"
        return _kind(list(self.params))

    def from_unit(self, u: float) -> Any:
        """The value at the unit draw ``u`` in [0, 1) (inverse CDF)."""
        if self.kind == "uniform":
            lo, hi = self.params
            return float(lo + (hi - lo) * u)
        if self.kind == "normal":
            from scipy.special import ndtri

            mean, sd = self.params
            x = float(mean + sd * ndtri(min(max(u, 1e-16), 1 - 1e-16)))
            if self.clip is not None:
                x = float(min(max(x, self.clip[0]), self.clip[1]))
            return x
        if self.kind == "choice":
            n = len(self.params)
            return copy.deepcopy(self.params[min(int(u * n), n - 1)])
        raise AssertionError(self.kind)

    def to_doc(self) -> Any:
        """The normalised SPEC form (for campaign.yaml)."""
        if self.kind == "grid":
            return list(self.params)
        if self.kind == "value":
            return {"value": self.params[0]}
        d: dict[str, Any] = {self.kind: list(self.params)}
        if self.clip is not None:
            d["clip"] = list(self.clip)
        return d


def _parse_vary(key: Any, v: Any) -> Vary:
    where = f"vary.{key}"
    if not isinstance(key, str) or not key or any(p == "" for p in key.split(".")):
        raise SpecError(f"vary: keys must be dotted names like sea.hs, got {key!r}")
    if key in RESERVED_COLUMNS:
        raise SpecError(f"{where}: {key!r} is a reserved column name ({', '.join(RESERVED_COLUMNS)})")
    if isinstance(v, list):
        if not v:
            raise SpecError(f"{where}: a grid needs at least one value")
        return Vary(key, "grid", tuple(v))
    if not isinstance(v, Mapping):
        return Vary(key, "value", (v,))
    dists = sorted(set(v) & _DIST_KEYS)
    extra = sorted(set(v) - _DIST_KEYS - {"clip"})
    if len(dists) != 1 or extra:
        raise SpecError(f"{where}: expected a list (grid), a scalar, or one of {{uniform: [lo, hi]}}, "
                        f"{{normal: [mean, sd]}}, {{choice: [a, b, ...]}}, {{value: x}}; got {dict(v)!r}")
    kind = dists[0]
    p = v[kind]
    if "clip" in v and kind != "normal":
        raise SpecError(f"{where}: clip applies to normal only")
    if kind == "value":
        return Vary(key, "value", (p,))
    if kind == "choice":
        if not isinstance(p, list) or not p:
            raise SpecError(f"{where}.choice must be a non-empty list of values, got {p!r}")
        return Vary(key, "choice", tuple(p))
    if not isinstance(p, list) or len(p) != 2:
        raise SpecError(f"{where}.{kind} must be a list of 2 numbers, got {p!r}")
    a, b = _num(p[0], f"{where}.{kind}[0]"), _num(p[1], f"{where}.{kind}[1]")
    if kind == "uniform" and not a < b:
        raise SpecError(f"{where}.uniform needs low < high, got {p!r}")
    if kind == "normal" and not b > 0:
        raise SpecError(f"{where}.normal needs a standard deviation > 0, got {p!r}")
    clip = None
    if "clip" in v:
        c = v["clip"]
        if not isinstance(c, list) or len(c) != 2:
            raise SpecError(f"{where}.clip must be [low, high], got {c!r}")
        clip = (_num(c[0], f"{where}.clip[0]"), _num(c[1], f"{where}.clip[1]"))
        if not clip[0] < clip[1]:
            raise SpecError(f"{where}.clip needs low < high, got {c!r}")
    return Vary(key, kind, (a, b), clip)


# ------------------------------------------------------------------------------------------ the spec
@dataclass
class CampaignSpec:
    """A validated SPEC.  ``base`` is the mission document (``extends`` merged) or the maneuver options."""

    name: str
    target: str                          #: "mission" or "maneuver"
    base: dict[str, Any]                 #: mission document, or maneuver options
    base_dir: str | None                 #: where the mission's relative files are looked up
    source: str                          #: mission file / maneuver name as given
    maneuver: str | None                 #: maneuver name
    seed: int
    samples: int
    vary: tuple[Vary, ...]
    collect: tuple[str, ...]             #: column names of the collected figures
    sampling: str = "random"
    seed_key: str | None = None
    description: str = ""
    spec_file: str | None = None
    graph_dir: str | None = None          #: --graph: each run flies the ROS graph, bags under this directory
    notes: tuple[str, ...] = ()           #: what the campaign chose that the SPEC left open (default_sea)
    _unit: np.ndarray | None = field(default=None, repr=False, compare=False)
    _may_batch: bool | None = field(default=None, repr=False, compare=False)   #: worker.may_batch, remembered

    # -- the design
    @property
    def grid(self) -> tuple[Vary, ...]:
        return tuple(v for v in self.vary if v.kind == "grid")

    @property
    def dists(self) -> tuple[Vary, ...]:
        return tuple(v for v in self.vary if v.random)

    @property
    def n_grid(self) -> int:
        return int(np.prod([len(v.params) for v in self.grid])) if self.grid else 1

    @property
    def n_runs(self) -> int:
        return self.samples * self.n_grid

    @property
    def input_columns(self) -> tuple[str, ...]:
        return tuple(v.key for v in self.vary)

    def unit_draws(self) -> np.ndarray:
        """(samples, n_distributions) unit draws in [0, 1): plain random or a Latin hypercube."""
        if self._unit is None:
            d = len(self.dists)
            ss = np.random.SeedSequence([self.seed, 0x5EED])
            if d == 0:
                self._unit = np.zeros((self.samples, 0))
            elif self.sampling == "latin_hypercube":
                from scipy.stats import qmc

                self._unit = qmc.LatinHypercube(d=d, rng=np.random.default_rng(ss)).random(self.samples)
            else:
                self._unit = np.random.default_rng(ss).random((self.samples, d))
        return self._unit

    def inputs(self, index: int) -> dict[str, Any]:
        """Dotted key -> value of run ``index`` (runs are ``sample * n_grid + grid point``, the last grid
        key fastest)."""
        if not 0 <= index < self.n_runs:
            raise SpecError(f"run index {index} outside 0..{self.n_runs - 1}")
        sample, g = divmod(int(index), self.n_grid)
        u = self.unit_draws()[sample]
        grid_vals: dict[str, Any] = {}
        for v in reversed(self.grid):
            g, k = divmod(g, len(v.params))
            grid_vals[v.key] = copy.deepcopy(v.params[k])
        out: dict[str, Any] = {}
        j = 0
        for v in self.vary:
            if v.random:
                out[v.key] = v.from_unit(float(u[j]))
                j += 1
            elif v.kind == "grid":
                out[v.key] = grid_vals[v.key]
            else:
                out[v.key] = copy.deepcopy(v.params[0])
        return out

    def run_seed(self, index: int) -> int:
        return run_seed(self.seed, index)

    def document(self, index: int) -> dict[str, Any]:
        """The mission document (or maneuver options) of run ``index``: the base with its overrides."""
        doc = copy.deepcopy(self.base)
        for k, val in self.inputs(index).items():
            set_dotted(doc, k, val)
        if self.seed_key:
            set_dotted(doc, self.seed_key, self.run_seed(index))
        return doc

    def to_doc(self) -> dict[str, Any]:
        """The resolved SPEC (what campaign.yaml stores)."""
        d: dict[str, Any] = {"name": self.name}
        if self.description:
            d["description"] = self.description
        if self.target == "mission":
            d["mission"] = self.source
            d["mission_document"] = copy.deepcopy(self.base)
            d["base_dir"] = self.base_dir
        else:
            d["maneuver"] = {"name": self.maneuver, "options": copy.deepcopy(self.base)}
        d.update(seed=self.seed, samples=self.samples, sampling=self.sampling,
                 vary={v.key: v.to_doc() for v in self.vary}, collect=list(self.collect))
        if self.seed_key:
            d["seed_key"] = self.seed_key
        if self.notes:
            d["notes"] = list(self.notes)
        if self.graph_dir:
            d["graph"] = True
        d["runs"] = self.n_runs
        return d


SEA_DEFAULT_SPECTRUM = {False: "pm", True: "jonswap"}
"""The spectrum a campaign gives a sea whose Hs it varies and whose document names none, by whether a peak period
is given (``sea.tp`` in the document or varied): Pierson-Moskowitz (fully developed: Hs alone fixes it) or JONSWAP."""


def default_sea(base: dict[str, Any], vary: Sequence[Vary], seed_key: str | None
                ) -> tuple[dict[str, Any], str | None, tuple[str, ...]]:
    """The sea of a SPEC that varies ``sea.hs`` (say with ``sea.heading_deg``) on a mission or maneuver whose
    document has no sea (a calm mission such as the canyon), or a ``sea:`` block naming no spectrum, component
    list or sea state: without this, every run would be refused (``hs need a spectrum``).

    The base document's sea becomes ``{spectrum: pm, hs: 0, ...}`` (``jonswap`` when a ``tp`` is given or varied;
    Hs 0: the base alone is calm) and, unless the SPEC names a ``seed_key`` or the sea its ``seed``, each run's own
    seed goes into ``sea.seed`` (``seed_key: sea.seed``), so every run flies its own wave phases -- what a Monte
    Carlo of sea states needs.  A ``sea_state: 0`` (the authors' table, calm) is such a calm document, and goes.
    Both choices are returned as notes (the CLI prints them; ``campaign.yaml`` keeps
    them, and the resolved document and seed key are the ones stored).  Any other SPEC is returned unchanged:
    a sea with a spectrum, components or a sea state is the document's own, and a SPEC varying only the sea's
    direction keeps its error (a calm sea has no direction)."""
    keys = {v.key for v in vary}
    sea = base.get("sea")
    calm_table = _is_num(base.get("sea_state")) and float(base["sea_state"]) == 0.0   # sea_state: 0, no sea
    if ("sea.hs" not in keys or ("sea_state" in base and not calm_table) or "sea_state" in keys
            or (sea is not None and not isinstance(sea, Mapping))
            or any(k in (sea or {}) for k in ("spectrum", "components", "sea_state"))
            or keys & {"sea", "sea.spectrum", "sea.components", "sea.sea_state"}):
        return base, seed_key, ()
    sea = dict(sea or {})
    spectrum = SEA_DEFAULT_SPECTRUM["tp" in sea or "sea.tp" in keys]
    sea = {"spectrum": spectrum, **({"hs": 0.0} if "hs" not in sea else {}), **sea}
    notes = [f"vary sets sea.hs and the {'sea block' if base.get('sea') is not None else 'document'} names no "
             f"spectrum: the runs fly a {'Pierson-Moskowitz' if spectrum == 'pm' else 'JONSWAP'} sea "
             f"(sea.spectrum: {spectrum}{', its Tp from Hs' if spectrum == 'pm' else ''}); set sea.spectrum "
             "in the mission or the SPEC to choose another"]
    if seed_key is None and "seed" not in sea and "sea.seed" not in keys:
        seed_key = "sea.seed"
        notes.append("each run flies its own wave phases: its seed goes into sea.seed (seed_key: sea.seed); "
                     "set sea.seed or seed_key to choose")
    return {**{k: v for k, v in base.items() if k != "sea_state"}, "sea": sea}, seed_key, tuple(notes)


def _read_mission_document(file: Path) -> dict[str, Any]:
    """A mission file with its ``extends`` chain merged (:func:`bb2_mission.schema.read_mission_document`, what
    :func:`bb2_mission.schema.load_mission` reads)."""
    from bb2_mission.schema import MissionError, read_mission_document

    try:
        doc = read_mission_document(file)
    except MissionError as e:
        raise SpecError(f"mission: {' '.join(str(e).split())}") from None
    doc.setdefault("name", file.stem)
    return doc


def _find_mission(value: str, spec_dir: Path | None) -> Path:
    from bb2_mission.schema import MISSIONS_DIR

    p = Path(value).expanduser()
    cands = [p] if p.is_absolute() else ([spec_dir / p] if spec_dir else []) + [Path.cwd() / p]
    if not p.is_absolute():   # the shipped missions, from any working directory: canyon, canyon.yaml, missions/...
        if p.suffix == "":
            cands.append(MISSIONS_DIR / f"{value}.yaml")
        cands.append(MISSIONS_DIR / (Path(*p.parts[1:]) if len(p.parts) > 1 and p.parts[0] == MISSIONS_DIR.name
                                     else p))
    for c in cands:
        if c.is_file():
            return c.resolve()
    from bb2_mission.schema import shipped_name_hint

    raise SpecError(f"mission: file {value!r} not found (looked beside the SPEC, in the working directory"
                    f" and in missions/){shipped_name_hint(value)}")


def parse_spec(doc: Any, *, spec_file: str | Path | None = None) -> CampaignSpec:
    """Validate a parsed SPEC document (see :mod:`bb2_tools.campaign`); raises :class:`SpecError`."""
    if not isinstance(doc, Mapping):
        raise SpecError(f"SPEC must be a mapping of settings, got {type(doc).__name__}")
    unknown = sorted(set(map(str, doc)) - _TOP)
    if unknown:
        raise SpecError(f"unknown key(s) {unknown}{unknown_keys_hint(unknown, _TOP)}; allowed: {sorted(_TOP)}")
    spec_dir = Path(spec_file).resolve().parent if spec_file else None
    has_m, has_man = doc.get("mission") is not None, doc.get("maneuver") is not None
    if has_m == has_man:
        raise SpecError("mission / maneuver: give exactly one of 'mission: FILE.yaml' or "
                        "'maneuver: {name: NAME, options: {...}}'")
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SpecError(f"seed must be an integer >= 0, got {seed!r}")
    samples = doc.get("samples", 1)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise SpecError(f"samples must be an integer >= 1, got {samples!r}")
    sampling = doc.get("sampling", "random")
    if sampling not in SAMPLING:
        raise SpecError(f"sampling must be one of {list(SAMPLING)}, got {sampling!r}")
    vary_doc = doc.get("vary") or {}
    if not isinstance(vary_doc, Mapping):
        raise SpecError(f"vary must be a mapping of dotted keys to distributions, got {vary_doc!r}")
    vary = tuple(_parse_vary(k, v) for k, v in vary_doc.items())
    seed_key = doc.get("seed_key")
    if seed_key is not None and (not isinstance(seed_key, str) or not seed_key):
        raise SpecError(f"seed_key must be a dotted key (e.g. sea.seed), got {seed_key!r}")
    if seed_key in {v.key for v in vary}:
        raise SpecError(f"seed_key {seed_key!r} is also varied")

    if has_m:
        mission = doc["mission"]
        if not isinstance(mission, str) or not mission:
            raise SpecError(f"mission must be a mission file name, got {mission!r}")
        f = _find_mission(mission, spec_dir)
        base, base_dir, source, man_name, target = _read_mission_document(f), str(f.parent), mission, None, "mission"
    else:
        man = doc["maneuver"]
        if isinstance(man, str):
            man = {"name": man}
        if not isinstance(man, Mapping) or set(man) - {"name", "options"} or not isinstance(man.get("name"), str):
            raise SpecError(f"maneuver must be {{name: NAME, options: {{...}}}}, got {man!r}")
        from bb2_sim.maneuvers import maneuver_names

        if man["name"] not in maneuver_names():
            raise SpecError(f"maneuver.name {man['name']!r} is not one of {', '.join(maneuver_names())}")
        opts = man.get("options") or {}
        if not isinstance(opts, Mapping):
            raise SpecError(f"maneuver.options must be a mapping, got {opts!r}")
        base, base_dir, source, man_name, target = dict(opts), None, man["name"], man["name"], "maneuver"

    from bb2_tools.campaign.figures import resolve_collect

    collect_doc = doc.get("collect")
    if collect_doc is not None and (not isinstance(collect_doc, list) or not collect_doc
                                    or not all(isinstance(c, str) for c in collect_doc)):
        raise SpecError(f"collect must be a non-empty list of figure names, got {collect_doc!r}")
    collect = resolve_collect(target, man_name, collect_doc)
    clash = sorted(set(collect) & ({v.key for v in vary} | set(RESERVED_COLUMNS)))
    if clash:
        raise SpecError(f"collect: {clash} clash with varied keys or reserved columns")
    if len(set(collect)) != len(collect):
        raise SpecError(f"collect: duplicate names in {list(collect)}")
    try:  # (the default --out folder is named for it)
        name = plain_name(doc.get("name") or (Path(spec_file).stem if spec_file else "campaign"), "name")
    except ValueError as exc:
        raise SpecError(str(exc)) from None
    base, seed_key, notes = default_sea(base, vary, seed_key)
    spec = CampaignSpec(name=name, target=target, base=base, base_dir=base_dir, source=source,
                        maneuver=man_name, seed=seed, samples=samples, vary=vary, collect=tuple(collect),
                        sampling=sampling, seed_key=seed_key, description=str(doc.get("description", "")),
                        spec_file=str(Path(spec_file).resolve()) if spec_file else None, notes=notes)
    if spec.n_runs > _MAX_RUNS:
        raise SpecError(f"samples x grid = {spec.n_runs} runs; at most {_MAX_RUNS}")
    return spec


def load_spec(file: str | Path) -> CampaignSpec:
    """Read, parse and validate a SPEC file (not yet probed against the mission: see
    :func:`bb2_tools.campaign.worker.probe`)."""
    f = Path(file)
    try:
        doc = load_yaml(f.read_text())
    except OSError as e:
        raise SpecError(f"cannot read SPEC ({e.strerror})") from None
    except yaml.YAMLError as e:
        raise SpecError(f"not valid YAML ({' '.join(str(e).split())})") from None
    return parse_spec(doc, spec_file=f)
