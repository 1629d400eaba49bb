# The spine of the study: design -> one UCS job per sample -> gathered dataset.
# A sample whose DEM run fails writes a failure record (--failed-ok: exit 0), so the DAG
# goes on and the dataset carries the sample with its status and reason.


rule design:
    output:
        DESIGN,
    log:
        f"{LOGS}/design.log",
    params:
        ranges=json.dumps(config["ranges"]),
        n=N,
        seed=config["study"]["lhs_seed"],
        opt=config["study"]["lhs_optimization"],
    shell:
        "bpmcal design --ranges {params.ranges:q} --n {params.n:q} --seed {params.seed:q} "
        "--optimization {params.opt:q} --out {output:q} > {log:q} 2>&1"


rule ucs:
    input:
        DESIGN,
    output:
        f"{OUT}/ucs/{{sample}}.h5",
    log:
        f"{LOGS}/ucs/{{sample}}.log",
    wildcard_constraints:
        sample=r"s\d+",
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
        design=DESIGN,
        runs=expand(f"{OUT}/ucs/{{sample}}.h5", sample=SAMPLES),
    output:
        DATASET,
    log:
        f"{LOGS}/gather.log",
    params:
        runs=parent_of("runs", io="input"),
    shell:
        "bpmcal gather --design {input.design:q} --runs {params.runs:q} --out {output:q} "
        "> {log:q} 2>&1"
