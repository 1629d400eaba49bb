# bpmcal: the calibration study of Yu et al. (2026) as a Snakemake DAG.
#
#   snakemake --cores 2                                   # default study (config/config.yaml)
#   snakemake --cores 2 --configfile config/smoke.yaml    # a few tiny samples (CI)
#   snakemake --workflow-profile workflow/profiles/slurm --configfile config/paper.yaml
#
# The config is validated against workflow/schemas/config.schema.yaml before any job runs
# (every key: config/README.md). Every file of the study is named in one place,
# bpmcal.io.study_files (docs/architecture.md); the rules declare each file they read and write.
from snakemake.utils import min_version

min_version("8.0")


configfile: "config/config.yaml"


# `snakemake --report results/report.html`: self-contained HTML with every figure and caption
report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"


# cheap rules run on the submit host when the study goes to a cluster
localrules:
    all,
    design,
    gather,
    screen,
    regress,
    calibrate,
    calibrate_initial,
    verification_tables,
    transfer_table,
    fresh_seeds_table,
    sweep_plan,
    sweep_analyse,
    impact_analyse,
    triaxial_envelopes,
    report,


include: "workflow/rules/study.smk"
include: "workflow/rules/analysis.smk"
include: "workflow/rules/fracture.smk"
include: "workflow/rules/triaxial.smk"
include: "workflow/rules/posterior.smk"
include: "workflow/rules/bts_size.smk"
include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        FILES.dataset,
        rules.screen.output,
        rules.regress.output,
        rules.calibrate.output,
        rules.verification_tables.output,
        rules.seed_scatter.output,
        rules.fresh_seeds_table.output if FRESH_SEEDS_ON else [],
        # every fresh seed's run files: a seed added to verification.fresh_seeds makes
        # its runs missing, which reruns its fresh_seeds job (the seed tables alone
        # would not)
        [FILES.fresh_seed_run(s, seed) for s in SPECIMENS for seed in FRESH_SEEDS],
        (
            [
                FILES.fresh_seed_bts_run(s, seed)
                for s in SPECIMENS
                for seed in FRESH_SEEDS
            ]
            if BTS_ON
            else []
        ),
        (
            [
                FILES.fresh_seed_dtt_run(s, seed)
                for s in SPECIMENS
                for seed in FRESH_SEEDS
            ]
            if LAB_DTT
            else []
        ),
        [FILES.bts_size_fit(s) for s in BTS_SIZE_SPECS],
        rules.transfer_table.output if TRANSFER_ON else [],
        rules.sweep_analyse.output if SWEEP_ON else [],
        rules.impact_analyse.output,
        rules.triaxial_envelopes.output if TRIAX_ON else [],
        [FILES.posterior_card(s) for s in SPECIMENS] if POSTERIOR_ON else [],
        # the table and every run file: a new confining stress is a missing file (Snakemake
        # reruns a job for its missing outputs only when they are requested)
        [
            f
            for s in PREDICTIVE_SPECS
            for f in (
                FILES.posterior_predictive(s),
                *sum(FILES.predictive_runs(s, _PRED_N, _PRED_S3, _PRED_IMPACT), []),
            )
        ],
        rules.report.output,
