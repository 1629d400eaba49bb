# The spine of the study: design -> one job per sample (its UCS test and, with
# bts.enabled, its Brazilian test) -> gathered dataset.
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


rule ucs:
    input:
        FILES.design,
    output:
        ucs=FILES.ucs_run("{sample}"),
        # with bts.enabled, the sample's Brazilian test runs in the same job (one process
        # start-up for both; `bpmcal ucs --bts-out`): a sample job writes both run files
        bts=FILES.bts_run("{sample}") if BTS_ON else [],
    log:
        FILES.log("ucs", "{sample}"),
    wildcard_constraints:
        sample=r"s\d+",
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["ucs_threads"]
    resources:
        runtime=config["resources"]["ucs_runtime_min"],
        mem_mb=config["resources"]["ucs_mem_mb"],
    params:
        opts=specimen_args(),
        bts=lambda wc, output: (
            ["--bts-out", output.bts, *bts_args()] if BTS_ON else []
        ),
    shell:
        "bpmcal ucs --design {input:q} --sample {wildcards.sample:q} --out {output.ucs:q} "
        "--threads {threads} --failed-ok {params.opts:q} {params.bts:q} > {log:q} 2>&1"


rule gather:
    input:
        design=FILES.design,
        runs=[FILES.ucs_run(s) for s in SAMPLES],
        bts=[FILES.bts_run(s) for s in SAMPLES] if BTS_ON else [],
    output:
        FILES.dataset,
    log:
        FILES.log("gather"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        bts=lambda wc, input: ["--bts-runs", *input.bts] if input.bts else [],
    shell:
        "bpmcal gather --design {input.design:q} --runs {input.runs:q} {params.bts:q} "
        "--out {output:q} > {log:q} 2>&1"
