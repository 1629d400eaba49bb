"""Per-seed measurement: the strength of a per-sample test (``P.SAMPLE_TESTS``: σt on a
Brazilian disc or a direct-tension cylinder, σ1 of the triaxial test) on one packing seed,
as the closed loop (:mod:`.loop_runs`), the transfer, the fresh-seed check
(:mod:`.fresh_seeds`) and the posterior's refinement runs measure it: an invalid run
replaced (:func:`valid_tensile_run`), a tensile strength the mean of several specimens
(:func:`seed_strength`, :func:`combine_specimens`), written into a seed's row
(:func:`row_strength`); the tests a seed runs (:class:`SeedTests`).

The seeds of these measurements follow the one seed scheme (:mod:`bpmcal.lab.seeds`):
specimen j of packing seed s is packed with ``replicate_seed(s, j)``, the m-th
replacement of an invalid run with ``replacement_seed(., m)`` (m <= ``MAX_REPLACEMENTS``),
and a Brazilian disc's own ISRM retests, which the lab runs within one test, with
``retest_seed``; :func:`packing_seed_gap` shows that no two of them share a packing. An
invalid run is replaced in ``seeds.retry``, the one retry loop.

Every DEM run of the closed loop, the transfer, the seed scatter, the fresh-seed check and
the posterior's refinement goes through :data:`RUNNERS`, looked up at the call: the one
seam through which a test replaces the DEM.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..analysis.calibration.loop_settings import MAX_TENSILE_SPECIMENS
from ..io.checks import BadInput
from ..lab import seeds
from ..lab.brazilian import BTSSettings
from ..lab.direct_tension import DTTSettings
from ..lab.registry import SAMPLE_KINDS
from ..lab.runner import Geometry
from ..lab.runner import bts_geometry as _isrm_disc
from ..lab.triaxial import TriaxialSettings
from ..lab.ucs import UCSSettings
from ..params import SAMPLE_TESTS, TENSILE_TESTS
from .runs import RUN_FILES

#: the tensile tests by their test names (``bts``, ``dtt``: the values of
#: ``params.TENSILE_TESTS``, response -> test), whose strength a seed may measure on several
#: specimens (``tensile_specimens``, packed with ``seeds.replicate_seed``)
TENSILE_TEST_NAMES: tuple[str, ...] = tuple(TENSILE_TESTS.values())
#: (the replicate stride under the name the CLI's help and the benchmarks read)
TENSILE_REPLICATE_STRIDE = seeds.REPLICATE_STRIDE


def packing_seed_gap(max_retests: int = 10) -> tuple[int, int]:
    """``seeds.packing_seed_gap`` over the closed loop's tensile specimens
    (``MAX_TENSILE_SPECIMENS``): two seeds closer than the gap never share a packing."""
    return seeds.packing_seed_gap(MAX_TENSILE_SPECIMENS, max_retests)


#: the DEM runner of each test, by the test's name: the UCS test (a
#: closed-loop seed's, a seed scatter's, a fresh seed's) and the per-sample tests
#: (``P.SAMPLE_TESTS``' tests: :func:`valid_tensile_run`). Looked up here at every call,
#: never bound at import: the seam through which tests replace the DEM
#: (``monkeypatch.setitem(measure.RUNNERS, "bts", fake)``)
RUNNERS = {key: RUN_FILES[k.name] for key, k in SAMPLE_KINDS.items()}


def disc_geometry(geometry):
    """The Brazilian disc (ISRM 50 x 25 mm) at the scale and with the genesis options of
    the UCS cylinder ``geometry``."""
    return _isrm_disc(scale=geometry.scale, sigma0_MPa=geometry.sigma0_MPa,
                      install_gap_mm=geometry.install_gap_mm,
                      relax_ratio=geometry.relax_ratio, genesis=geometry.genesis)


@dataclass(frozen=True)
class SeedTests:
    """The tests a packing seed of a card runs, and how (the closed loop's, the
    transfer's, the fresh seeds', the posterior's refinement runs): the UCS cylinder
    ``geometry`` loaded with ``settings``; the Brazilian disc ``bts_geometry`` (None: the
    ISRM disc at the cylinder's scale and genesis, :func:`disc_geometry`) loaded with
    ``bts_settings``; the direct-tension cylinder ``dtt_geometry`` (None: the UCS
    cylinder) with ``dtt_settings``; the triaxial test at the design confinement,
    ``tri_settings`` (its ``sigma3``), on the UCS cylinder (None: none, and a card with a
    triaxial-strength target cannot be run). Which of them a seed runs is its card's
    targets'."""

    geometry: Geometry = field(default_factory=Geometry)
    settings: UCSSettings = field(default_factory=UCSSettings)
    bts_geometry: Geometry | None = None
    bts_settings: BTSSettings = field(default_factory=BTSSettings)
    dtt_geometry: Geometry | None = None
    dtt_settings: DTTSettings = field(default_factory=DTTSettings)
    tri_settings: TriaxialSettings | None = None

    @property
    def disc(self) -> Geometry:
        """The Brazilian disc (``bts_geometry``, or the ISRM disc at the cylinder's scale)."""
        return self.bts_geometry or disc_geometry(self.geometry)

    @property
    def cylinder(self) -> Geometry:
        """The direct-tension cylinder (``dtt_geometry``, or the UCS cylinder)."""
        return self.dtt_geometry or self.geometry

    def specimens(self) -> dict:
        """Per-sample test -> (its specimen, its settings): what a seed's ``bts``, ``dtt``
        and ``tri`` runs take."""
        return {"bts": (self.disc, self.bts_settings), "dtt": (self.cylinder, self.dtt_settings),
                "tri": (self.geometry, self.tri_settings)}


def test_strength(resp: str, outcome) -> float:
    """The strength ``resp`` (``P.SAMPLE_TESTS``' responses: ``bts_MPa``, ``dtt_MPa``,
    ``tri_MPa``) of a finished run's outcome, NaN for a failed one: the summary key the
    dataset reads it from (``study.gather.TEST_COLUMNS``)."""
    from ..study.gather import TEST_COLUMNS

    keys = TEST_COLUMNS[SAMPLE_TESTS[resp]][0]
    key = next(k for k, col in keys.items() if col == resp)
    return float(outcome.summary[key]) if outcome.status == "ok" else math.nan


def valid_tensile_run(test: str, path_of, params: dict, seed: int, geometry, settings, *,
                      max_replacements: int = seeds.MAX_REPLACEMENTS, **kw):
    """A per-sample test (``test``: "bts", the Brazilian disc ``geometry``; "dtt", the
    direct-tension cylinder; "tri", the triaxial test at the design confinement, whose
    runs have no validity check) of ``params`` on packing ``seed`` that measures its
    strength: an invalid run (``<test>_valid`` false) is replaced by the specimen of the
    next replacement seed (``seeds.replacement_seed(seed, k)``), up to
    ``max_replacements`` times; a failed run (instability, genesis) is not replaced (it is
    a failure, not a measurement of the wrong thing). ``path_of(seed, k)`` names the run
    file of attempt k. Returns (the outcome used, the packing seed it ran on, the reasons
    of the invalid attempts); the outcome has ``<test>_MPa`` NaN when every attempt was
    invalid."""
    run_file = RUNNERS[test]
    invalid = []

    def attempt(k: int):
        s = seeds.replacement_seed(seed, k)
        return s, run_file(path_of(s, k), params, s, geometry, settings, **kw)

    def usable(sb) -> bool:
        return sb[1].status != "ok" or sb[1].summary.get(f"{test}_valid", True)

    def discard(k: int, sb) -> None:
        invalid.append(f"seed {sb[0]}: {sb[1].summary.get(f'{test}_invalid_reason', 'invalid')}")

    (s, b), _ = seeds.retry(attempt, max_replacements + 1, usable, discard)
    if not usable((s, b)):  # every attempt invalid: the last one is counted too
        discard(max_replacements, (s, b))
    return b, s, invalid


def valid_bts_run(path_of, params: dict, seed: int, disc, settings, **kw):
    """:func:`valid_tensile_run` of the Brazilian test."""
    return valid_tensile_run("bts", path_of, params, seed, disc, settings, **kw)


@dataclass
class SpecimenRun:
    """One tensile specimen of a packing seed, measured (:func:`specimen_run`): its run's
    status, error and file (the attempt used), the packing seed that attempt ran on, the
    invalid attempts' reasons and the strength (NaN: failed, or no valid attempt)."""

    status: str
    error: str
    path: str | None
    seed: int
    invalid: list
    value: float


def specimen_run(resp: str, path_of, params: dict, seed: int, j: int, geometry, settings,
                 **kw) -> SpecimenRun:
    """Specimen ``j`` of packing ``seed``'s test of strength ``resp`` (packed with
    ``replicate_seed(seed, j)``; an invalid run replaced: :func:`valid_tensile_run`);
    ``path_of(j, s, k)`` names the run file of its attempt k on packing s."""
    b, s, bad = valid_tensile_run(SAMPLE_TESTS[resp], lambda s, k: path_of(j, s, k), params,
                                  seeds.replicate_seed(seed, j), geometry, settings, **kw)
    return SpecimenRun(b.status, b.error, None if b.path is None else str(b.path), int(s),
                       list(bad), test_strength(resp, b))


def combine_specimens(runs, n: int):
    """A seed's strength from its specimens' :class:`SpecimenRun` in order (those after a
    failed one are not counted: a seed with a failed specimen has no strength): (the first
    specimen's run, or the failed one's, the packing seed the first ran on, every invalid
    attempt's reason, the mean of the ``n`` specimens or NaN, the specimens' strengths)."""
    first, used, invalid, values = None, None, [], []
    for r in runs:
        invalid += r.invalid
        values.append(r.value)
        if first is None:
            first, used = r, r.seed
        if r.status != "ok":
            first = r  # a failed specimen: the seed has no σt; the others do not count
            break
    v = np.array(values, float)
    mean = float(v.mean()) if len(v) == n and np.isfinite(v).all() else math.nan
    return first, used, invalid, mean, values


def seed_strength(resp: str, path_of, params: dict, seed: int, geometry, settings, *,
                  specimens: int = 1, start: int = 0, **kw):
    """The strength ``resp`` (``P.SAMPLE_TESTS``) of packing ``seed``: with ``specimens``
    = 1 its test's (:func:`valid_tensile_run`); a tensile strength (σt: Brazilian or
    direct tension, ``TENSILE_TEST_NAMES``) with ``specimens`` = n > 1 the mean of n
    specimens, packed with ``replicate_seed(seed, j)``, j = 0 .. n-1, each valid or
    replaced as one test is, as a laboratory states σt as the mean of several specimens:
    the seed's σt then scatters sqrt(n) times less from packing to packing, at n tests' cost.
    ``path_of(j, s, k)`` names the run file of specimen j's attempt k on packing s. The
    mean is NaN when a specimen failed or had no valid test (a seed is measured on all n,
    or it has no σt). ``start`` = m > 0 runs specimens m .. n-1 only (a seed's count
    raised after its first m were measured: :class:`~.loop_runs.LoopRuns`); the mean is then theirs.
    Returns (the first specimen's :class:`SpecimenRun`, or the failed one's, the packing
    seed the first ran on, the invalid attempts' reasons of every specimen, the seed's
    strength, the specimens' strengths). The specimens run one after the other here;
    :meth:`~.loop_runs.LoopRuns._parts` and :mod:`.fresh_seeds` run them side by side and combine them
    alike
    (:func:`combine_specimens`)."""
    test = SAMPLE_TESTS[resp]
    if specimens > 1 and test not in TENSILE_TEST_NAMES:
        raise BadInput(f"tensile specimens {specimens}: only a tensile strength "
                       f"({', '.join(TENSILE_TEST_NAMES)}) is measured on several specimens, "
                       f"not {resp}")
    runs = []
    for j in range(start, specimens):
        runs.append(specimen_run(resp, path_of, params, seed, j, geometry, settings, **kw))
        if runs[-1].status != "ok":
            break  # a failed specimen: the seed has no σt; the others need not run
    return combine_specimens(runs, specimens - start)


def specimens_of(resp: str, tensile_specimens: int) -> int:
    """How many specimens measure ``resp`` on a seed (a tensile test's count; one else)."""
    return tensile_specimens if SAMPLE_TESTS[resp] in TENSILE_TEST_NAMES else 1


def specimen_text(values) -> str:
    """A seed row's ``<test>_specimen_MPa``: each specimen's strength, ``;``-separated
    (:func:`specimen_values` reads it back)."""
    return ";".join(f"{v:.6g}" for v in values)


def specimen_values(row: dict, resp: str, test: str) -> list[float]:
    """The strengths of a seed row's tensile specimens (``<test>_specimen_MPa``, or the
    seed's one value ``row[resp]``)."""
    text = row.get(f"{test}_specimen_MPa")
    if isinstance(text, str) and text:
        return [float(v) for v in text.split(";")]
    return [float(row.get(resp, math.nan))]


def row_strength(row: dict, resp: str, path_of, params: dict, seed: int, geometry, settings,
                 *, tensile_specimens: int = 1, **kw):
    """:func:`seed_strength` of ``resp`` into a seed's ``row`` (the closed loop's and the
    fresh-seed check's): the strength, the packing seed used (``<test>_seed``), the count
    of invalid attempts (``<test>_invalid``) and, when σt is measured on
    ``tensile_specimens`` > 1 specimens (a tensile test's count; any other test has one),
    how many ran and each one's strength (``<test>_specimens``, ``<test>_specimen_MPa``:
    ``;``-separated, MPa; NaN: failed or no valid test). Returns (the outcome
    :func:`seed_strength` returns, the invalid attempts' reasons)."""
    test = SAMPLE_TESTS[resp]
    n = tensile_specimens if test in TENSILE_TEST_NAMES else 1
    b, used, invalid, row[resp], values = seed_strength(resp, path_of, params, seed, geometry,
                                                        settings, specimens=n, **kw)
    row[f"{test}_seed"], row[f"{test}_invalid"] = used, len(invalid)
    if n > 1:
        row[f"{test}_specimens"] = len(values)
        row[f"{test}_specimen_MPa"] = specimen_text(values)
    return b, invalid
