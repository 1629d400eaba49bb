# σt at the lab's disc size (bpmcal bts-size; bpmcal.stages.bts_size): for every lab row
# whose bts_diameter_mm differs from the study's disc, its verified card's σt on a few disc
# sizes, the fitted size curve and σt at the lab's size against the lab's. No lab row with
# a diameter: no job (the DAG is the study's without it).
from bpmcal.cli.jobs import bts_size_diameters

# specimen -> its lab discs' diameter [mm], where it differs from the study's disc
BTS_SIZE_SPECS = list(bts_size_diameters(config, _lab))


rule bts_size:
    input:
        card=FILES.verified_card("{spec}"),
        lab=config["lab"]["csv"],  # its bts_diameter_mm (the job's --lab-diameter)
    output:
        beside(
            FILES.bts_size_runs("{spec}"),
            FILES.bts_size_sizes("{spec}"),
            FILES.bts_size_fit("{spec}"),
        ),
        run_dir=directory(FILES.bts_size_dir("{spec}")),
        runs=FILES.bts_size_runs("{spec}"),
        sizes=FILES.bts_size_sizes("{spec}"),
        fit=FILES.bts_size_fit("{spec}"),
    log:
        FILES.log("bts_size", "{spec}"),
    priority: PRIORITY["bts_size"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["dem_threads"]
    resources:
        runtime=config["resources"]["dem_runtime_min"]
        * 3
        * config["bts_size"]["max_seeds"],
        mem_mb=config["resources"]["dem_mem_mb"],
    params:
        settings=settings("bts_size"),
        argv=argv("bts_size"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
