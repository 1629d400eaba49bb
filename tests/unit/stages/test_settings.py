"""A stage's settings value (:mod:`bpmcal.stages.settings`): its limited fields are
checked (and converted) when it is built, naming the field; ``limits`` lists them."""
from dataclasses import dataclass

import pytest

from bpmcal.analysis.calibration.loop_settings import Limit
from bpmcal.io.checks import BadInput
from bpmcal.stages.settings import SEED, check_fields, limits, setting


@dataclass(frozen=True)
class Knobs:
    files: tuple = ()
    share: float = setting(10.0, Limit("float", 0.0, 100.0))
    folds: int = setting(5, Limit("int", 2, 20))
    kind: str = setting("gain", Limit("choice", words=("gain", "shap")))
    seed: int = setting(11, SEED)

    def __post_init__(self):
        check_fields(self)


def test_a_value_is_checked_and_converted_when_built():
    k = Knobs(share=50, folds=3)
    assert k.share == 50.0 and isinstance(k.share, float) and k.folds == 3
    assert list(limits(Knobs)) == ["share", "folds", "kind", "seed"]


@pytest.mark.parametrize("name, bad", [("share", 100.1), ("share", float("nan")),
                                       ("folds", 1), ("folds", 2.5), ("folds", True),
                                       ("kind", "weight"), ("seed", 2 ** 32)])
def test_a_bad_value_is_refused_naming_the_field(name, bad):
    with pytest.raises(BadInput, match=f"^{name}="):
        Knobs(**{name: bad})
