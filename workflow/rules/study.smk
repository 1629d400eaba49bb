# The spine of the study: design -> one UCS job per sample -> gathered dataset.
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
        FILES.ucs_run("{sample}"),
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
    shell:
        "bpmcal ucs --design {input:q} --sample {wildcards.sample:q} --out {output:q} "
        "--threads {threads} --failed-ok {params.opts:q} > {log:q} 2>&1"


rule gather:
    input:
        design=FILES.design,
        runs=[FILES.ucs_run(s) for s in SAMPLES],
    output:
        FILES.dataset,
    log:
        FILES.log("gather"),
    conda:
        "../envs/bpmcal.yaml"
    shell:
        "bpmcal gather --design {input.design:q} --runs {input.runs:q} --out {output:q} "
        "> {log:q} 2>&1"
