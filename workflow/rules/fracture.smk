# Bond-strength-ratio sweep (Figs. 4, 5) and drop-hammer impact (Fig. 7, t10 vs Ecs).


rule sweep_plan:
    input:
        card=FILES.initial_card(SWEEP_SPEC),
        models=FILES.models,
    output:
        plan=FILES.sweep_plan,
    log:
        FILES.log("sweep_plan"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("sweep_plan"),
        argv=argv("sweep_plan"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule sweep_ucs:
    input:
        plan=FILES.sweep_plan,
    output:
        run=FILES.sweep_run("{rid}"),
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
        settings=settings("sweep_ucs"),
        argv=argv("sweep_ucs"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


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
        settings=settings("sweep_analyse"),
        argv=argv("sweep_analyse"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule impact:
    input:
        card=IMPACT_CARD,
    output:
        run=FILES.impact_run("{v}"),
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
        settings=settings("impact"),
        argv=argv("impact"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


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
    params:
        argv=argv("impact_analyse"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
