# σt at the lab's disc size (bpmcal bts-size; bpmcal.stages.bts_size): for every lab row
# whose bts_diameter_mm differs from the study's disc, its verified card's σt on a few disc
# sizes, the fitted size curve and σt at the lab's size against the lab's. No lab row with
# a diameter: no job (the DAG is the study's without it).
from bpmcal.study.lab_data import lab_disc_diameters

# the study's disc [mm]: bts.scale (null: the cylinder's scale) x bts.diameter_mm
_BTS_DISC_MM = (
    config["bts"]["scale"]
    if config["bts"]["scale"] is not None
    else config["specimen"]["scale"]
) * config["bts"]["diameter_mm"]
# specimen -> its lab discs' diameter [mm], where it differs from the study's disc
BTS_SIZE_LAB_MM = lab_disc_diameters(_lab, _BTS_DISC_MM)
BTS_SIZE_SPECS = list(BTS_SIZE_LAB_MM)


rule bts_size:
    input:
        card=FILES.verified_card("{spec}"),
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
        lab_mm=lambda wc: BTS_SIZE_LAB_MM[wc.spec],
        size=[
            "--seeds",
            config["bts_size"]["seeds"],
            "--max-seeds",
            config["bts_size"]["max_seeds"],
            "--target-se",
            config["bts_size"]["target_se"],
            "--first-seed",
            config["bts_size"]["first_seed"],
            "--middle" if config["bts_size"]["middle"] else "--no-middle",
        ],
        opts=specimen_args(),
        bts=bts_args(),
    shell:
        "bpmcal bts-size --card {input.card:q} --lab-diameter {params.lab_mm:q} "
        "--run-dir {output.run_dir:q} --runs {output.runs:q} --sizes {output.sizes:q} "
        "--fit {output.fit:q} --threads {threads} {params.size:q} {params.opts:q} "
        "{params.bts:q} > {log:q} 2>&1"
