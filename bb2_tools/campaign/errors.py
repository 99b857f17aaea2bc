"""The campaign's input error (its own module so that every other module of the package can import it)."""
from __future__ import annotations

__all__ = ["SpecError"]


class SpecError(ValueError):
    """A malformed SPEC or command line (the message names the field; the CLI exits 2)."""
