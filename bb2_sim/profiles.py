"""Physics profiles: ``iowa`` (the authors' model, every quirk) and ``corrected`` (named fixes).

The switches and their documentation are data (``data/profiles.yaml``); each maps to one quirk of
SPEC section 15 so users can ablate the fixes one by one.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from functools import lru_cache
from pathlib import Path
from typing import Mapping

from bb2_sim.yaml_files import load as load_yaml

DATA = Path(__file__).resolve().parent / "data" / "profiles.yaml"


class ProfileError(ValueError):
    """Unknown profile or switch."""


@dataclass(frozen=True)
class Profile:
    """One set of physics switches (all False = the authors' implementation)."""

    name: str = "iowa"
    euler_roll_inertia: bool = False
    zuvw_b_abs_beta: bool = False
    kpp_once: bool = False
    thrust_deduction_wired: bool = False
    static_forces_correct: bool = False
    free_surface_clipping: bool = False
    wave_velocity_in_phase: bool = False
    zero_speed_guard: bool = False
    speed_pi_feedforward: bool = False
    n_planes_clamped_depth: bool = False

    def switches(self) -> dict[str, bool]:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "name"}


@lru_cache(maxsize=1)
def _data() -> dict:
    return load_yaml(DATA.read_text())


def switch_docs() -> dict[str, str]:
    """Switch name -> 'Qn: what it fixes'."""
    return {k: f"{v['quirk']}: {v['doc']}" for k, v in _data()["switches"].items()}


def profile_names() -> list[str]:
    return list(_data()["profiles"])


def get_profile(spec: "str | Profile | Mapping" = "iowa") -> Profile:
    """A profile by name (``iowa``/``corrected``), or a mapping ``{base: ..., switch: bool, ...}``."""
    if isinstance(spec, Profile):
        return spec
    data = _data()
    if isinstance(spec, str):
        if spec not in data["profiles"]:
            raise ProfileError(f"unknown physics profile {spec!r} (choose from {', '.join(data['profiles'])})")
        return Profile(name=spec, **(data["profiles"][spec] or {}))
    spec = dict(spec)
    base = get_profile(spec.pop("base", "iowa"))
    known = set(data["switches"])
    bad = set(spec) - known
    if bad:
        raise ProfileError(f"unknown profile switch(es) {sorted(bad)} (known: {sorted(known)})")
    sw = base.switches()
    sw.update({k: bool(v) for k, v in spec.items()})
    name = base.name + "".join(f"{'+' if v else '-'}{k}" for k, v in spec.items())
    return Profile(name=name, **sw)


def at_rest_hint(profile: "str | Profile | Mapping", speed_mps: float, diverged_at_s: float) -> str:
    """For a run that diverged at its start: '' or why, when it started at rest (``speed_mps`` 0) under a profile
    without ``zero_speed_guard`` -- the authors' model is singular at zero relative speed (Q13: ``u/|u|`` and the
    plane incidence divide by it) -- and the profiles that start from rest."""
    p = get_profile(profile)
    if p.zero_speed_guard or speed_mps != 0.0 or diverged_at_s > 0.0:
        return ""
    quirk = _data()["switches"]["zero_speed_guard"]["quirk"]
    return (f"it started at rest: the {p.name} profile is singular at zero relative speed ({quirk}: u/|u| and the "
            "plane incidence divide by it, as in the authors' model); the corrected profile starts from rest, as "
            "does any with zero_speed_guard: true ({base: iowa, zero_speed_guard: true})")
