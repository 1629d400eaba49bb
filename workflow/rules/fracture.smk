# Bond-strength-ratio sweep (Figs. 4, 5) and drop-hammer impact (Fig. 7, t10 vs Ecs).


rule sweep_plan:
    input:
        card=f"{CALIB0}/{SWEEP_SPEC}.yaml",
        models=f"{REGR}/models.json",
    output:
        SWEEP_PLAN,
    log:
        f"{LOGS}/sweep_plan.log",
    params:
        ratios=",".join(str(x) for x in config["ratio_sweep"]["ratios"]),
        seed=config["ratio_sweep"]["seed"],
    shell:
        "bpmcal sweep-plan --card {input.card:q} --models {input.models:q} "
        "--ratios {params.ratios:q} --seed {params.seed:q} --out {output:q} > {log:q} 2>&1"


rule sweep_ucs:
    input:
        SWEEP_PLAN,
    output:
        f"{SWEEP}/runs/{{rid}}.h5",
    log:
        f"{LOGS}/sweep/{{rid}}.log",
    wildcard_constraints:
        rid=r"a\d+",
    threads: config["resources"]["ucs_threads"]
    resources:
        runtime=config["resources"]["ucs_runtime_min"],
        mem_mb=config["resources"]["ucs_mem_mb"],
    params:
        opts=specimen_args(),
    shell:
        "bpmcal ucs --design {input:q} --sample {wildcards.rid:q} --out {output:q} "
        "--threads {threads} --failed-ok {params.opts:q} > {log:q} 2>&1"


rule sweep_analyse:
    input:
        plan=SWEEP_PLAN,
        runs=expand(f"{SWEEP}/runs/{{rid}}.h5", rid=SWEEP_IDS),
    output:
        table=f"{TABLES}/ratio_sweep.csv",
        chosen=SWEEP_CHOSEN,
        fig4=report(f"{FIGS}/fig4_ratio_cracks.png", caption="../report/fig4.rst",
                    category="Failure and fragmentation"),
        fig5=report(f"{FIGS}/fig5_failure_patterns.png", caption="../report/fig5.rst",
                    category="Failure and fragmentation"),
    log:
        f"{LOGS}/sweep_analyse.log",
    params:
        figs=parent_of("fig4"),
        runs=parent_of("runs", io="input"),
        vtk=f"{SWEEP}/vtk",
        tables=parent_of("table"),
        s=config["ratio_sweep"],
    shell:
        "bpmcal sweep-analyse --plan {input.plan:q} --runs {params.runs:q} "
        "--criterion {params.s[criterion]:q} --target {params.s[target]:q} "
        "--tables {params.tables:q} --figures {params.figs:q} --vtk {params.vtk:q} "
        "--chosen {output.chosen:q} > {log:q} 2>&1"


rule impact:
    input:
        card=f"{VERIF}/{IMPACT_SPEC}/card.yaml",
    output:
        f"{IMPACT}/impact_{{v}}ms.h5",
    log:
        f"{LOGS}/impact/impact_{{v}}ms.log",
    wildcard_constraints:
        v=r"[0-9][0-9.e+-]*",
    threads: config["resources"]["ucs_threads"]
    resources:
        runtime=config["resources"]["ucs_runtime_min"] * 2,
        mem_mb=config["resources"]["ucs_mem_mb"],
    params:
        i=config["impact"],
        opts=specimen_args(scale=config["impact"]["scale"]),
    shell:
        "bpmcal impact --card {input.card:q} --out {output:q} --velocity {wildcards.v:q} "
        "--hammer-mass {params.i[hammer_mass_kg]:q} --dp-ratio {params.i[dp_ratio]:q} "
        "--anvil-fric {params.i[anvil_fric]:q} --duration-ms {params.i[duration_ms]:q} "
        "--record-us {params.i[record_us]:q} --seed {params.i[seed]:q} --threads {threads} "
        "--failed-ok {params.opts:q} > {log:q} 2>&1"


rule impact_analyse:
    input:
        main=f"{IMPACT}/impact_{IMPACT_V0}ms.h5",
        runs=expand(f"{IMPACT}/impact_{{v}}ms.h5", v=IMPACT_VS),
    output:
        energy=f"{TABLES}/impact_energy.csv",
        t10=f"{TABLES}/t10_ecs.csv",
        fig7=report(f"{FIGS}/fig7_impact_energy.png", caption="../report/fig7.rst",
                    category="Failure and fragmentation"),
        figt10=report(f"{FIGS}/t10_ecs.png", caption="../report/t10.rst",
                      category="Failure and fragmentation"),
    log:
        f"{LOGS}/impact_analyse.log",
    params:
        figs=parent_of("fig7"),
        tables=parent_of("energy"),
    shell:
        "bpmcal impact-analyse --main {input.main:q} --runs {input.runs:q} "
        "--tables {params.tables:q} --figures {params.figs:q} > {log:q} 2>&1"
