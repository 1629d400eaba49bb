"""Shared helpers of the lab tests: a UCS test on a small A1 specimen."""
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.ucs import run_ucs
from support.paper import A1, FAST, SMALL  # noqa: F401  (re-exported for the lab tests)


def ucs(params, cache, seed=3, geometry=SMALL, settings=FAST):
    sp = make_specimen(params, seed, geometry, cache=cache)
    return run_ucs(sp, settings), sp
