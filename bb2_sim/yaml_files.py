"""How the project reads YAML: PyYAML's safe loader with YAML 1.2's numbers.

PyYAML implements YAML 1.1, whose floats need a dot and a signed exponent: ``1e-3``, ``1e9`` and ``1.0e9`` are read
as *strings* there, while ROS 2's parameter files (rcl reads them with yaml-cpp, YAML 1.2) read them as numbers.
A mission, stack, sensor, fleet or campaign file that writes a gain or a noise density as ``1e-3`` then failed
with "must be a number, got '1e-3'".  :func:`load` reads them as numbers, as ROS 2 does; everything else
(booleans, integers, the 1.1 float forms, dates) is the safe loader's unchanged.

A key written twice in one mapping is an error (YAML says keys are unique; PyYAML keeps the last without a word,
so a mission with two ``duration_s:`` lines, or a fleet with the same boat twice, flew one of them silently).
Keys brought in by a merge (``<<: *base``) may be overridden, as YAML intends.
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
    """``yaml.SafeLoader`` that also reads YAML 1.2's exponent forms as floats, and refuses a mapping that writes
    one key twice."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, Any] = {}
            for key_node, _value in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":   # '<<': merged keys may be overridden
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.setdefault(key, key_node.start_mark)
                except TypeError:   # an unhashable key: the safe loader's own error
                    continue
                if first is not key_node.start_mark:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"found the key {key!r} twice (first on line {first.line + 1})",
                        key_node.start_mark)
        return super().construct_mapping(node, deep)


Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_1_2, list("-+0123456789."))


class YAMLError(yaml.YAMLError):
    """Malformed YAML, said in one line (``line 3, column 1: found the key 'duration_s' twice (first on line 2)``):
    PyYAML's own message spans five lines with the text quoted, which a one-line error of a CLI cannot carry.  A
    ``yaml.YAMLError``, so every ``except yaml.YAMLError`` takes it."""


def _one_line(exc: yaml.YAMLError) -> str:
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        what = exc.problem or exc.context or type(exc).__name__
        if exc.context and exc.problem and exc.context_mark is not None:
            what += f" ({exc.context} at line {exc.context_mark.line + 1})"
        return where + " ".join(what.split())
    return " ".join(str(exc).split())


def load(stream: str | bytes | IO[str] | IO[bytes]) -> Any:
    """Parse one YAML document as ``yaml.safe_load`` does, with YAML 1.2's numbers (``1e-3`` is a float).

    Raises :class:`YAMLError` (a ``yaml.YAMLError``) on malformed YAML or a key written twice, in one line.
    """
    try:
        return yaml.load(stream, Loader=Loader)  # noqa: S506  (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        raise YAMLError(_one_line(exc)) from None
