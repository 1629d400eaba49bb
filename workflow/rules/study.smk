# The spine of the study: design -> one job per sample (rule sample: its UCS test and, with
# bts.enabled / dtt.enabled, its Brazilian / direct-tension test, with
# triaxial.design_sigma3_MPa its triaxial test at that confinement) -> gathered dataset.
# A sample whose DEM run fails writes a failure record (--failed-ok: exit 0), so the DAG
# goes on and the dataset carries the sample with its status and reason.


rule design:
    output:
        FILES.design,
    log:
        FILES.log("design"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        ranges=json.dumps(config["ranges"]),
        n=config["study"]["n_samples"],
        seed=config["study"]["lhs_seed"],
        opt=config["study"]["lhs_optimization"],
    shell:
        "bpmcal design --ranges {params.ranges:q} --n {params.n:q} --seed {params.seed:q} "
        "--optimization {params.opt:q} --out {output:q} > {log:q} 2>&1"


rule sample:
    input:
        FILES.design,
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
        opts=specimen_args(),
        # the Brazilian settings as a plain value (a callable's value is not compared by
        # Snakemake's params trigger: a changed bts key would not rerun the samples)
        bts_opts=bts_args() if BTS_ON else [],
        bts_out=lambda wc, output: ["--bts-out", output.bts] if BTS_ON else [],
        dtt_opts=dtt_args() if DTT_ON else [],
        dtt_out=lambda wc, output: ["--dtt-out", output.dtt] if DTT_ON else [],
        tri_opts=tri_args() if TRI_ON else [],
        tri_out=lambda wc, output: ["--tri-out", output.tri] if TRI_ON else [],
    shell:
        "bpmcal sample --design {input:q} --sample {wildcards.sample:q} --out {output.ucs:q} "
        "--threads {threads} --failed-ok {params.opts:q} {params.bts_out:q} "
        "{params.bts_opts:q} {params.dtt_out:q} {params.dtt_opts:q} "
        "{params.tri_out:q} {params.tri_opts:q} > {log:q} 2>&1"


rule gather:
    input:
        design=FILES.design,
        runs=[FILES.ucs_run(s) for s in SAMPLES],
        bts=[FILES.bts_run(s) for s in SAMPLES] if BTS_ON else [],
        dtt=[FILES.dtt_run(s) for s in SAMPLES] if DTT_ON else [],
        tri=[FILES.tri_run(s) for s in SAMPLES] if TRI_ON else [],
    output:
        FILES.dataset,
    log:
        FILES.log("gather"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        bts=lambda wc, input: ["--bts-runs", *input.bts] if input.bts else [],
        dtt=lambda wc, input: ["--dtt-runs", *input.dtt] if input.dtt else [],
        tri=lambda wc, input: ["--tri-runs", *input.tri] if input.tri else [],
    shell:
        "bpmcal gather --design {input.design:q} --runs {input.runs:q} {params.bts:q} "
        "{params.dtt:q} {params.tri:q} --out {output:q} > {log:q} 2>&1"
