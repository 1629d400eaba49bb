"""A stage's settings as one value: the fields of a frozen dataclass that are config keys
carry their :class:`~bpmcal.analysis.calibration.loop_settings.Limit` (the closed loop's
limit type), checked once when the value is built; the ``bpmcal`` command takes each
option's default, bounds and choices from the field (``bpmcal.cli.args.limited``), and
the config schema states the same (``tests/workflow/test_stage_settings.py``).

Used by :class:`~.screening.ScreeningSettings`, :class:`~.regression.RegressionSettings`
and :class:`~.calibration.CalibrationSettings`.
"""
from __future__ import annotations

from dataclasses import field, fields

from ..analysis.calibration.loop_settings import Limit

#: a packing or random seed
SEED = Limit("int", 0, 2 ** 32 - 1, what="a seed")


def setting(default, limit: Limit):
    """A field of a settings dataclass: its ``default`` and the ``limit`` its values are
    checked against (:func:`check_fields`)."""
    return field(default=default, metadata={"limit": limit})


def check_fields(obj) -> None:
    """Check (and convert: an int of a float field is a float) every field of ``obj``
    that has a limit; BadInput naming the field and what it accepts. For a frozen
    dataclass's ``__post_init__``."""
    for f in fields(obj):
        if "limit" in f.metadata:
            object.__setattr__(obj, f.name, f.metadata["limit"].check(f.name,
                                                                       getattr(obj, f.name)))


def limits(cls) -> dict[str, Limit]:
    """Field name -> its limit, of the fields of ``cls`` that have one."""
    return {f.name: f.metadata["limit"] for f in fields(cls) if "limit" in f.metadata}
