# Dataset -> screening (Table 3) -> stepwise regression (Table 4) -> calibration to the
# lab specimens -> closed-loop DEM verification (Tables 5, 6, Fig. 6).


rule screen:
    input:
        dataset=FILES.dataset,
    output:
        beside(
            FILES.table(L.TABLE3),
            FILES.figure(L.FIG_SCREENING),
            FILES.importance_table,
            FILES.screening_cv,
            FILES.screening_shadow,
        ),
        selected=FILES.selected,
        table3=FILES.table(L.TABLE3),
        fig=report(
            FILES.figure(L.FIG_SCREENING),
            caption="../report/screening.rst",
            category="Calibration",
        ),
        importance=FILES.importance_table,
        cv=FILES.screening_cv,
        shadow=FILES.screening_shadow,
        summary=FILES.screening_summary,
    log:
        FILES.log("screen"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("screen"),
        argv=argv("screen"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule regress:
    input:
        dataset=FILES.dataset,
        selected=FILES.selected,
    output:
        beside(
            FILES.table(L.TABLE4),
            FILES.table(L.REGRESSION_FIT),
            FILES.figure(L.FIG_REGRESSION),
            FILES.coefficients,
            FILES.candidate_terms,
        ),
        models=FILES.models,
        equations=FILES.equations,
        summaries=FILES.regression_summaries,
        coefficients=FILES.coefficients,
        candidates=FILES.candidate_terms,
        table4=FILES.table(L.TABLE4),
        fit=FILES.table(L.REGRESSION_FIT),
        fig=report(
            FILES.figure(L.FIG_REGRESSION),
            caption="../report/regression.rst",
            category="Calibration",
        ),
    log:
        FILES.log("regress"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("regress"),
        argv=argv("regress"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule calibrate_initial:
    input:
        dataset=FILES.dataset,
        models=FILES.models,
        lab=config["lab"]["csv"],
    output:
        cards=[FILES.initial_card(s) for s in SPECIMENS],
    log:
        FILES.log("calibrate_initial"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("calibrate_initial"),
        argv=argv("calibrate_initial"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule calibrate:
    input:
        dataset=FILES.dataset,
        models=FILES.models,
        lab=config["lab"]["csv"],
        chosen=FILES.sweep_chosen if SWEEP_ON else [],
    output:
        beside(FILES.table(L.CALIBRATION)),
        cards=[FILES.card(s) for s in SPECIMENS],
        table=FILES.table(L.CALIBRATION),
    log:
        FILES.log("calibrate"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("calibrate"),
        argv=argv("calibrate"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule verify:
    input:
        card=FILES.card("{spec}"),
        models=FILES.models,
    output:
        beside(FILES.verification_rounds("{spec}"), FILES.verification_seeds("{spec}")),
        card=FILES.verified_card("{spec}"),
        rounds=FILES.verification_rounds("{spec}"),
        seeds=FILES.verification_seeds("{spec}"),
        run=FILES.verification_run("{spec}"),
    log:
        FILES.log("verify", "{spec}"),
    priority: PRIORITY["verify"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["loop_threads"]  # its seeds side by side
    resources:
        runtime=config["resources"]["dem_runtime_min"]
        * loop_rounds_bound(config, LAB_BTS or LAB_DTT)
        * config["verification"]["max_seeds"],
        mem_mb=config["resources"]["dem_mem_mb"] * config["resources"]["loop_threads"],
    params:
        # the closed loop's settings only (LoopSettings' fields): changing another
        # verification key (fresh_seeds, scatter_seeds) must not rerun the closed loops
        settings=settings("verify"),
        argv=argv("verify"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule transfer:
    input:
        card=FILES.verified_card("{spec}"),
        models=FILES.models,
    output:
        beside(FILES.transfer_rounds("{spec}")),
        card=FILES.transferred_card("{spec}"),
        rounds=FILES.transfer_rounds("{spec}"),
        run=FILES.transfer_run("{spec}"),
    log:
        FILES.log("transfer", "{spec}"),
    priority: PRIORITY["transfer"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["dem_threads"]
    resources:
        runtime=config["resources"]["dem_runtime_min"]
        * (1 + config["transfer"]["max_rounds"]),
        mem_mb=config["resources"]["dem_mem_mb"],
    params:
        settings=settings("transfer"),
        argv=argv("transfer"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule transfer_table:
    input:
        cards=[FILES.transferred_card(s) for s in SPECIMENS],
    output:
        beside(FILES.table(L.TRANSFER)),
        table=FILES.table(L.TRANSFER),
    log:
        FILES.log("transfer_table"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        argv=argv("transfer_table"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule seed_scatter:
    input:
        card=FILES.card(SPECIMENS[0]),
    output:
        beside(FILES.scatter_runs, FILES.seed_scatter),
        runs=[FILES.scatter_run(s) for s in SCATTER_SEEDS],
        seed_runs=FILES.scatter_runs,
        table=FILES.seed_scatter,
    log:
        FILES.log("seed_scatter"),
    priority: PRIORITY["seed_scatter"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["loop_threads"]  # its seeds side by side
    resources:
        runtime=config["resources"]["dem_runtime_min"] * len(SCATTER_SEEDS),
        mem_mb=config["resources"]["dem_mem_mb"] * config["resources"]["loop_threads"],
    params:
        settings=settings("seed_scatter"),
        argv=argv("seed_scatter"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule fresh_seeds:
    input:
        card=FILES.verified_card("{spec}"),
    output:
        beside(FILES.fresh_seed_runs("{spec}")),
        runs=[FILES.fresh_seed_run("{spec}", s) for s in FRESH_SEEDS],
        # every card's σt on the fresh seeds (a target, or the card's prediction)
        bts_runs=(
            [FILES.fresh_seed_bts_run("{spec}", s) for s in FRESH_SEEDS]
            if BTS_ON
            else []
        ),
        # σt,d too when the study runs direct tension (a target, or the prediction)
        dtt_runs=(
            [FILES.fresh_seed_dtt_run("{spec}", s) for s in FRESH_SEEDS]
            if LAB_DTT or DTT_ON
            else []
        ),
        tri_runs=(
            [FILES.fresh_seed_tri_run("{spec}", s) for s in FRESH_SEEDS]
            if LAB_TRI
            else []
        ),
        seed_runs=FILES.fresh_seed_runs("{spec}"),
    log:
        FILES.log("fresh_seeds", "{spec}"),
    priority: PRIORITY["fresh_seeds"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["loop_threads"]  # its seeds side by side
    resources:
        runtime=config["resources"]["dem_runtime_min"] * max(1, len(FRESH_SEEDS)),
        mem_mb=config["resources"]["dem_mem_mb"] * config["resources"]["loop_threads"],
    params:
        settings=settings("fresh_seeds"),
        argv=argv("fresh_seeds"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule fresh_seeds_table:
    input:
        cards=[FILES.verified_card(s) for s in SPECIMENS],
        seed_runs=[FILES.fresh_seed_runs(s) for s in SPECIMENS],
    output:
        beside(FILES.table(L.FRESH_SEEDS)),
        table=FILES.table(L.FRESH_SEEDS),
    log:
        FILES.log("fresh_seeds_table"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("fresh_seeds_table"),
        argv=argv("fresh_seeds_table"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


rule verification_tables:
    input:
        cards=[FILES.verified_card(s) for s in SPECIMENS],
        runs=[FILES.verification_run(s) for s in SPECIMENS],
        lab=config["lab"]["csv"],
    output:
        beside(FILES.table(L.TABLE5), FILES.table(L.TABLE6), FILES.figure(L.FIG6)),
        table5=FILES.table(L.TABLE5),
        table6=FILES.table(L.TABLE6),
        fig6=report(
            FILES.figure(L.FIG6),
            caption="../report/fig6.rst",
            category="Verification",
        ),
    log:
        FILES.log("verification_tables"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        argv=argv("verification_tables"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
