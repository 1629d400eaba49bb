# Bond-strength-ratio sweep (Figs. 4, 5) and drop-hammer impact (Fig. 7, t10 vs Ecs).


rule sweep_plan:
    input:
        card=FILES.initial_card(SWEEP_SPEC),
        models=FILES.models,
    output:
        FILES.sweep_plan,
    log:
        FILES.log("sweep_plan"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        ratios=",".join(str(x) for x in config["ratio_sweep"]["ratios"]),
        seed=config["ratio_sweep"]["seed"],
    shell:
        "bpmcal sweep-plan --card {input.card:q} --models {input.models:q} "
        "--ratios {params.ratios:q} --seed {params.seed:q} --out {output:q} > {log:q} 2>&1"


rule sweep_ucs:
    input:
        FILES.sweep_plan,
    output:
        FILES.sweep_run("{rid}"),
    log:
        FILES.log("sweep", "{rid}"),
    wildcard_constraints:
        rid=r"a\d+",
    priority: PRIORITY["sweep_ucs"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["dem_threads"]
    resources:
        runtime=config["resources"]["dem_runtime_min"],
        mem_mb=config["resources"]["dem_mem_mb"],
    params:
        opts=specimen_args(),
    shell:
        "bpmcal ucs --design {input:q} --sample {wildcards.rid:q} --out {output:q} "
        "--threads {threads} --failed-ok {params.opts:q} > {log:q} 2>&1"


rule sweep_analyse:
    input:
        plan=FILES.sweep_plan,
        runs=[FILES.sweep_run(r) for r in SWEEP_IDS],
    output:
        beside(
            FILES.table(L.RATIO_SWEEP),
            FILES.figure(L.FIG4),
            FILES.figure(L.FIG5),
        ),
        table=FILES.table(L.RATIO_SWEEP),
        chosen=FILES.sweep_chosen,
        fig4=report(
            FILES.figure(L.FIG4),
            caption="../report/fig4.rst",
            category="Failure and fragmentation",
        ),
        fig5=report(
            FILES.figure(L.FIG5),
            caption="../report/fig5.rst",
            category="Failure and fragmentation",
        ),
        vtk=directory(FILES.sweep_vtk),
    log:
        FILES.log("sweep_analyse"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        s={k: config["ratio_sweep"][k] for k in ("criterion", "target")},
    shell:
        "bpmcal sweep-analyse --plan {input.plan:q} --runs {input.runs:q} "
        "--criterion {params.s[criterion]:q} --target {params.s[target]:q} "
        "--table {output.table:q} --chosen {output.chosen:q} --fig4 {output.fig4:q} "
        "--fig5 {output.fig5:q} --vtk {output.vtk:q} > {log:q} 2>&1"


rule impact:
    input:
        card=IMPACT_CARD,
    output:
        FILES.impact_run("{v}"),
    log:
        FILES.log("impact", "impact_{v}ms"),
    wildcard_constraints:
        v=r"[0-9][0-9.e+-]*",
    priority: PRIORITY["impact"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["dem_threads"]
    resources:
        runtime=config["resources"]["dem_runtime_min"] * 2,
        mem_mb=config["resources"]["dem_mem_mb"],
    params:
        # what an impact run reads (not the velocities: a job's own is its wildcard)
        i={
            k: config["impact"][k]
            for k in (
                "hammer_mass_kg",
                "dp_ratio",
                "anvil_fric",
                "duration_ms",
                "record_us",
                "seed",
            )
        },
        opts=specimen_args(scale=config["impact"]["scale"], loading=False),
    shell:
        "bpmcal impact --card {input.card:q} --out {output:q} --velocity {wildcards.v:q} "
        "--hammer-mass {params.i[hammer_mass_kg]:q} --dp-ratio {params.i[dp_ratio]:q} "
        "--anvil-fric {params.i[anvil_fric]:q} --duration-ms {params.i[duration_ms]:q} "
        "--record-us {params.i[record_us]:q} --seed {params.i[seed]:q} --threads {threads} "
        "--failed-ok {params.opts:q} > {log:q} 2>&1"


rule impact_analyse:
    input:
        main=FILES.impact_run(IMPACT_V0),
        runs=[FILES.impact_run(v) for v in IMPACT_VS],
    output:
        beside(
            FILES.table(L.IMPACT_ENERGY),
            FILES.table(L.T10_ECS),
            FILES.figure(L.FIG7),
            FILES.figure(L.FIG_T10),
        ),
        energy=FILES.table(L.IMPACT_ENERGY),
        t10=FILES.table(L.T10_ECS),
        jk_fit=FILES.jk_fit,
        fig7=report(
            FILES.figure(L.FIG7),
            caption="../report/fig7.rst",
            category="Failure and fragmentation",
        ),
        figt10=report(
            FILES.figure(L.FIG_T10),
            caption="../report/t10.rst",
            category="Failure and fragmentation",
        ),
    log:
        FILES.log("impact_analyse"),
    conda:
        "../envs/bpmcal.yaml"
    shell:
        "bpmcal impact-analyse --main {input.main:q} --runs {input.runs:q} "
        "--energy {output.energy:q} --t10 {output.t10:q} --jk-fit {output.jk_fit:q} "
        "--fig7 {output.fig7:q} --fig-t10 {output.figt10:q} > {log:q} 2>&1"
