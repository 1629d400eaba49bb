"""The fresh-seed check of the verified cards (rules ``fresh_seeds`` and ``fresh_seeds_table``).

The closed loop steers the mean of its rounds' packing seeds onto the lab targets. Whether
the card then describes the rock rather than those packings shows on packings the loop
never saw: :func:`fresh_seeds` runs a verified card's parameters on fresh packing seeds (the
UCS test of every seed and, for a card with a tensile-strength target, its Brazilian test
on the same seed), and :func:`fresh_seeds_table` judges every card and target.

The check (``passed``) asks whether the fresh seeds read as the card's closed loop read on
its own seeds (:func:`loop_reference_stats`): the two-sample t of the two means, against the
Student-t quantile at the level of ``z`` normal standard errors shared among the card's
targets (Šidák), so that a card which describes the rock as well as its loop's seeds can
tell fails with that probability (4.55 % for z = 2), whatever its number of targets and
seeds. The loop itself judged the card against the lab, within max(rtol, z standard
errors): the two together say that the card meets the lab on packings it never saw. The
lab-referenced statistics stay in the table as measurements: is the lab value within ``z``
standard errors of the fresh seeds' mean (``within_z_se``), and within the loop's own
tolerance max(rtol, z standard errors) (``met``)? They count neither the loop's own
sampling error, which the card carries (:func:`false_alarm`), nor the residual the loop
accepted, so a card exactly as good as its loop can make it fails them more often than z
says. A card whose fresh seeds did not run the loop's parameters on the loop's specimens
(a transferred card, another scale) has no loop reference and is judged on ``within_z_se``.
A failed run is a row with its reason, counted in ``n_failed``, never dropped.
"""
from __future__ import annotations

import math
from pathlib import Path
from statistics import NormalDist

import numpy as np
import pandas as pd

from .. import params as P
from ..analysis.calibration.loop_settings import LoopSettings
from ..io.card import card_parameters, read_card
from ..io.checks import BadInput
from ..io.tables import write_table
from ..lab.run_context import RunContext
from ..lab.runner import bts_inputs, dtt_inputs, triaxial_inputs, ucs_inputs
from ..lab.triaxial import TriaxialSettings
from ..params import BTS
from .inputs import CSV, H5, output_dirs, outputs
from .measure import (
    RUNNERS,
    combine_specimens,
    specimen_run,
    specimen_text,
    specimens_of,
)
from .pool import SeedPool
from .runs import write_failure
from .verification import check_tri_target

#: per-seed columns of the seed table besides the targets
_EXTRA = ("u_pre_MJm3", "peak_strain")
#: the closed loop's relative tolerance (the ``met`` verdict uses the loop's own rule)
_RTOL = LoopSettings().rtol


def used_seeds(card: dict) -> set[int]:
    """The packing seeds a verified card was fitted or checked on: every round's seeds of
    its closed loop and the full-size transfer's seed, if it ran."""
    v = card.get("verification") or {}
    seeds = {int(s) for s in v.get("seeds") or []}
    t = card.get("transfer") or {}
    if t.get("seed") is not None and t.get("status") not in (None, "not-run"):
        seeds.add(int(t["seed"]))
    return seeds


def fresh_seeds(card, *, seeds, runs, seed_runs, tests, ctx: RunContext = RunContext(),
                bts_runs=None, dtt_runs=None, tri_runs=None) -> pd.DataFrame:
    """Run a verified card on fresh packing ``seeds`` (none of them one its closed loop or
    transfer used: BadInput naming them otherwise) with the tests of ``tests``
    (:class:`~.measure.SeedTests`): the UCS test of every seed into ``runs[i]`` and, with
    ``bts_runs``, the Brazilian test of the same seed (its disc, default the ISRM disc at
    the cylinder's scale, and loading) into ``bts_runs[i]``: σt judged against the lab's
    when it is a target (``bts_runs`` is then required), else the card's prediction and
    its seed scatter. With ``dtt_runs`` the direct-tension test of every seed runs into
    ``dtt_runs[i]`` (its cylinder, default the UCS cylinder), likewise a target or the
    card's prediction (a card with a direct-tension target, ``dtt_MPa``, needs them; with
    both tensile tests the report gives the card's direct/Brazilian ratio); a card with a
    triaxial-strength target (``tri_MPa``) the triaxial test of ``tests.tri_settings``
    (its design confinement) on the UCS cylinder into ``tri_runs[i]``. ``ctx``: how the
    DEM runs (:class:`~bpmcal.lab.run_context.RunContext`).
    An invalid tensile test is run again on replacement
    seeds (:func:`~.measure.valid_tensile_run`); when none is valid the seed has no σt
    (NaN, the reasons in ``error``) and keeps its UCS responses. σt is measured as the card's
    closed loop measured it: the mean of ``verification.tensile_specimens`` specimens per
    seed (default 1; :func:`~bpmcal.stages.measure.seed_strength`), specimen j > 0
    written beside the seed's run file as ``<run>.r<j>.h5``. ``seed_runs``: one row per seed
    with its status, failure reason and responses. The parameters are the card's
    (:func:`card_parameters`: the closed loop's, or the transfer's when it ran). A card
    whose closed loop did not run (``not-run``: an unreachable calibration) is not run on
    any seed: every run file is a failure record with the reason and every seed a row with
    status ``not-run``. The seeds run side by side on up to ``ctx.threads`` processes
    (:class:`SeedPool`; the rows do not depend on how many)."""
    c = read_card(card, "--card", need=("parameters", "specimen", "targets", "verification"))
    seeds = [int(s) for s in seeds]
    if len(runs) != len(seeds):
        raise BadInput(f"--runs: {len(runs)} run file(s) for {len(seeds)} seed(s); expected "
                       "one per seed, in the order of --seeds")
    if bts_runs is not None and len(bts_runs) != len(seeds):
        raise BadInput(f"--bts-runs: {len(bts_runs)} run file(s) for {len(seeds)} seed(s); "
                       "expected one per seed, in the order of --seeds")
    seen = sorted(used_seeds(c) & set(seeds))
    if seen:
        raise BadInput(f"--seeds: {', '.join(map(str, seen))} already used by the card's "
                       f"closed loop or transfer (seeds {sorted(used_seeds(c))}); expected "
                       "fresh packing seeds")
    v = c["verification"]
    ran = v.get("status") != "not-run" and bool(v.get("parameters"))  # verified parameters
    with_bts = BTS in c["targets"]
    with_dtt = "dtt_MPa" in c["targets"]
    run_dtt = with_dtt or dtt_runs is not None  # a target, or the card's prediction
    if with_bts and bts_runs is None and ran:
        raise BadInput(f"--card {card} has a tensile-strength target (bts_MPa): give "
                       "--bts-runs, one Brazilian run file per seed")
    if with_dtt and dtt_runs is None and ran:
        raise BadInput(f"--card {card} has a direct-tension target (dtt_MPa): give "
                       "--dtt-runs, one direct-tension run file per seed")
    with_tri = P.TRI in c["targets"]
    if with_tri and tri_runs is None and ran:
        raise BadInput(f"--card {card} has a triaxial-strength target (tri_MPa): give "
                       "--tri-runs, one triaxial run file per seed")
    if ran:
        check_tri_target(card, c["targets"], tests.tri_settings)
    for flag, files in (("--dtt-runs", dtt_runs), ("--tri-runs", tri_runs)):
        if files is not None and len(files) != len(seeds):
            raise BadInput(f"{flag}: {len(files)} run file(s) for {len(seeds)} seed(s); "
                           "expected one per seed, in the order of --seeds")
    geometry, settings = tests.geometry, tests.settings
    cylinder, disc = tests.cylinder, tests.disc
    params = card_parameters(c)
    # the loop's mean is this card's on other seeds only if these runs repeat the loop's
    other = _loop_reference(c, geometry, disc if with_bts else None,
                            cylinder if with_dtt else None)
    if ran:
        ctx.check_budget(params, geometry, *([disc] if bts_runs is not None else []),
                         *([cylinder] if run_dtt else []))
    outputs(*((r, "--runs", H5) for r in runs), *((r, "--bts-runs", H5) for r in bts_runs or ()),
            *((r, "--dtt-runs", H5) for r in dtt_runs or ()),
            *((r, "--tri-runs", H5) for r in tri_runs or ()), (seed_runs, "--seed-runs", CSV))
    # the per-sample tests besides the UCS test: (strength, run files, measured for this
    # card - σt and σt,d whenever their run files are given, as a target or the card's
    # prediction -, run test, specimen, settings, inputs of its record, what it is, the
    # target it needs)
    extra = [(BTS, bts_runs, True, "bts", disc, tests.bts_settings, bts_inputs,
              "Brazilian test", ""),
             ("dtt_MPa", dtt_runs, run_dtt, "dtt", cylinder, tests.dtt_settings, dtt_inputs,
              "direct-tension test", "direct-tension target"),
             (P.TRI, tri_runs, with_tri, "triaxial", geometry, tests.tri_settings, _tri_inputs,
              "triaxial test", "triaxial-strength target")]
    if not ran:
        # no verified parameters: every run is a failure record saying why, every seed a row
        reason = f"not run: the card's closed loop did not run ({v.get('message', '')})"
        for i, s in enumerate(seeds):
            write_failure(runs[i], test="ucs", inputs=ucs_inputs(params, s, geometry, settings),
                          error=reason)
            for _, files, _, test, geo, st, inputs_of, _, _ in extra:
                if files is not None:
                    write_failure(files[i], test=test, inputs=inputs_of(params, s, geo, st),
                                  error=reason)
        df = pd.DataFrame([{"specimen": c["specimen"], "seed": s, "status": "not-run",
                            "error": reason, **{k: math.nan for k in (*c["targets"], *_EXTRA)},
                            "loop_reference": False,
                            "loop_reference_note": "the card's closed loop did not run"}
                           for s in seeds])
        write_table(df, seed_runs, index=False)
        return df
    output_dirs((ctx.cache, "--specimen-cache"))
    ts = int(v.get("tensile_specimens", 1))
    jobs = [dict(specimen=c["specimen"], params=params, seed=s, run=runs[i], geometry=geometry,
                 settings=settings, extra=[(e[0], None if e[1] is None else e[1][i], *e[2:])
                                           for e in extra], tensile_specimens=ts)
            for i, s in enumerate(seeds)]
    parts = [(i, p) for i, job in enumerate(jobs) for p in _fresh_parts(job)]
    order = sorted(range(len(parts)), key=lambda k: (parts[k][1]["part"] != "ucs",
                                                     parts[k][1].get("j", 0)))
    with SeedPool.of(ctx) as pool:  # every test of every seed side by side
        done = pool.map(_fresh_part, [parts[k][1] for k in order],
                        tags=[_part_tag(parts[k][1]) for k in order])
    by_seed = [{} for _ in jobs]
    for k, rec in zip(order, done):
        i, p = parts[k]
        by_seed[i][(p["part"], p.get("j", 0))] = rec
    rows = [_fresh_row(job, recs) for job, recs in zip(jobs, by_seed)]
    df = pd.DataFrame(rows)
    df["loop_reference"] = not other
    df["loop_reference_note"] = other
    write_table(df, seed_runs, index=False)
    return df


def _same_values(a: dict | None, b: dict) -> bool:
    """Whether the geometry record ``a`` (a card's, read back from YAML) describes the same
    specimen as ``b`` (``Geometry.to_dict``): every key equal, numbers to 1e-9 relative,
    NaN equal to NaN (a card writes it as null)."""
    if not isinstance(a, dict) or set(a) != set(b):
        return False
    for k, x in b.items():
        y = math.nan if a[k] is None else a[k]
        if isinstance(x, (int, float)) and isinstance(y, (int, float)):
            if not (math.isnan(x) and math.isnan(y)) and not math.isclose(x, y, rel_tol=1e-9):
                return False
        elif x != y:
            return False
    return True


def _loop_reference(c: dict, geometry, disc=None, cylinder=None) -> str:
    """Why fresh seeds run on ``geometry`` (and the Brazilian ``disc``, the direct-tension
    ``cylinder``: None without that target) do not repeat the runs of the card's closed
    loop with other packings, "" when they do: the loop's own parameters (no full-size
    transfer's), on the loop's specimens. Only then is the loop's mean a reference for the
    fresh seeds' (:func:`loop_reference_stats`)."""
    v = c.get("verification") or {}
    if (c.get("transfer") or {}).get("parameters"):
        return "the card's parameters are its full-size transfer's, not its loop's"
    if not v.get("closed_loop"):
        return "the card has no closed-loop mean"
    if not _same_values(v.get("geometry"), geometry.to_dict()):
        return "the fresh seeds run another UCS specimen than the loop's"
    for key, g, what in (("bts_geometry", disc, "Brazilian disc"),
                         ("dtt_geometry", cylinder, "direct-tension cylinder")):
        if g is not None and not _same_values(v.get(key), g.to_dict()):
            return f"the fresh seeds run another {what} than the loop's"
    return ""


#: why a seed table without a ``loop_reference`` column is judged against the lab
OLD_SEED_TABLE = ("a seed table of an older bpmcal, which does not say whether its runs "
                  "repeat the loop's")


def _fresh_parts(job: dict) -> list[dict]:
    """The pool jobs of one fresh seed (``job``: the seed's arguments): its UCS test, and
    every specimen j of each per-sample test measured for this card (each run a job of
    its own, as a closed loop's: :func:`~.loop_runs.seed_parts`)."""
    base = {k: job[k] for k in ("params", "seed")}
    parts = [dict(base, part="ucs", out=job["run"], geometry=job["geometry"],
                  settings=job["settings"])]
    for resp, path, measured, test, geo, st, *_ in job["extra"]:
        if path is not None and measured:
            parts += [dict(base, part=resp, j=j, out=path, geometry=geo, settings=st)
                      for j in range(specimens_of(resp, job["tensile_specimens"]))]
    return parts


def _part_tag(p: dict) -> str:
    return f"seed {p['seed']} " + ("UCS" if p["part"] == "ucs"
                                   else f"{P.SAMPLE_TESTS[p['part']]} {p['j'] + 1}")


def _fresh_part(*, part: str, params: dict, seed: int, out, geometry, settings, ctx,
                j: int = 0):
    """One run of a fresh seed (a :class:`SeedPool` job of :func:`_fresh_parts`, with its
    :class:`~bpmcal.lab.run_context.RunContext` ``ctx``): its UCS
    test into ``out`` (the outcome's status, error and the responses a seed row keeps), or
    specimen ``j`` of the test of strength ``part`` into ``out`` (j = 0) or
    ``<out stem>.r<j>.h5`` (a :class:`~.measure.SpecimenRun`)."""
    kw = dict(ctx.lab_kw(), keep_particles=False)
    if part == "ucs":
        u = RUNNERS["ucs"](out, params, seed, geometry, settings, **kw)
        return {"status": u.status, "error": u.error,
                "values": {k: float(u.summary.get(k, math.nan)) if u.status == "ok"
                           else math.nan for k in (*P.TARGETS, *_EXTRA)}}
    return specimen_run(part, lambda j, _s, _k: out if j == 0
                        else Path(out).with_suffix(f".r{j}.h5"),
                        params, seed, j, geometry, settings, **kw)


def _fresh_row(job: dict, recs: dict) -> dict:
    """A fresh seed's row from its runs (``recs``: (part, j) -> :func:`_fresh_part`'s
    record), as the seed's tests run one after the other give it: its UCS responses and,
    for every per-sample test of ``job["extra"]``, the test when it is measured for this
    card (:func:`_fresh_test`), else a failure record saying why not."""
    u = recs[("ucs", 0)]
    row = {"specimen": job["specimen"], "seed": job["seed"], "status": u["status"],
           "error": u["error"], **u["values"]}
    for resp, path, measured, test, geo, st, inputs_of, what, target in job["extra"]:
        if path is None:
            continue
        if measured:
            n = specimens_of(resp, job["tensile_specimens"])
            _fresh_test(row, resp, what, [recs[(resp, j)] for j in range(n)], n)
        else:
            write_failure(path, test=test, inputs=inputs_of(job["params"], job["seed"], geo, st),
                          error=f"not run: the card has no {target} ({resp})")
    return row


def _tri_inputs(params: dict, seed: int, geometry, settings) -> dict:
    """The inputs record of a triaxial run file that is not run (``settings`` None: the
    default settings)."""
    return triaxial_inputs(params, seed, geometry, settings or TriaxialSettings())


def _fresh_test(row: dict, resp: str, what: str, runs: list, n: int) -> None:
    """One fresh seed's per-sample test of strength ``resp`` (``P.SAMPLE_TESTS``) into
    ``row`` from its ``n`` specimens' runs (:class:`~.measure.SpecimenRun`, in
    order): the strength (the specimens' mean, :func:`combine_specimens`; NaN for a
    failed run, or when no replacement seed gave a valid test: the seed keeps its UCS
    responses), the packing seed used, the invalid attempts, and the status and error of
    a failure (the columns of :func:`~.measure.row_strength`)."""
    test = P.SAMPLE_TESTS[resp]
    b, used, invalid, row[resp], values = combine_specimens(runs, n)
    row[f"{test}_seed"], row[f"{test}_invalid"] = used, len(invalid)
    if n > 1:
        row[f"{test}_specimens"] = len(values)
        row[f"{test}_specimen_MPa"] = specimen_text(values)
    if b.status != "ok":
        row["status"] = "failed"
        row["error"] = "; ".join(x for x in (row["error"], f"{what}: {b.error}") if x)
    elif not math.isfinite(row[resp]):
        row["error"] = "; ".join(x for x in (row["error"], f"{what} invalid on every "
                                             "replacement seed: " + "; ".join(invalid)) if x)


def fresh_seed_stats(values, lab: float, *, rtol: float, z: float = 2.0,
                     lab_se: float = 0.0) -> dict:
    """Mean, sample standard deviation, standard error of the mean of ``values`` (the
    fresh seeds' responses; NaN entries are failed runs and do not count), the error of
    the mean in % of ``lab``, its z-score (error / standard error) and the verdicts
    ``within_z_se`` (|mean - lab| <= z standard errors) and ``met`` (|error| <= max(rtol,
    z standard errors), the closed loop's own acceptance). ``lab_se``: the lab value's own
    standard error (its lab row's ``<target>_se``; default 0, an exact target): the
    z-score and both verdicts then use sqrt(se² + lab_se²), the error of a difference of
    two means. Fewer than two values: no standard error, so neither verdict holds."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    n = len(v)
    mean = float(v.mean()) if n else math.nan
    sd = float(v.std(ddof=1)) if n > 1 else math.nan
    se = sd / math.sqrt(n) if n > 1 else math.nan
    err = 100 * (mean / lab - 1) if n and lab else math.nan
    both = math.hypot(se, lab_se) if n > 1 else math.nan  # the difference's standard error
    zs = (mean - lab) / both if n > 1 and both > 0 else (0.0 if n > 1 and mean == lab else math.nan)
    se_pct = 100 * se / abs(lab) if n > 1 and lab else math.nan
    within = bool(n > 1 and abs(mean - lab) <= z * both)
    tol = max(100 * rtol, z * 100 * both / abs(lab)) if n > 1 and lab else math.nan
    return {"n": n, "mean": mean, "sd": sd, "se": se, "err_pct": err, "se_pct": se_pct,
            "z_score": zs, "z": float(z), "within_z_se": within, "tol_pct": tol,
            "met": bool(n > 1 and abs(err) <= tol)}


def check_level(z: float = 2.0) -> float:
    """The two-sided level of ``z`` normal standard errors, 2 (1 - Phi(z)): the chance
    that the fresh-seed check fails a card that generalises (4.55 % for z = 2)."""
    return 2.0 * NormalDist().cdf(-float(z))


def check_limit(dof: float, z: float = 2.0, targets: int = 1) -> float:
    """The fresh-seed check's limit on |t| with ``dof`` degrees of freedom: the Student-t
    quantile of :func:`check_level` shared among ``targets`` targets (Šidák: each at
    1 - (1 - level)^(1/targets))."""
    from scipy import stats

    each = 1.0 - (1.0 - check_level(z)) ** (1.0 / max(int(targets), 1))
    return float(stats.t.isf(each / 2.0, dof))


def loop_reference_stats(values, *, loop_mean: float, loop_sd: float, loop_n: int,
                         lab: float, z: float = 2.0, targets: int = 1) -> dict:
    """Do the fresh seeds' ``values`` (NaN: a failed run, not counted) read as the card's
    closed loop read on its own ``loop_n`` seeds (mean ``loop_mean``, sample SD
    ``loop_sd``)? The same parameters and specimens on two independent sets of packings:
    their means differ by sampling alone, whatever the lab value and whatever residual the
    loop accepted against it, and both sets scatter alike (one population of packings).
    So Student's two-sample t with the pooled SD (``t_loop``, ``dof`` = n + loop_n - 2,
    exact for normal scatter) is judged against the Student-t quantile ``t_crit`` of the
    two-sided level of ``z`` normal standard errors (alpha = 2 (1 - Phi(z)): 4.55 % for
    z = 2) shared among the card's ``targets`` (Šidák: 1 - (1 - alpha)^(1/targets) each),
    so that a card that generalises fails one target or more with probability alpha.
    ``reproduces_loop``: |t_loop| <= t_crit. ``loop_se``: the loop mean's own standard
    error; ``diff_pct``: the difference of the means in % of ``lab`` (of the loop's mean
    without one); ``mdd_pct``: the difference, in the same %, that the check finds half
    the time (t_crit standard errors of the difference): what these seeds can tell from
    noise. Fewer than two fresh or loop seeds: no verdict (NaN statistics,
    ``reproduces_loop`` False)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return two_sample_check(float(v.mean()) if len(v) else math.nan,
                            float(v.std(ddof=1)) if len(v) > 1 else math.nan, len(v),
                            loop_mean=loop_mean, loop_sd=loop_sd, loop_n=loop_n, lab=lab, z=z,
                            targets=targets)


def two_sample_check(mean: float, sd: float, n: int, *, loop_mean: float, loop_sd: float,
                     loop_n: int, lab: float, z: float = 2.0, targets: int = 1) -> dict:
    """:func:`loop_reference_stats` from the fresh seeds' ``mean``, sample SD ``sd`` and
    count ``n`` (a record that kept only those)."""
    k = int(loop_n) if loop_n is not None and math.isfinite(loop_n) else 0
    out = {"loop_mean": float(loop_mean), "loop_n": k, "loop_se": math.nan, "diff_pct": math.nan,
           "t_loop": math.nan, "dof": math.nan, "t_crit": math.nan, "mdd_pct": math.nan,
           "reproduces_loop": False}
    if n < 2 or k < 2 or not all(math.isfinite(x) for x in (mean, sd, loop_mean, loop_sd)):
        return out
    dof = n + k - 2
    pooled = math.sqrt(((n - 1) * float(sd) ** 2 + (k - 1) * float(loop_sd) ** 2) / dof)
    se = pooled * math.sqrt(1.0 / n + 1.0 / k)
    crit = check_limit(dof, z, targets)
    d = float(mean) - float(loop_mean)
    t = d / se if se > 0 else (0.0 if d == 0 else math.copysign(math.inf, d))
    ref = abs(lab) if lab and math.isfinite(lab) else abs(float(loop_mean))
    out.update(loop_se=float(loop_sd) / math.sqrt(k), diff_pct=100 * d / ref if ref else math.nan,
               t_loop=t, dof=float(dof), t_crit=crit,
               mdd_pct=100 * crit * se / ref if ref else math.nan,
               reproduces_loop=bool(abs(t) <= crit))
    return out


def false_alarm(n: int, z: float = 2.0, targets: int = 1, loop_seeds: int | None = None) -> float:
    """The probability that a card exactly on its targets still fails the ``within_z_se``
    check of :func:`fresh_seed_stats` on ``n`` fresh seeds for at least one of ``targets``
    independent targets: the standard error comes from the same ``n`` seeds, so the
    z-score is Student-t with n - 1 degrees of freedom (5 seeds, z = 2: 11.6 % per
    target, 67 % for one miss or more among 9).

    With ``loop_seeds`` = k, the card is instead exactly on its targets over the mean of
    its closed loop's k packings, which is itself off the rock's mean by that mean's error
    (SD sigma / sqrt(k)); the fresh mean's error then has variance sigma² (1/n + 1/k), of
    which the check's standard error counts only the first part: z = sqrt(1 + n/k) T with
    T Student-t (n - 1), exactly. (5 fresh and 10 loop seeds, z = 2: 17.8 % per target,
    62 % for one miss or more among 5.)"""
    from scipy import stats

    if n < 2:
        return math.nan
    inflate = 1.0 if loop_seeds is None else math.sqrt(1.0 + n / float(loop_seeds))
    p_one = float(2 * stats.t.sf(z / inflate, n - 1))
    return 1 - (1 - p_one) ** int(targets)


def _lab_because(df: pd.DataFrame, loop: dict) -> str:
    """Why a card's fresh seeds (its seed table ``df``) are judged against the lab rather
    than its closed loop's mean (``loop``: the card's ``verification.closed_loop``)."""
    if not len(df):
        return "no fresh seed ran"
    if "loop_reference" not in df.columns:
        return OLD_SEED_TABLE
    notes = (df["loop_reference_note"].astype(object).fillna("").astype(str)
             if "loop_reference_note" in df.columns else pd.Series([""]))
    said = next((n for n in notes if n), "")
    return said or ("the card has no closed-loop mean" if not loop
                    else "the seed table says its runs do not repeat the loop's")


def fresh_seeds_table(cards, seed_runs, *, table, rtol=_RTOL, z=2.0) -> pd.DataFrame:
    """One row per card (``cards[i]`` with its seed table ``seed_runs[i]`` from
    :func:`fresh_seeds`) and target: the lab value, the fresh seeds' n, mean, standard
    deviation, standard error and CV, the error of the mean (%), its z-score and the
    verdicts of :func:`fresh_seed_stats`; the card's closed-loop mean, its standard error
    and seeds, and the comparison of :func:`loop_reference_stats` with the card's targets
    sharing the level (when the seed table says its runs repeat the loop's:
    ``loop_reference``); ``passed`` the check's verdict (``reproduces_loop``, or
    ``within_z_se`` without a loop reference) and ``judged_by`` which ("closed loop" or
    "lab"; ``lab_because`` says why a target's row is judged against the lab),
    ``loop_status`` the closed loop's status (a check passed against a loop that
    did not converge does not verify the card); ``seeds`` lists the seeds, ``n_failed``
    the failed runs and ``note`` why none ran (a card whose closed loop did not run). A
    tensile strength measured on the fresh seeds but not a target of the card is a row
    too, its ``role`` "prediction" (no lab value, no verdict: σt of the card and its seed
    scatter); the targets' rows have ``role`` "target"."""
    if len(seed_runs) != len(cards):
        raise BadInput(f"--seed-runs: {len(seed_runs)} table(s) for {len(cards)} card(s); "
                       "expected one per card, in the same order")
    if not (isinstance(rtol, (int, float)) and 0 < rtol < 1):
        raise BadInput(f"--rtol {rtol!r}: expected a number in (0, 1)")
    if not (isinstance(z, (int, float)) and z > 0):
        raise BadInput(f"--z {z!r}: expected a number > 0")
    loaded = [read_card(c, "--cards", need=("specimen", "targets")) for c in cards]
    frames = []
    for f in seed_runs:
        try:
            frames.append(pd.read_csv(f))
        except (OSError, ValueError) as e:
            raise BadInput(f"--seed-runs {f}: cannot read it as CSV ({e})") from None
    outputs((table, "--table", CSV))
    rows = []
    for c, df, f in zip(loaded, frames, seed_runs):
        missing = [k for k in ("seed", "status", *c["targets"]) if k not in df.columns]
        if missing:
            raise BadInput(f"--seed-runs {f}: missing column(s) {missing} for the targets of "
                           f"card {c['specimen']} (expected a seed table of bpmcal fresh-seeds)")
        ok = df["status"] == "ok"
        not_run = (df["status"] == "not-run").all() and len(df)
        note = str(df["error"].iloc[0]) if not_run and "error" in df.columns else ""
        predicted = [k for k in P.SAMPLE_TESTS if k in df.columns
                     and k not in c["targets"]]  # measured on the fresh seeds, no lab value
        loop = (c.get("verification") or {}).get("closed_loop") or {}
        by_loop = bool(len(df) and "loop_reference" in df.columns and loop
                       and df["loop_reference"].astype(bool).all())
        lab_because = "" if by_loop else _lab_because(df, loop)
        for k in (*c["targets"], *predicted):
            target = k in c["targets"]
            lab = float(c["targets"][k]) if target else math.nan
            vals = df.loc[ok, k].to_numpy(float)
            st = fresh_seed_stats(vals, lab, rtol=rtol, z=z,
                                  lab_se=float((c.get("target_se") or {}).get(k, 0.0)))
            ref = loop_reference_stats(
                vals, loop_mean=float(loop.get(k, math.nan)) if by_loop else math.nan,
                loop_sd=float((loop.get("seed_sd") or {}).get(k, math.nan)),
                loop_n=int((loop.get("n_measured") or {}).get(k, loop.get("n_seeds", 0))),
                lab=lab, z=z, targets=len(c["targets"]))
            fin = vals[np.isfinite(vals)]
            rows.append({"specimen": c["specimen"], "response": k,
                         "role": "target" if target else "prediction",
                         "lab": lab, **st,
                         "cv_pct": (100 * st["sd"] / abs(st["mean"])
                                    if len(fin) > 1 and st["mean"] else math.nan),
                         **ref, "judged_by": ("closed loop" if by_loop else "lab") if target else "",
                         "lab_because": lab_because if target else "",
                         "loop_status": str((c.get("verification") or {}).get("status", "")),
                         "passed": target and (ref["reproduces_loop"] if by_loop
                                               else st["within_z_se"]),
                         "n_failed": int((~ok).sum()),
                         "seeds": ",".join(str(int(s)) for s in df["seed"]), "note": note})
    out = pd.DataFrame(rows)
    write_table(out, table, index=False)
    return out
