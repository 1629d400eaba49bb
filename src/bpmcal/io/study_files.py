"""The study's file contract: every file the workflow writes under ``outdir``, and the ids
in their names, defined once.

``workflow/rules/common.smk`` declares every rule's inputs and outputs with
:class:`StudyFiles` and passes each file to the ``bpmcal`` command; the stages open only the
files they are given (the report, the files of this layout); a file a stage reads is
always one that a rule declares (``tests/workflow/test_smoke.py``,
``test_every_file_a_stage_reads_is_declared_by_the_rule_graph``, checks that on a real
run). Nothing walks the output tree to find names again.

Conventions that hold for every file here:

- **A table** is a CSV with its Markdown rendering beside it (same stem, ``.md``); a
  **figure** is a PNG with a PDF beside it. :func:`companions` lists both, and the writers
  (``bpmcal.io.tables.write_table``, ``bpmcal.io.figures.save_figure``) write both.
- **Ids** in file names come from the functions here: sample ids ``s000`` ...
  (:func:`sample_ids`), strength-ratio sweep ids ``a050`` for a = 0.50 (:func:`ratio_id`,
  over :func:`ratio_grid`), impact velocity tags ``6`` for 6.0 m/s (:func:`velocity_tag`).
  Lab specimen names come from the lab CSV (checked safe names, ``bpmcal.io.safe_names``).
- Paths are strings joined with ``/`` (Snakemake's wildcards such as ``"{sample}"`` pass
  through the functions unchanged, so the rules use the same functions as the code).

Adding a file: add a method (or a stem constant) here, declare it in the rule that writes
it (``output:``) and in every rule that reads it (``input:``), and pass it on the command
line. ``docs/architecture.md`` walks through adding a stage.
"""
from __future__ import annotations

import math

from .. import params as P

# ------------------------------------------------------------------------ conventions
#: extensions of a table (CSV, Markdown) and of a figure (PNG, PDF); the first is the
#: file a command is given, the others are written beside it with the same stem
TABLE_EXTS = (".csv", ".md")
FIGURE_EXTS = (".png", ".pdf")


def companions(path: str) -> list[str]:
    """The files written for ``path``: a table's CSV and Markdown, a figure's PNG and
    PDF, else ``path`` alone."""
    for exts in (TABLE_EXTS, FIGURE_EXTS):
        if path.endswith(exts[0]):
            stem = path[: -len(exts[0])]
            return [stem + e for e in exts]
    return [path]


# ------------------------------------------------------------------------ ids
def sample_ids(n: int, prefix: str = "s") -> list[str]:
    """The design's sample ids: ``s000`` ... (at least three digits, more for n > 999)."""
    n = int(n)
    width = max(3, len(str(n)))
    return [f"{prefix}{i:0{width}d}" for i in range(n)]


#: at most this many ratios in the strength-ratio sweep (one DEM job each; the config's
#: ``ratio_sweep.ratios`` and ``bpmcal sweep-plan --ratios`` alike)
MAX_SWEEP_RATIOS = 200


def ratio_count(start: float, stop: float, step: float) -> float:
    """How many ratios start, start + step, ... <= stop are (a float: it may be huge, or
    inf for a denormal step)."""
    q = (stop - start) / step + 1e-9
    return math.floor(q) + 1 if math.isfinite(q) else math.inf


def ratio_grid(start: float, stop: float, step: float) -> list[float]:
    """The strength ratios of the sweep: start, start + step, ... <= stop (rounded to 10
    digits); ParameterError for a reversed, empty or non-finite grid, one of more than
    :data:`MAX_SWEEP_RATIOS` ratios, or a step finer than the run names (0.01)."""
    ok = all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
             for x in (start, stop, step))
    if not (ok and start > 0 and stop >= start and step > 0):
        raise P.ParameterError(f"ratio grid [{start}, {stop}] step {step}: expected "
                               "finite numbers with 0 < start <= stop and step > 0")
    n = ratio_count(start, stop, step)
    if not n <= MAX_SWEEP_RATIOS:
        raise P.ParameterError(f"ratio grid [{start:g}, {stop:g}] step {step:g} gives "
                               f"{n:.4g} ratios, more than {MAX_SWEEP_RATIOS} (one DEM run "
                               "each); use a larger step")
    grid = [round(start + k * step, 10) for k in range(int(n))]
    ids = [ratio_id(a) for a in grid]
    if len(set(ids)) != len(ids):
        raise P.ParameterError(f"ratio grid step {step:g} is finer than 0.01: ratios would "
                               "share a run name (a{100 x ratio})")
    return grid


def ratio_id(a: float) -> str:
    """The run name of ratio ``a`` ("a050" for a = 0.50)."""
    return f"a{int(round(a * 100)):03d}"


def sweep_ids(ratios) -> list[str]:
    """The run names of the sweep ``ratios`` = [start, stop, step] (the config's)."""
    return [ratio_id(a) for a in ratio_grid(*ratios)]


def velocity_tag(v: float) -> str:
    """The file-name tag of an impact velocity: 6.0 -> "6", 2.5 -> "2.5" [m/s]."""
    return f"{float(v):g}"


def sigma3_tag(s3: float) -> str:
    """The file-name tag of a confining stress: 0.0 -> "0", 2.5 -> "2.5" [MPa]."""
    return f"{float(s3):g}"


#: the cards the triaxial stage runs: the calibration's and the closed loop's
TRIAXIAL_CARDS = ("calibrated", "verified")


def impact_tags(reference: float, others=()) -> list[str]:
    """Tags of the impact runs: the reference velocity and the sweep's, unique, by speed."""
    return sorted({velocity_tag(v) for v in [reference, *others]}, key=float)


# ------------------------------------------------------------------------ tables, figures
#: table stems (``tables/<stem>.csv`` + ``.md``) and what they hold
TABLE3 = "table3_importance"  # XGBoost importance shares (screen)
TABLE4 = "table4_terms"  # terms retained by the stepwise regression (regress)
REGRESSION_FIT = "regression_fit"  # adjusted and CV R² of every stage (regress)
CALIBRATION = "calibration"  # calibrated parameters of every specimen (calibrate)
TABLE5 = "table5_verification"  # DEM vs lab, single pass and closed loop (verification_tables)
TRANSFER = "transfer_full_size"  # verified vs full-size responses per card (transfer_table)
TABLE6 = "table6_prepeak_energy"  # pre-peak energy density (verification_tables)
FRESH_SEEDS = "fresh_seeds"  # verified cards on fresh packing seeds vs lab (fresh_seeds_table)
RATIO_SWEEP = "ratio_sweep"  # cracks per strength ratio (sweep_analyse)
IMPACT_ENERGY = "impact_energy"  # energy budget of the reference impact (impact_analyse)
T10_ECS = "t10_ecs"  # t10 vs specific energy (impact_analyse)
TRIAXIAL_ENVELOPES = "triaxial_envelopes"  # c, phi, mi, sigma_c, sigma_t per card (envelopes)
TRIAXIAL_POINTS = "triaxial_points"  # every triaxial run, ok or failed (envelopes)
TRIAXIAL_LAB = "triaxial_lab"  # lab triaxial points vs each card's envelopes (envelopes)

#: figure stems (``figures/<stem>.png`` + ``.pdf``)
FIG_SCREENING = "screening_importance"
FIG_REGRESSION = "regression_fit"
FIG4 = "fig4_ratio_cracks"
FIG5 = "fig5_failure_patterns"
FIG6 = "fig6_stress_strain"
FIG7 = "fig7_impact_energy"
FIG_T10 = "t10_ecs"
FIG_ENVELOPES = "triaxial_envelopes"


class StudyFiles:
    """Every file of a study under ``outdir`` (a string path; no trailing slash needed).

    Methods that take an id (``ucs_run("s007")``, ``card("B1")``) accept a Snakemake
    wildcard too (``ucs_run("{sample}")``)."""

    def __init__(self, outdir):
        self.outdir = str(outdir).rstrip("/") or "."

    def __repr__(self):
        return f"StudyFiles({self.outdir!r})"

    def path(self, *parts: str) -> str:
        return "/".join([self.outdir, *parts])

    # ---------------------------------------------------------------- the spine
    @property
    def design(self) -> str:
        """The LHS design: sample_id, the 8 meso-parameters, seed."""
        return self.path("design", "samples.csv")

    def ucs_run(self, sample: str) -> str:
        """The UCS run file of one design sample (or its failure record)."""
        return self.path("ucs", f"{sample}.h5")

    def bts_run(self, sample: str) -> str:
        """The Brazilian run file of one design sample (or its failure record)."""
        return self.path("bts", f"{sample}.h5")

    def dtt_run(self, sample: str) -> str:
        """The direct-tension run file of one design sample (or its failure record)."""
        return self.path("dtt", f"{sample}.h5")

    def tri_run(self, sample: str) -> str:
        """The triaxial run file of one design sample at the design confinement (or its
        failure record)."""
        return self.path("tri", f"{sample}.h5")

    @property
    def dataset(self) -> str:
        """One row per sample: design, responses, status, error (and, when the study runs
        the Brazilian test, bts_MPa, bts_status, bts_error)."""
        return self.path("dataset.csv")

    @property
    def packings(self) -> str:
        """The specimen-packing cache of the DEM jobs (a cache folder, not a contract file)."""
        return self.path("cache", "packings")

    def log(self, *name: str) -> str:
        """``logs/<name>.log`` (``log("sample", "s007")`` -> ``logs/sample/s007.log``)."""
        return self.path("logs", *name[:-1], f"{name[-1]}.log")

    # ---------------------------------------------------------------- tables, figures
    def table(self, stem: str) -> str:
        """A table's CSV (``tables/<stem>.csv``; its ``.md`` beside it)."""
        return self.path("tables", f"{stem}.csv")

    def figure(self, stem: str) -> str:
        """A figure's PNG (``figures/<stem>.png``; its ``.pdf`` beside it)."""
        return self.path("figures", f"{stem}.png")

    # ---------------------------------------------------------------- screening
    @property
    def selected(self) -> str:
        """The screening's selected candidates per response (JSON)."""
        return self.path("screening", "selected.json")

    @property
    def importance_table(self) -> str:
        """Every importance type per parameter and response (table)."""
        return self.path("screening", "importance_all_types.csv")

    @property
    def screening_cv(self) -> str:
        """Cross-validated R² of the XGBoost models (table)."""
        return self.path("screening", "xgb_cv_r2.csv")

    @property
    def screening_shadow(self) -> str:
        """Largest importance of the shadow (permuted) features (table)."""
        return self.path("screening", "shadow_max.csv")

    @property
    def screening_summary(self) -> str:
        return self.path("screening", "summary.txt")

    # ---------------------------------------------------------------- regression
    @property
    def models(self) -> str:
        """The fitted stepwise models (JSON, ``bpmcal.analysis.stepwise.FORMAT``)."""
        return self.path("regression", "models.json")

    @property
    def equations(self) -> str:
        return self.path("regression", "equations.md")

    @property
    def regression_summaries(self) -> str:
        return self.path("regression", "summaries.txt")

    @property
    def coefficients(self) -> str:
        """Coefficients of every model and stage (table)."""
        return self.path("regression", "coefficients.csv")

    @property
    def candidate_terms(self) -> str:
        """Table 4 over all candidate terms (table)."""
        return self.path("regression", "table4_candidate_terms.csv")

    # ---------------------------------------------------------------- calibration
    def initial_card(self, specimen: str) -> str:
        """The material card of the calibration at the configured ratio (feeds the sweep)."""
        return self.path("calibration_initial", f"{specimen}.yaml")

    def card(self, specimen: str) -> str:
        """The material card of the final calibration (``bpmcal.io.card``)."""
        return self.path("calibration", f"{specimen}.yaml")

    # ---------------------------------------------------------------- verification
    def verified_card(self, specimen: str) -> str:
        """The card with its closed-loop DEM verification."""
        return self.path("verification", specimen, "card.yaml")

    def verification_rounds(self, specimen: str) -> str:
        """One row per DEM round of the closed loop (table)."""
        return self.path("verification", specimen, "rounds.csv")

    def verification_run(self, specimen: str) -> str:
        """The run file of the best round (a failure record when the loop did not run)."""
        return self.path("verification", specimen, "best_round.h5")

    def verification_seeds(self, specimen: str) -> str:
        """Every seed run of every round of the closed loop (table: round, seed,
        parameters, responses): the runs near the card the posterior learns from."""
        return self.path("verification", specimen, "seeds.csv")

    # ---------------------------------------------------------------- posterior
    def posterior_card(self, specimen: str) -> str:
        """The verified card with its posterior (``posterior`` section: intervals, what
        the targets pin and leave free, reach)."""
        return self.path("posterior", specimen, "card.yaml")

    def posterior_table(self, specimen: str) -> str:
        """One row per calibrated parameter: card value, posterior mean, sd, 90 % HDI,
        the card's position, convergence (table)."""
        return self.path("posterior", specimen, "parameters.csv")

    def posterior_predictions(self, specimen: str) -> str:
        """One row per response (targeted or not): the surrogate's mean and interval over
        the posterior, the card's value (table)."""
        return self.path("posterior", specimen, "predictions.csv")

    def posterior_netcdf(self, specimen: str) -> str:
        """The posterior's draws as an arviz InferenceData (NetCDF)."""
        return self.path("posterior", specimen, "posterior.nc")

    def posterior_pairs(self, specimen: str) -> str:
        """The pair plot of the posterior's draws, the card marked (figure)."""
        return self.path("posterior", specimen, "pairs.png")

    def posterior_learning(self, specimen: str) -> str:
        """The learning curve: posterior width against the DEM runs near the card
        (table)."""
        return self.path("posterior", specimen, "learning.csv")

    def posterior_learning_figure(self, specimen: str) -> str:
        """The learning curve (figure)."""
        return self.path("posterior", specimen, "learning.png")

    def posterior_refine(self, specimen: str) -> str:
        """The refinement's DEM runs (table: one row per seed run, like the loop's)."""
        return self.path("posterior", specimen, "refine.csv")

    def posterior_draws(self, specimen: str) -> str:
        """The draws the posterior predictive runs in DEM (table)."""
        return self.path("posterior", specimen, "draws.csv")

    def predictive_run(self, specimen: str, draw, test: str) -> str:
        """A posterior-predictive DEM run of draw ``draw`` (``test``: ``s3_<σ3>MPa`` or
        ``impact``)."""
        return self.path("posterior", specimen, "predictive", f"draw{draw}.{test}.h5")

    def predictive_runs(self, specimen: str, n: int, sigma3, impact: bool
                        ) -> tuple[list[str], list[str]]:
        """The run files of ``n`` predictive draws: the triaxial runs draw by draw, σ3
        (MPa) within each, and the impact runs (empty without)."""
        tri = [self.predictive_run(specimen, i, f"s3_{sigma3_tag(s)}MPa")
               for i in range(1, n + 1) for s in sigma3]
        imp = [self.predictive_run(specimen, i, "impact") for i in range(1, n + 1)] if impact \
            else []
        return tri, imp

    def posterior_predictive(self, specimen: str) -> str:
        """The posterior predictive in DEM: one row per draw (mi, c, φ, η_f) and the
        verified card's (table)."""
        return self.path("posterior", specimen, "predictive.csv")

    def transferred_card(self, specimen: str) -> str:
        """The verified card run (and, if needed, corrected) at the transfer scale."""
        return self.path("transfer", specimen, "card.yaml")

    def transfer_rounds(self, specimen: str) -> str:
        """One row per DEM round of the full-size transfer (table)."""
        return self.path("transfer", specimen, "rounds.csv")

    def transfer_run(self, specimen: str) -> str:
        """The run file of the transfer's best round."""
        return self.path("transfer", specimen, "best_round.h5")

    def fresh_seed_run(self, specimen: str, seed) -> str:
        """The fresh-seed check's UCS run of a verified card with packing seed ``seed``."""
        return self.path("verification", specimen, "fresh_seeds", f"seed{seed}.h5")

    def fresh_seed_bts_run(self, specimen: str, seed) -> str:
        """... and its Brazilian run (a failure record "not run" without a σt target)."""
        return self.path("verification", specimen, "fresh_seeds", f"seed{seed}.bts.h5")

    def fresh_seed_dtt_run(self, specimen: str, seed) -> str:
        """... and its direct-tension run (with a direct-tension strength target)."""
        return self.path("verification", specimen, "fresh_seeds", f"seed{seed}.dtt.h5")

    def fresh_seed_tri_run(self, specimen: str, seed) -> str:
        """... and its triaxial run at the design confinement (with a tri_MPa target)."""
        return self.path("verification", specimen, "fresh_seeds", f"seed{seed}.tri.h5")

    def fresh_seed_runs(self, specimen: str) -> str:
        """The fresh-seed check's responses of every seed (table)."""
        return self.path("verification", specimen, "fresh_seeds", "seeds.csv")

    def bts_size_dir(self, specimen: str) -> str:
        """The run files of a verified card's σt size curve (``bts_size``; a folder: the
        seeds per size grow until σt is precise enough)."""
        return self.path("verification", specimen, "bts_size", "runs")

    def bts_size_runs(self, specimen: str) -> str:
        """... one row per disc size and seed (table)."""
        return self.path("verification", specimen, "bts_size", "runs.csv")

    def bts_size_sizes(self, specimen: str) -> str:
        """... one row per disc size: seeds, valid discs, σt mean and SE (table)."""
        return self.path("verification", specimen, "bts_size", "sizes.csv")

    def bts_size_fit(self, specimen: str) -> str:
        """... the power-law fit and σt at the lab's disc size against the lab (table)."""
        return self.path("verification", specimen, "bts_size", "fit.csv")

    def scatter_run(self, seed) -> str:
        """The UCS run of the first specimen's card with packing seed ``seed``."""
        return self.path("verification", "seed_scatter", f"seed{seed}.h5")

    @property
    def scatter_runs(self) -> str:
        """The responses of every seed's run (table)."""
        return self.path("verification", "seed_scatter", "seed_runs.csv")

    @property
    def seed_scatter(self) -> str:
        """Coefficient of variation and noise floor per response (table)."""
        return self.path("verification", "seed_scatter", "seed_scatter.csv")

    # ---------------------------------------------------------------- strength-ratio sweep
    @property
    def sweep_plan(self) -> str:
        """One row per ratio: the parameters to run, or why not (unreachable)."""
        return self.path("ratio_sweep", "plan.csv")

    def sweep_run(self, rid: str) -> str:
        return self.path("ratio_sweep", "runs", f"{rid}.h5")

    @property
    def sweep_chosen(self) -> str:
        """The chosen ratio (JSON; ``chosen_ratio`` null when no run was usable)."""
        return self.path("ratio_sweep", "chosen.json")

    @property
    def sweep_vtk(self) -> str:
        """ParaView files of the runs Fig. 5 shows (a folder: which runs depends on the
        chosen ratio)."""
        return self.path("ratio_sweep", "vtk")

    # ---------------------------------------------------------------- triaxial
    def triaxial_card(self, kind: str, specimen: str) -> str:
        """The card a triaxial run of ``kind`` ("calibrated" | "verified") uses."""
        if kind not in TRIAXIAL_CARDS:
            raise ValueError(f"triaxial card kind {kind!r}: expected one of {TRIAXIAL_CARDS}")
        return self.card(specimen) if kind == "calibrated" else self.verified_card(specimen)

    def triaxial_run(self, kind: str, specimen: str, tag: str) -> str:
        """The triaxial run of a card at confining stress tag ``tag`` (:func:`sigma3_tag`)."""
        return self.path("triaxial", kind, specimen, f"s3_{tag}MPa.h5")

    # ---------------------------------------------------------------- impact
    def impact_run(self, tag: str) -> str:
        """The drop-hammer run at velocity tag ``tag`` (:func:`velocity_tag`)."""
        return self.path("impact", f"impact_{tag}ms.h5")

    @property
    def jk_fit(self) -> str:
        """The JK breakage-model fit of t10 vs Ecs (JSON; null when the fit failed)."""
        return self.path("tables", "jk_fit.json")

    # ---------------------------------------------------------------- report
    @property
    def report_dir(self) -> str:
        return self.path("report")

    @property
    def report_index(self) -> str:
        return self.path("report", "index.md")

    @property
    def report_config(self) -> str:
        """The merged study config the report was built with (JSON)."""
        return self.path("report", "config.json")

    def posterior_report_files(self, specimens, curve: bool = True, predictive=()) -> list[str]:
        """The posterior files the report shows (every specimen's tables, figures and
        card; the predictive table of the ``predictive`` specimens)."""
        out = []
        for s in specimens:
            out += [self.posterior_card(s), *companions(self.posterior_table(s)),
                    *companions(self.posterior_predictions(s)),
                    *companions(self.posterior_pairs(s))]
            if curve:
                out += [*companions(self.posterior_learning(s)),
                        *companions(self.posterior_learning_figure(s))]
            if s in predictive:
                out += companions(self.posterior_predictive(s))
        return out

    def report_copy(self, path: str) -> str:
        """Where the report keeps its copy of a table, figure or the equations."""
        folder = {".csv": "tables", ".md": "tables", ".png": "figures", ".pdf": "figures"}
        name = path.rsplit("/", 1)[-1]
        if path == self.equations:
            return self.path("report", name)
        post = self.path("posterior", "")
        if path.startswith(post):  # posterior/<specimen>/<name>: one folder per specimen
            return self.path("report", "posterior", path[len(post):])
        return self.path("report", folder[name[name.rfind("."):]], name)

    @property
    def comparison(self) -> str:
        """Every published value next to ours (report of the paper's study only)."""
        return self.path("report", "tables", "comparison.csv")

    # ---------------------------------------------------------------- what the report shows
    def triaxial_tables(self, lab: bool = False) -> list[str]:
        """The tables of the triaxial envelope stage (CSV paths); the lab comparison only
        when lab triaxial points are given."""
        return [self.table(s) for s in (TRIAXIAL_ENVELOPES, TRIAXIAL_POINTS,
                                        *([TRIAXIAL_LAB] if lab else []))]

    def report_tables(self, sweep: bool = True, triaxial: bool = False,
                      triaxial_lab: bool = False, fresh_seeds: bool = False) -> list[str]:
        """The tables the report shows (CSV paths), in its order."""
        stems = [TABLE3, TABLE4, REGRESSION_FIT, CALIBRATION, TABLE5, TABLE6,
                 *([FRESH_SEEDS] if fresh_seeds else []), *([RATIO_SWEEP] if sweep else []),
                 IMPACT_ENERGY, T10_ECS]
        tx = self.triaxial_tables(triaxial_lab) if triaxial else []
        return [self.table(s) for s in stems] + tx

    def report_figures(self, sweep: bool = True, triaxial: bool = False) -> list[str]:
        """The figures the report shows (PNG paths), in its order."""
        stems = [FIG_SCREENING, FIG_REGRESSION, *([FIG4, FIG5] if sweep else []), FIG6, FIG7,
                 FIG_T10, *([FIG_ENVELOPES] if triaxial else [])]
        return [self.figure(s) for s in stems]

    def report_inputs(self, specimens, impact_tag: str, sweep: bool = True,
                      triaxial: bool = False, triaxial_lab: bool = False,
                      fresh_seeds: bool = False, posterior=()) -> dict:
        """Every file the report reads, by role (the report rule's ``input:``);
        ``posterior``: :meth:`posterior_report_files`."""
        tabs = [f for t in self.report_tables(sweep, triaxial, triaxial_lab, fresh_seeds)
                for f in companions(t)]
        figs = [f for g in self.report_figures(sweep, triaxial) for f in companions(g)]
        return {
            "tables": tabs, "figures": figs, "equations": [self.equations],
            "dataset": [self.dataset], "cards": [self.card(s) for s in specimens],
            "verified": [self.verified_card(specimens[0])], "scatter": [self.seed_scatter],
            "impact": [self.impact_run(impact_tag)], "jk_fit": [self.jk_fit],
            "chosen": [self.sweep_chosen] if sweep else [],
            "posterior": list(posterior),
        }

    def report_outputs(self, sweep: bool = True, reference: bool = True,
                       triaxial: bool = False, triaxial_lab: bool = False,
                       fresh_seeds: bool = False, posterior=()) -> list[str]:
        """Every file the report writes (the report rule's ``output:``); ``posterior``:
        :meth:`posterior_report_files` (every one but the cards is copied)."""
        copies = [self.report_copy(f) for f in [
            *(f for t in self.report_tables(sweep, triaxial, triaxial_lab, fresh_seeds)
              for f in companions(t)),
            *(f for g in self.report_figures(sweep, triaxial) for f in companions(g)),
            self.equations, *(f for f in posterior if not f.endswith(".yaml"))]]
        extra = companions(self.comparison) if reference else []
        return [self.report_index, self.report_config, *copies, *extra]
