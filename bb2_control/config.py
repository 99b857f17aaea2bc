"""Loading of bb2_control data files (YAML or JSON) and nested overrides."""
from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any, Mapping

import yaml

from bb2_control.errors import ControlConfigError
from bb2_sim.yaml_files import load as load_yaml

DATA_DIR = Path(__file__).resolve().parent / "data"

__all__ = ["DATA_DIR", "load_mapping", "load_data", "deep_merge", "require"]


_PARSED: dict[tuple[str, int, int], dict[str, Any]] = {}
_PARSED_MAX = 64


def load_mapping(path: str | Path) -> dict[str, Any]:
    """Read a YAML (.yaml/.yml) or JSON (.json) file holding a mapping (a fresh copy each call).

    A file is parsed once per process while its modification time and size stay the same (building a stack reads
    its data files nine times: ~0.1 s of YAML parsing per mission, which a campaign worker paid for every run)."""
    p = Path(path)
    if not p.is_file():
        raise ControlConfigError(f"configuration file not found: {p}")
    st = p.stat()
    key = (str(p.resolve()), st.st_mtime_ns, st.st_size)
    data = _PARSED.get(key)
    if data is None:
        text = p.read_text()
        try:
            data = json.loads(text) if p.suffix.lower() == ".json" else load_yaml(text)
        except (json.JSONDecodeError, yaml.YAMLError) as exc:
            raise ControlConfigError(f"cannot parse {p}: {exc}") from None
        if not isinstance(data, dict):
            raise ControlConfigError(f"{p} must hold a mapping at top level, got {type(data).__name__}")
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.pop(next(iter(_PARSED)))
        _PARSED[key] = data
    return copy.deepcopy(data)


def load_data(name: str) -> dict[str, Any]:
    """Load ``bb2_control/data/<name>.yaml``."""
    return load_mapping(DATA_DIR / f"{name}.yaml")


def deep_merge(base: Mapping[str, Any], overrides: Mapping[str, Any] | None) -> dict[str, Any]:
    """Copy of ``base`` with ``overrides`` applied recursively (mappings merge, other values replace)."""
    out = copy.deepcopy(dict(base))
    for k, v in (overrides or {}).items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def require(cfg: Mapping[str, Any], key: str, where: str) -> Any:
    """``cfg[key]`` or a ControlConfigError naming the missing key and the section."""
    try:
        return cfg[key]
    except (KeyError, TypeError):
        raise ControlConfigError(f"{where}: missing key {key!r}") from None
