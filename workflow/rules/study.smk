# The spine of the study: design -> one job per sample (rule sample: its UCS test and, with
# bts.enabled / dtt.enabled, its Brazilian / direct-tension test, with
# triaxial.design_sigma3_MPa its triaxial test at that confinement) -> gathered dataset.
# A sample whose DEM run fails writes a failure record (--failed-ok: exit 0), so the DAG
# goes on and the dataset carries the sample with its status and reason.
# Every rule's command is the package's (bpmcal.cli.jobs, by the rule's name): the rule
# names its files; params.settings is what the job reads of the config (compared by
# Snakemake's params trigger), params.argv the whole command.


rule design:
    output:
        design=FILES.design,
    log:
        FILES.log("design"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("design"),
        argv=argv("design"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule sample:
    input:
        design=FILES.design,
    output:
        ucs=FILES.ucs_run("{sample}"),
        # with bts.enabled, the sample's Brazilian test runs in the same job (one process
        # start-up for both; `bpmcal sample --bts-out`): a sample job writes both run files
        bts=FILES.bts_run("{sample}") if BTS_ON else [],
        dtt=FILES.dtt_run("{sample}") if DTT_ON else [],
        tri=FILES.tri_run("{sample}") if TRI_ON else [],
    log:
        FILES.log("sample", "{sample}"),
    wildcard_constraints:
        sample=r"s\d+",
    priority: PRIORITY["sample"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["dem_threads"]
    resources:
        runtime=config["resources"]["dem_runtime_min"],
        mem_mb=config["resources"]["dem_mem_mb"],
    params:
        # the settings as a plain value (argv, derived from the job's files, is not
        # compared by Snakemake's params trigger: a changed bts key would not rerun the
        # samples)
        settings=settings("sample"),
        argv=argv("sample"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule gather:
    input:
        design=FILES.design,
        runs=[FILES.ucs_run(s) for s in SAMPLES],
        bts=[FILES.bts_run(s) for s in SAMPLES] if BTS_ON else [],
        dtt=[FILES.dtt_run(s) for s in SAMPLES] if DTT_ON else [],
        tri=[FILES.tri_run(s) for s in SAMPLES] if TRI_ON else [],
    output:
        dataset=FILES.dataset,
    log:
        FILES.log("gather"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        argv=argv("gather"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
