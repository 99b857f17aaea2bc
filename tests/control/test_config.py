"""bb2_control.config: a data file is parsed once per process, yet every call gets its own copy and an edited
file is read again."""
import os

import pytest

from bb2_control.config import load_mapping
from bb2_control.errors import ControlConfigError


def test_load_mapping_copies_and_rereads_an_edited_file(tmp_path):
    f = tmp_path / "gains.yaml"
    f.write_text("autopilot: {K_q: 3000.0}\n")
    a = load_mapping(f)
    a["autopilot"]["K_q"] = -1.0                         # a caller changing its copy changes nobody else's
    assert load_mapping(f) == {"autopilot": {"K_q": 3000.0}}
    f.write_text("autopilot: {K_q: 2500.0}\n")           # same size: the modification time tells
    st = f.stat()
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert load_mapping(f) == {"autopilot": {"K_q": 2500.0}}
    f.write_text("- not a mapping\n")
    with pytest.raises(ControlConfigError, match="mapping"):
        load_mapping(f)
