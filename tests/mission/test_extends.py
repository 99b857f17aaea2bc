"""``extends:``: one reading for every tool (``bb2_mission.schema.read_mission_document``): each base is found
beside the file that names it, then in the working directory, then, a bare name, among the shipped missions; the
library's ``load_mission`` and ``bb2-campaign`` read the same document (the campaign resolved a nested ``extends``
beside the top file, and a mission file that is no text stopped it with a traceback)."""
from __future__ import annotations

import pytest
import yaml

from bb2_mission.schema import MISSIONS_DIR, MissionError, load_mission, read_mission_document


def test_a_bare_name_extends_the_shipped_mission(tmp_path):
    f = tmp_path / "short.yaml"
    f.write_text("extends: canyon\nduration_s: 4\n")
    m = load_mission(f)
    shipped = load_mission("canyon")
    assert m.duration_s == 4.0 and m.path_source == shipped.path_source and m.stack == shipped.stack
    assert read_mission_document(f) == {**yaml.safe_load((MISSIONS_DIR / "canyon.yaml").read_text()),
                                        "duration_s": 4}


def test_a_file_beside_it_wins_over_a_shipped_name(tmp_path):
    (tmp_path / "canyon").write_text("name: mine\nduration_s: 7\n")   # no suffix: a file of that very name
    f = tmp_path / "m.yaml"
    f.write_text("extends: canyon\n")
    assert read_mission_document(f)["name"] == "mine"


def test_a_nested_extends_is_found_beside_the_file_that_names_it(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "base.yaml").write_text("extends: canyon\nduration_s: 9\nname: base\n")
    (tmp_path / "sub" / "mid.yaml").write_text("extends: ../base.yaml\nname: mid\n")
    (tmp_path / "top.yaml").write_text("extends: sub/mid.yaml\nduration_s: 2\n")
    doc = read_mission_document(tmp_path / "top.yaml")
    assert doc["duration_s"] == 2 and doc["name"] == "mid" and "path" in doc
    assert load_mission(tmp_path / "top.yaml").duration_s == 2.0


@pytest.mark.parametrize("text, said", [
    ("extends: no_such_mission\n", "extends: mission file 'no_such_mission' not found"),
    ("extends: [canyon]\n", "extends: mission file ['canyon'] not found"),
    ("extends: me.yaml\n", "extends: cycle through"),
])
def test_a_bad_extends_names_it(tmp_path, text, said):
    f = tmp_path / "me.yaml"
    f.write_text(text)
    with pytest.raises(MissionError, match="extends") as e:
        read_mission_document(f)
    assert said in str(e.value)


def test_the_campaign_reads_the_same_document(tmp_path):
    pytest.importorskip("pyarrow")
    from bb2_tools.campaign.spec import SpecError, parse_spec

    (tmp_path / "sub").mkdir()
    (tmp_path / "base.yaml").write_text("extends: canyon\nduration_s: 9\n")
    (tmp_path / "sub" / "mid.yaml").write_text("extends: ../base.yaml\nname: mid\n")
    spec = parse_spec({"mission": str(tmp_path / "sub" / "mid.yaml"), "samples": 1})
    assert spec.base == {**read_mission_document(tmp_path / "sub" / "mid.yaml")}
    (tmp_path / "bin.yaml").write_bytes(b"name: x\n\xd0\xff\x00\n")
    with pytest.raises(SpecError, match=r"mission: .*bin.yaml: not UTF-8 text \(byte 8\)"):
        parse_spec({"mission": str(tmp_path / "bin.yaml"), "samples": 1})


def test_a_misspelt_shipped_name_is_named_with_the_likely_one(tmp_path, monkeypatch):
    """``bb2-sim mission canyn`` and ``extends: circel`` said only 'No such file or directory' / 'not found': both
    now name the likely shipped mission and list the shipped ones (a path, or a name with a suffix, gets no list)."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(MissionError) as exc:
        load_mission("canyn")
    assert str(exc.value).startswith("canyn: cannot read mission file (No such file or directory) (did you mean "
                                     "'canyon'?); shipped missions: canyon, canyon_los,"), exc.value
    (tmp_path / "e.yaml").write_text("extends: circel\n")
    with pytest.raises(MissionError, match=r"extends: mission file 'circel' not found \(did you mean 'circle'\?\); "
                                           r"shipped missions: canyon"):
        load_mission(tmp_path / "e.yaml")
    with pytest.raises(MissionError) as exc:
        load_mission(tmp_path / "nope.yaml")
    assert "shipped missions" not in str(exc.value)
