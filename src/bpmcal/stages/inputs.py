"""Reading the files a stage is given, checked before any work: each problem is one
``BadInput`` (or ``ParameterError``, ``ConfigError``, ``CardError``, ``RunFileError``)
naming the file and what was expected, which the CLI reports as one line with exit code 2.
Also the output checks every stage makes before it computes anything."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..analysis import models_from_dict
from ..io.checks import BadInput, in_file, out_dir, out_file, read_json, read_model_table
from ..io.safe_names import name_problem
from ..study.lab_data import load_lab

#: the suffixes of the files the stages write
CSV, JSON, YAML, MD, TXT, PNG, H5 = ((".csv",), (".json",), (".yaml", ".yml"), (".md",),
                                     (".txt",), (".png",), (".h5", ".hdf5"))


def outputs(*files) -> None:
    """Check every output file (``(path, flag, suffixes)``; ``path`` None is skipped)
    before any work: a sane suffix, not a directory, its folder created and writable."""
    for path, flag, suffixes in files:
        if path is not None:
            out_file(path, flag, suffixes=suffixes)


def output_dirs(*dirs) -> None:
    """Check output folders (``(path, flag)``) before any work."""
    for path, flag in dirs:
        if path is not None:
            out_dir(path, flag)


def read_dataset(path, flag: str = "--dataset", min_ok: int = 1) -> pd.DataFrame:
    """A gathered dataset CSV with the columns the analyses need and enough ok samples."""
    df, _ = read_model_table(path, flag, lambda m: ["sample_id", *m.params, "status"])
    n_ok = int((df["status"] == "ok").sum())
    if n_ok < min_ok:
        raise BadInput(f"{flag} {path}: {n_ok} of {len(df)} samples have status ok; this step "
                       f"needs at least {min_ok}")
    return df


def usable(df: pd.DataFrame) -> str:
    """How many samples an analysis uses, and which it leaves out (a note for its outputs)."""
    ok = df[df["status"] == "ok"]
    return (f"{len(ok)} of {len(df)} samples used"
            + (f" ({len(df) - len(ok)} failed/missing dropped: "
               f"{', '.join(df.loc[df['status'] != 'ok', 'sample_id'])})"
               if len(ok) < len(df) else ""))


def read_models(path, flag: str = "--models") -> dict:
    """The regression's models.json (``bpmcal.analysis.stepwise.FORMAT``) with a model of
    sigma_c."""
    d = read_json(path, flag)
    try:
        models = models_from_dict(d)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise BadInput(f"{flag} {path}: not a models.json of 'bpmcal regress' "
                       f"({type(e).__name__}: {e})") from None
    if "ucs_MPa" not in models:
        raise BadInput(f"{flag} {path}: no model of ucs_MPa")
    return models


def read_lab(path, flag: str = "--lab") -> pd.DataFrame:
    """The validated lab table (specimen names are checked: they become file names)."""
    return load_lab(in_file(path, flag))


def runs_by_id(files, flag: str, ids=None) -> dict[str, Path]:
    """Run files given on the command line, by their stem (the sample, ratio or seed id of
    ``bpmcal.io.study_files``): each a file name ending in .h5 with a safe, unique stem; with
    ``ids``, no stem outside them. A listed file that does not exist is left to the
    caller (a missing run is data, not bad input)."""
    out: dict[str, Path] = {}
    for f in files:
        p = Path(f)
        if p.is_dir():
            raise BadInput(f"{flag} {f}: is a directory, expected a run file (<id>.h5)")
        if p.suffix not in H5:
            raise BadInput(f"{flag} {f}: expected a run file ending in .h5")
        m = name_problem(p.stem)
        if m:
            raise BadInput(f"{flag} {f}: file name {m}")
        if p.stem in out:
            raise BadInput(f"{flag} {f}: {p.stem} given twice")
        out[p.stem] = p
    if ids is not None:
        extra = sorted(set(out) - set(ids))
        if extra:
            raise BadInput(f"{flag}: run file(s) {extra} match no id of the table "
                           f"({len(ids)} ids: {ids[0]}...{ids[-1]})")
    return out


def check_ids(ids, flag: str, what: str = "sample_id") -> None:
    """Ids that become file names: safe names (``bpmcal.io.safe_names``)."""
    for sid in ids:
        m = name_problem(sid)
        if m:
            raise BadInput(f"{flag}: {what} {m}")
