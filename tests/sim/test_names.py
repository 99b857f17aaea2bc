"""bb2_sim.names: the likely name behind a misspelt one, as every refusal of the project says it."""
from __future__ import annotations

from bb2_sim.names import close_name, did_you_mean, unknown_keys_hint


def test_the_close_name_or_none():
    assert close_name("rate_hzz", ["rate_hz", "startup_timeout_s"]) == "rate_hz"
    assert close_name("mixr", ("planner", "mixer")) == "mixer"
    assert close_name("zzz", ["rate_hz"]) is None
    assert close_name("x", []) is None
    assert close_name(3, [1, 2, 3]) == "3"  # keys of any type (YAML), compared as text


def test_did_you_mean_quoted_or_bare():
    assert did_you_mean("guidanc", ["guidance", "mixer"]) == " (did you mean 'guidance'?)"
    assert did_you_mean("guidanc", ["guidance"], quote=False) == " (did you mean guidance?)"
    assert did_you_mean("zzz", ["guidance"]) == ""


def test_unknown_keys_hint_for_one_or_several():
    assert unknown_keys_hint(["duraton_s"], ["duration_s", "path"]) == " (did you mean 'duration_s'?)"
    assert unknown_keys_hint(["stak", "qqq", "pth"], ["stack", "path"]) == \
        " (did you mean 'stack' for 'stak', 'path' for 'pth'?)"
    assert unknown_keys_hint(["qqq"], ["stack"]) == ""
