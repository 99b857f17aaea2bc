"""How the project reads YAML: PyYAML's safe loader with YAML 1.2's numbers.

PyYAML implements YAML 1.1, whose floats need a dot and a signed exponent: ``1e-3``, ``1e9`` and ``1.0e9`` are read
as *strings* there, while ROS 2's parameter files (rcl reads them with yaml-cpp, YAML 1.2) read them as numbers.
A mission, stack, sensor, fleet or campaign file that writes a gain or a noise density as ``1e-3`` then failed
with "must be a number, got '1e-3'".  :func:`load` reads them as numbers, as ROS 2 does; everything else
(booleans, integers, the 1.1 float forms, dates) is the safe loader's unchanged.
"""
from __future__ import annotations

import re
from typing import IO, Any

import yaml

# YAML 1.2 core schema floats beyond those YAML 1.1 already reads: an exponent without a dot ("1e9", "-2E-3") or
# without its sign ("1.5e3", ".5e3"); digits may carry the 1.1 underscores, as PyYAML's own float forms do
_FLOAT_1_2 = re.compile(r"""^(?:[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+
                            |[-+]?\.[0-9][0-9_]*[eE][-+]?[0-9]+)$""", re.X)


class Loader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that also reads YAML 1.2's exponent forms as floats."""


Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_1_2, list("-+0123456789."))


def load(stream: str | bytes | IO[str] | IO[bytes]) -> Any:
    """Parse one YAML document as ``yaml.safe_load`` does, with YAML 1.2's numbers (``1e-3`` is a float).

    Raises ``yaml.YAMLError`` on malformed YAML, as ``yaml.safe_load``.
    """
    return yaml.load(stream, Loader=Loader)  # noqa: S506  (a SafeLoader subclass)
