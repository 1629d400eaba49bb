# Minimal workflow until the study DAG lands (issue: the study as a Snakemake DAG):
# runs a small engine demo so that `snakemake --cores 2` works on a fresh clone.
rule all:
    input:
        "results/demo/engine_throughput.json",


rule engine_demo:
    output:
        "results/demo/engine_throughput.json",
    log:
        "results/logs/engine_demo.log",
    shell:
        "python benchmarks/dem_throughput.py --n 2000 --steps 500 --json > {output} 2> {log}"
