"""Material cards have a versioned format (bpmcal.io.card): every card records it, every
reader checks it, and a card of another format is refused with what to do."""
import pytest
import yaml
from support.paper import A1

from bpmcal.cli import main
from bpmcal.io.card import CARD_FORMAT, CardError, read_card, write_card


def test_written_cards_record_the_format_first_and_read_back(tmp_path):
    f = write_card(tmp_path / "B1.yaml", {"specimen": "B1", "parameters": A1,
                                          "targets": {"ucs_MPa": 60.0}})
    assert f.read_text().splitlines()[0] == f"card_format: {CARD_FORMAT}"
    c = read_card(f, need=("parameters", "targets"))
    assert c["parameters"] == A1 and c["card_format"] == CARD_FORMAT


@pytest.mark.parametrize("fmt, needle", [
    (None, "no card_format: a material card of an older bpmcal"),
    (CARD_FORMAT + 1, f"card_format {CARD_FORMAT + 1} is newer than this bpmcal reads"),
    ("1", "card_format='1': expected the integer"),
    (0, "card_format 0 is older than this bpmcal reads"),
])
def test_another_format_is_refused_with_what_to_do(tmp_path, fmt, needle):
    d = {"specimen": "B1", "parameters": A1}
    if fmt is not None:
        d = {"card_format": fmt, **d}
    f = tmp_path / "old.yaml"
    f.write_text(yaml.safe_dump(d, sort_keys=False))
    with pytest.raises(CardError, match=needle.replace("*", r"\*")):
        read_card(f)


@pytest.mark.parametrize("cmd", [
    ["ucs", "--params", "{card}", "--out", "{o}/r.h5"],
    ["impact", "--card", "{card}", "--out", "{o}/i.h5"],
    ["sweep-plan", "--card", "{card}", "--models", "{card}", "--out", "{o}/plan.csv"],
    ["verify", "--card", "{card}", "--models", "{card}", "--out-card", "{o}/c.yaml",
     "--rounds", "{o}/r.csv", "--run", "{o}/b.h5"],
    ["scatter", "--card", "{card}", "--seeds", "1,2", "--runs", "{o}/1.h5", "{o}/2.h5",
     "--seed-runs", "{o}/s.csv", "--table", "{o}/t.csv"],
    ["fresh-seeds", "--card", "{card}", "--seeds", "101,102", "--runs", "{o}/1.h5", "{o}/2.h5",
     "--seed-runs", "{o}/s.csv"],
])
def test_every_command_that_takes_a_card_refuses_an_unversioned_one(tmp_path, capsys, cmd):
    card = tmp_path / "old.yaml"
    card.write_text(yaml.safe_dump({"specimen": "B1", "parameters": A1,
                                    "targets": {"ucs_MPa": 60.0}, "roles": {}, "ranges": {}}))
    o = tmp_path / "out"
    argv = [a.replace("{card}", str(card)).replace("{o}", str(o)) for a in cmd]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no card_format" in err[0] and "rerun 'bpmcal calibrate'" in err[0]
    assert not o.exists()
