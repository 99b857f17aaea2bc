"""The likely name behind a misspelt key, option, node or parameter, for the one-line errors that refuse it.

Every file and command of the project refuses a name it does not know (a mission's ``duraton_s``, a stack's
``guidanc``, a params file's ``rate_hzz``, ``--without mixr``) in one line; these say the close one it knows, by
:func:`difflib.get_close_matches` (ratio >= 0.6, the standard library's default), the same way everywhere.
"""
from __future__ import annotations

import difflib
from typing import Iterable

__all__ = ["close_name", "did_you_mean", "unknown_keys_hint"]

CUTOFF = 0.6
"""The similarity ratio a known name must reach to be offered (difflib's default)."""


def close_name(name: object, known: Iterable[object]) -> str | None:
    """The known name closest to ``name``, or None when none is close."""
    close = difflib.get_close_matches(str(name), sorted({str(k) for k in known}), 1, CUTOFF)
    return close[0] if close else None


def did_you_mean(name: object, known: Iterable[object], *, quote: bool = True) -> str:
    """``" (did you mean 'rate_hz'?)"`` (``quote=False``: ``" (did you mean rate_hz?)"``), or ``""``."""
    close = close_name(name, known)
    if close is None:
        return ""
    return f" (did you mean {close!r}?)" if quote else f" (did you mean {close}?)"


def unknown_keys_hint(unknown: Iterable[object], known: Iterable[object]) -> str:
    """For a list of unknown keys: ``" (did you mean 'duration_s'?)"`` for one, ``" (did you mean 'stack' for
    'stak', 'path' for 'pth'?)"`` for several (those with a close known key), or ``""``."""
    unknown, known = [str(u) for u in unknown], [str(k) for k in known]
    pairs = [(u, c) for u in unknown if (c := close_name(u, known)) is not None]
    if not pairs:
        return ""
    if len(unknown) == 1:
        return f" (did you mean {pairs[0][1]!r}?)"
    return " (did you mean " + ", ".join(f"{c!r} for {u!r}" for u, c in pairs) + "?)"
