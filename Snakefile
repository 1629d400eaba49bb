# bpmcal: the calibration study of Yu et al. (2026) as a Snakemake DAG.
#
#   snakemake --cores 2                                   # default study (config/config.yaml)
#   snakemake --cores 2 --configfile config/smoke.yaml    # a few tiny samples (CI)
#   snakemake --workflow-profile workflow/profiles/slurm --configfile config/paper.yaml
#
# The config is validated against workflow/schemas/config.schema.yaml before any job runs.

configfile: "config/config.yaml"


include: "workflow/rules/common.smk"


# cheap rules run on the submit host when the study goes to a cluster
localrules:
    all,
    design,
    gather,


include: "workflow/rules/study.smk"


rule all:
    input:
        DATASET,
    default_target: True
