"""The paper's cards A1-A3 (``bpmcal.study.paper``): one definition, read by the tests
(tests/support/paper.py), the benchmarks and the examples."""
import pytest

from bpmcal import params as P
from bpmcal.study import paper


@pytest.mark.parametrize("i", [1, 2, 3])
def test_a_card_is_section_4_2s_set_with_the_fixed_and_the_unstated_parameters(i):
    c = paper.CARDS[f"A{i}"]
    assert c == {**paper.CALIBRATED[f"B{i}"], "rmin_mm": 0.8, "porosity": 0.34,
                 "pb_fa_deg": 35.0, "fric": 0.35}
    assert list(c) == list(P.LINEARPBOND.names)[:8]  # Table 2's order, as the cards are written
    assert P.validate_params(c) == c  # a valid card of the paper's model


def test_the_unstated_parameters_are_the_middle_of_table_2():
    for k, v in paper.UNSTATED.items():
        assert v == pytest.approx((P.PARAMS[k].lo + P.PARAMS[k].hi) / 2, rel=1e-12), k


def test_a_card_is_a_new_dict():
    a = paper.card("B1")
    a["fric"] = 0.5
    assert paper.card("B1")["fric"] == 0.35 and paper.A1["fric"] == 0.35
