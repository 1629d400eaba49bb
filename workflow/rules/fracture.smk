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
        "bpmcal sweep-plan --card {input.card} --models {input.models} --ratios {params.ratios} "
        "--seed {params.seed} --out {output} > {log} 2>&1"


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
        "bpmcal ucs --design {input} --sample {wildcards.rid} --out {output} "
        "--threads {threads} {params.opts} > {log} 2>&1"


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
        sweep=parent_of("plan", io="input"),
        tables=parent_of("table"),
        s=config["ratio_sweep"],
    shell:
        "bpmcal sweep-analyse --plan {input.plan} --runs {params.sweep}/runs "
        "--criterion {params.s[criterion]} --target {params.s[target]} --tables {params.tables} "
        "--figures {params.figs} --vtk {params.sweep}/vtk --chosen {output.chosen} > {log} 2>&1"


rule impact:
    input:
        card=f"{VERIF}/{IMPACT_SPEC}/card.yaml",
    output:
        f"{IMPACT}/impact_{{v}}ms.h5",
    log:
        f"{LOGS}/impact/impact_{{v}}ms.log",
    threads: config["resources"]["ucs_threads"]
    resources:
        runtime=config["resources"]["ucs_runtime_min"] * 2,
        mem_mb=config["resources"]["ucs_mem_mb"],
    params:
        i=config["impact"],
        opts=specimen_args(scale=config["impact"]["scale"]),
    shell:
        "bpmcal impact --card {input.card} --out {output} --velocity {wildcards.v} "
        "--hammer-mass {params.i[hammer_mass_kg]} --dp-ratio {params.i[dp_ratio]} "
        "--anvil-fric {params.i[anvil_fric]} --duration-ms {params.i[duration_ms]} "
        "--record-us {params.i[record_us]} --seed {params.i[seed]} --threads {threads} "
        "{params.opts} > {log} 2>&1"


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
        "bpmcal impact-analyse --main {input.main} --runs {input.runs} --tables {params.tables} "
        "--figures {params.figs} > {log} 2>&1"
