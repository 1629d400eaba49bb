"""The seed-scatter job (rule ``seed_scatter`` in ``workflow/rules/analysis.smk``, ``bpmcal
scatter``): one card, several packing seeds -> their run files and the scatter table
(:func:`bpmcal.analysis.scatter_table`): the packing noise of every response, and whether
the closed loop's tolerance is below it (:func:`seed_scatter`).
"""
from __future__ import annotations

import math

import pandas as pd

from .. import params as P
from ..analysis import scatter_table
from ..analysis.calibration.loop_settings import LoopSettings
from ..io.card import card_parameters, read_card
from ..io.checks import BadInput
from ..io.tables import write_table
from ..lab.run_context import RunContext
from .inputs import CSV, H5, output_dirs, outputs
from .measure import RUNNERS
from .pool import SeedPool

#: the closed loop's relative tolerance (the scatter table judges it against the noise)
_RTOL = LoopSettings().rtol


def seed_scatter(card, *, runs, seeds, seed_runs, table, geometry, settings, rtol=_RTOL,
                 ctx: RunContext = RunContext()) -> pd.DataFrame:
    """One parameter set (a card's: :func:`card_parameters`, i.e. the closed loop's of a
    verified card, the transfer's of a transferred one), several packing seeds
    (``runs[i]`` is the run file of ``seeds[i]``): the scatter of the DEM responses
    (``seed_runs``: one row per seed; ``table``: coefficient of variation and noise floor
    per response), and whether the closed-loop tolerance is below it. The seeds run side
    by side on up to ``ctx.threads`` processes (:class:`SeedPool` of the
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``)."""
    c = read_card(card, "--card", need=("parameters", "specimen"))
    params = card_parameters(c)
    if len(runs) != len(seeds):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(seeds)} seed(s); expected "
                       "one per seed, in the order of --seeds")
    ctx.check_budget(params, geometry)
    outputs(*((r, "--runs", H5) for r in runs), (seed_runs, "--seed-runs", CSV),
            (table, "--table", CSV))
    output_dirs((ctx.cache, "--specimen-cache"))
    with SeedPool.of(ctx) as pool:  # the seeds side by side on `ctx.threads` CPUs
        rows = pool.map(_scatter_seed, [dict(params=params, seed=int(s), run=f,
                                             geometry=geometry, settings=settings)
                                        for s, f in zip(seeds, runs)],
                        tags=[f"seed {s}" for s in seeds])
    done = pd.DataFrame(rows)
    write_table(done, seed_runs, index=False)
    sc = scatter_table(done[done["status"] == "ok"], rtol=rtol)
    sc.insert(0, "specimen", c["specimen"])
    write_table(sc, table)
    return sc


def _scatter_seed(*, params: dict, seed: int, run, geometry, settings, ctx) -> dict:
    """One seed of :func:`seed_scatter` (a :class:`SeedPool` job, with its
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``): its UCS test into ``run``;
    returns the seed's row."""
    out = RUNNERS["ucs"](run, params, seed, geometry, settings, keep_particles=False,
                         **ctx.lab_kw())
    r = dict(out.summary, status=out.status)
    return {"seed": seed, "status": r["status"],
            **{k: r.get(k, math.nan) for k in (*P.TARGETS, "u_pre_MJm3")}}
