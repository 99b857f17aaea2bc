"""Maneuver settings written as a document (a campaign's maneuver options): a mission's ``sea:`` and ``current:``
blocks give the maneuver's sea and current as ``bb2-sim maneuver``'s sea and current options do, and an unknown
setting is named with the one it is most likely a typo of."""
from __future__ import annotations

import pytest

from bb2_sim.maneuvers import ManeuverError, maneuver_settings, with_sea


def test_a_sea_block_gives_the_maneuver_its_irregular_sea():
    s = maneuver_settings("turning-circle", sea={"spectrum": "jonswap", "hs": 2, "tp": 8, "seed": 3})
    assert s.environment is not None and s.sea_state == 0
    sea = s.environment.sea
    assert (sea.spectrum, sea.hs, sea.tp, sea.seed) == ("jonswap", 2.0, 8.0, 3)


def test_the_maneuvers_default_sea_state_is_not_the_blocks_but_a_given_one_is():
    """depth-heading flies sea state 5 by default: a spectrum block with its own Hs and Tp takes none of it (as
    ``bb2-sim maneuver depth-heading --spectrum jonswap --hs 2 --tp 8``); a sea state given with the settings
    gives a spectrum block its Hs and Tp from the table (as ``--sea-state 3 --spectrum jonswap``)."""
    assert maneuver_settings("depth-heading").sea_state == 5
    s = maneuver_settings("depth-heading", sea={"spectrum": "jonswap", "hs": 2, "tp": 8})
    assert (s.environment.sea.hs, s.environment.sea.sea_state) == (2.0, 0)   # 0: none (the SeaSpec default)
    given = maneuver_settings("turning-circle", sea_state=3, sea={"spectrum": "jonswap"})
    assert given.environment.sea.effective_hs_tp == maneuver_settings(
        "turning-circle", sea={"spectrum": "jonswap", "sea_state": 3}).environment.sea.effective_hs_tp
    assert given.environment.sea.effective_hs_tp[0] > 0


def test_a_current_alone_flies_in_the_maneuvers_sea_state():
    s = maneuver_settings("depth-heading", current={"speed_mps": 0.5, "heading_deg": 90})
    assert s.environment.sea.authors_table and s.sea_state == 5
    assert (s.environment.current.speed_mps, s.environment.current.heading_deg) == (0.5, 90.0)


def test_without_blocks_the_settings_are_as_before():
    s = maneuver_settings("turning-circle", rudder_deg=25)
    assert s.environment is None and with_sea(s) is s


@pytest.mark.parametrize("kw, said", [
    ({"sea": {"hs": 2, "tp": 8, "spectrum": "jonswap", "swell": 1}}, "unknown key(s) in sea: ['swell']"),
    ({"sea": 3}, "sea must be a mapping"),
    ({"sea": {"hs": 2}}, "sea: hs need a spectrum"),
    ({"current": {"speed_mps": -1}}, "current.speed_mps must be >= 0"),
    ({"sea": {"sea_state": 3, "spectrum": "jonswap"}, "sea_state": 4}, "sea_state 4 and sea.sea_state 3: give one"),
    ({"environment": {"hs": 2}}, "give the sea and the current as sea: and current: blocks"),
    ({"duration_s": 20}, "'duration_s' (did you mean 'duration'?)"),
    ({"speed_kn": 8}, "'speed_kn' (did you mean 'speed_mps'?)"),
])
def test_a_bad_setting_is_one_message_naming_it(kw, said):
    with pytest.raises(ManeuverError) as e:
        maneuver_settings("turning-circle", **kw)
    assert said in str(e.value), str(e.value)
    assert "\n" not in str(e.value)
