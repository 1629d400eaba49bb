"""The one registry of lab tests: name -> :class:`LabTestKind`.

Everything that differs between the lab tests and that more than one place needs is here,
once: the test's driver class (``driver.LabTest``; none for the impact, which the driver
does not run) and settings class, the specimen's boundary and size, the study's
per-sample key, the series of its peak, the summary keys that must be finite and the one
that is its measure, its verdict, and the dataset columns its summary gives. Read by the
runner (``runner.lab_test``, the inputs a run records), the run-file writer
(``stages.runs.run_test_file``), the stages (``stages.measure.RUNNERS``), the CLI (the
study-scale note) and gather (``study.gather``). A new test is one entry here.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .brazilian import BrazilianTest, BTSSettings
from .brazilian import settings_dict as _bts_dict
from .direct_tension import DirectTensionTest, DTTSettings
from .direct_tension import settings_dict as _dtt_dict
from .impact import ImpactSettings
from .impact import settings_dict as _impact_dict
from .triaxial import TriaxialSettings, TriaxialTest
from .triaxial import settings_dict as _tx_dict
from .ucs import UCSSettings, UCSTest
from .ucs import settings_dict as _ucs_dict
from .validity import cut_off_reason


@dataclass(frozen=True)
class LabTestKind:
    """One lab test. ``name``: the run file's ``test``; ``sample``: its key in a design
    sample's runs and the dataset (``P.SAMPLE_TESTS``' values, ``ucs``; None: not a
    per-sample test); ``title``: for messages; ``specimen``: what it loads;
    ``test_class``: its ``driver.LabTest`` (None: not driven); ``settings`` and
    ``settings_dict``: its settings class and their dict for the run file's inputs (under
    ``<name>_``); ``boundary``: the vessel walls its specimen keeps
    (``specimen.build_specimen``); ``disc``: its specimen is the Brazilian disc (the
    loaded length is the diameter); ``scale``: the specimen's key in
    ``runner.STUDY_SCALES`` and ``scale_key`` the config key that sizes it in the study;
    ``peak_series``: the series whose maximum is its peak (None: none); ``finite``: the
    summary keys a good run has finite; ``measure``: (what it measures, the summary key
    of its peak, unit), None for a test without a quasi-static peak; ``retests``: an
    invalid specimen is discarded and another tested within the test
    (``BTSSettings.retests``); ``invalid_what``: what an invalid run is (tests with a
    verdict ``<name>_valid``); ``responses`` (summary key -> dataset column) and
    ``columns`` (the dataset's columns, in order) of a per-sample test besides the UCS;
    ``confined``: its inputs record ``sigma3_MPa``."""

    name: str
    sample: str | None
    title: str
    specimen: str
    test_class: type | None
    settings: type
    settings_dict: object
    boundary: str
    scale: str
    scale_key: str
    peak_series: str | None
    finite: tuple[str, ...]
    measure: tuple[str, str, str] | None
    disc: bool = False
    retests: bool = False
    invalid_what: str = ""
    responses: dict = field(default_factory=dict)
    columns: tuple[str, ...] = ()
    confined: bool = False


LAB_TESTS: dict[str, LabTestKind] = {k.name: k for k in (
    LabTestKind("ucs", "ucs", "UCS", "UCS cylinder", UCSTest, UCSSettings, _ucs_dict,
                "platens", "cylinder", "specimen.scale", "axial_stress",
                ("ucs_MPa", "E_GPa", "nu"), ("sigma_c", "ucs_MPa", "MPa")),
    LabTestKind("bts", "bts", "Brazilian", "Brazilian disc", BrazilianTest, BTSSettings,
                _bts_dict, "free", "disc", "bts.scale", "load", ("bts_MPa",),
                ("sigma_t", "bts_peak_MPa", "MPa"), disc=True, retests=True,
                invalid_what="the fracture did not start in the disc's central zone or did "
                             "not split it",
                responses={"bts_MPa": "bts_MPa", "wall_s": "bts_wall_s",
                           "bts_valid": "bts_valid", "bts_peak_MPa": "bts_peak_MPa",
                           "balls_across": "bts_balls_across", "discs": "bts_discs"},
                columns=("bts_MPa", "bts_wall_s", "bts_status", "bts_error", "bts_valid",
                         "bts_peak_MPa", "bts_balls_across", "bts_discs")),
    LabTestKind("dtt", "dtt", "direct-tension", "direct-tension cylinder", DirectTensionTest,
                DTTSettings, _dtt_dict, "free", "cylinder", "specimen.scale", "axial_stress",
                (), ("sigma_t", "dtt_peak_MPa", "MPa"),
                invalid_what="the specimen broke next to a grip",
                responses={"dtt_MPa": "dtt_MPa", "wall_s": "dtt_wall_s",
                           "dtt_valid": "dtt_valid", "dtt_peak_MPa": "dtt_peak_MPa",
                           "balls_across": "dtt_balls_across"},
                columns=("dtt_MPa", "dtt_wall_s", "dtt_status", "dtt_error", "dtt_valid",
                         "dtt_peak_MPa", "dtt_balls_across")),
    LabTestKind("triaxial", "tri", "triaxial", "triaxial cylinder", TriaxialTest,
                TriaxialSettings, _tx_dict, "vessel", "cylinder", "specimen.scale",
                "deviator", ("sigma1_MPa", "E_GPa", "nu"),
                ("sigma_1 at failure", "sigma1_MPa", "MPa"),
                responses={"sigma1_MPa": "tri_MPa", "sigma3_MPa": "tri_sigma3_MPa",
                           "wall_s": "tri_wall_s"},
                columns=("tri_MPa", "tri_sigma3_MPa", "tri_wall_s", "tri_status",
                         "tri_error"), confined=True),
    LabTestKind("impact", None, "impact", "impact cylinder", None, ImpactSettings,
                _impact_dict, "platens", "impact", "impact.scale", None, (), None),
)}

#: the tests of a design sample by their sample key (``ucs``, ``bts``, ``dtt``, ``tri``)
SAMPLE_KINDS: dict[str, LabTestKind] = {k.sample: k for k in LAB_TESTS.values() if k.sample}


def kind(name: str) -> LabTestKind:
    """The registered lab test ``name`` (a KeyError naming the known ones otherwise)."""
    try:
        return LAB_TESTS[name]
    except KeyError:
        raise KeyError(f"lab test {name!r}: expected one of {', '.join(LAB_TESTS)}") from None


def incomplete_reason(test: str, summary: dict) -> str:
    """Why a finished run of ``test`` measured nothing (``validity.cut_off_reason`` of its
    measure: a quasi-static test stopped at a cut-off before its peak and drop), "" for
    a complete run or a test without such a measure (the impact, an unknown name)."""
    k = LAB_TESTS.get(test)
    return cut_off_reason(k.measure if k else None, summary)
