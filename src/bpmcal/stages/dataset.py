"""The spine of the study (``workflow/rules/study.smk``): the design, and the dataset
gathered from one UCS run file per sample (the runs themselves: ``stages.runs``)."""
from __future__ import annotations

import pandas as pd

from ..io.checks import BadInput, out_file, read_model_table
from ..io.tables import write_csv
from ..study.design import design_size_problem, lhs_design, validate_ranges
from ..study.gather import gather as gather_rows
from ..study.gather import status_report
from .inputs import check_ids, runs_by_id


def design(ranges: dict, n: int, seed: int, out, *, optimization: str | None = "random-cd"
           ) -> pd.DataFrame:
    """Latin-hypercube design over ``ranges`` (paper units) -> ``out`` (CSV)."""
    if not isinstance(ranges, dict):
        raise BadInput(f"--ranges {ranges!r}: expected a JSON object "
                       '{"name": [low, high], ...}')
    validate_ranges(ranges)
    problem = design_size_problem(n, optimization)
    if problem:
        raise BadInput(f"--n {n}: {problem}")
    out_file(out, suffixes=(".csv",))
    df = lhs_design(ranges, n, seed, optimization=optimization)
    write_csv(df, out)
    return df


def gather(design_csv, runs, out, bts_runs=None, dtt_runs=None,
           tri_runs=None) -> tuple[pd.DataFrame, str]:
    """One row per design sample from its run file (``runs``: the files, named
    ``<sample_id>.h5``) -> ``out`` (the dataset CSV); a sample without a run file is
    "missing", an unreadable one "unreadable". ``bts_runs`` / ``dtt_runs`` / ``tri_runs``: the
    samples' Brazilian / direct-tension / design-confinement triaxial run files (named the
    same), which add sigma_t or the triaxial strength and its own status and error
    (``study.gather``). Returns the table and a status report."""
    d, _ = read_model_table(design_csv, "--design", lambda m: ["sample_id", *m.params, "seed"],
                            dtype={"sample_id": str})
    check_ids(d["sample_id"], f"--design {design_csv}")
    files = runs_by_id(runs, "--runs", ids=list(d["sample_id"]))
    bts = None if bts_runs is None else runs_by_id(bts_runs, "--bts-runs",
                                                   ids=list(d["sample_id"]))
    dtt = None if dtt_runs is None else runs_by_id(dtt_runs, "--dtt-runs",
                                                   ids=list(d["sample_id"]))
    tri = None if tri_runs is None else runs_by_id(tri_runs, "--tri-runs",
                                                   ids=list(d["sample_id"]))
    out_file(out, suffixes=(".csv",))
    df = gather_rows(d, files, bts, dtt, tri)
    write_csv(df, out)
    return df, status_report(df)
