# Dataset -> screening (Table 3) -> stepwise regression (Table 4) -> calibration to the
# lab specimens -> closed-loop DEM verification (Tables 5, 6, Fig. 6).


rule screen:
    input:
        FILES.dataset,
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
        s=config["screening"],
    shell:
        "bpmcal screen --dataset {input:q} --selected {output.selected:q} "
        "--table3 {output.table3:q} --figure {output.fig:q} "
        "--importance-table {output.importance:q} --cv-table {output.cv:q} "
        "--shadow-table {output.shadow:q} --summary {output.summary:q} "
        "--threshold {params.s[threshold_pct]:q} --importance {params.s[importance]:q} "
        "--n-splits {params.s[n_splits]:q} --n-repeats {params.s[n_repeats]:q} "
        "--rule {params.s[rule]:q} --tensile-rule {params.s[tensile_rule]:q} "
        "--seed {params.s[seed]:q} > {log:q} 2>&1"


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
        r=config["regression"],
    shell:
        "bpmcal regress --dataset {input.dataset:q} --selected {input.selected:q} "
        "--models {output.models:q} --equations {output.equations:q} "
        "--summaries {output.summaries:q} --coefficients {output.coefficients:q} "
        "--candidates {output.candidates:q} --table4 {output.table4:q} "
        "--fit-table {output.fit:q} --figure {output.fig:q} "
        "--alpha-in {params.r[alpha_in]:q} --alpha-out {params.r[alpha_out]:q} "
        "--vif-max {params.r[vif_max]:q} --hierarchy {params.r[hierarchy]:q} "
        "--cv-folds {params.r[cv_folds]:q} --cv-repeats {params.r[cv_repeats]:q} "
        "--seed {params.r[seed]:q} > {log:q} 2>&1"


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
        # not n_boot: the initial calibration runs no bootstrap; c's keys are the options'
        # (--ratio), so that a study run before the key's rename does not rerun
        c={
            "ratio": config["calibration"]["strength_ratio"],
            "seed": config["calibration"]["seed"],
        },
        fixed=json.dumps(config["calibration"]["fixed"]),
        free=",".join(config["calibration"]["free"]),
        ranges=json.dumps(config["ranges"]),
        bounds=json.dumps(config["calibration"]["bounds"]),
    shell:
        "bpmcal calibrate --dataset {input.dataset:q} --models {input.models:q} "
        "--lab {input.lab:q} --cards {output.cards:q} --fixed {params.fixed:q} "
        "--free {params.free:q} --ranges {params.ranges:q} --bounds {params.bounds:q} "
        "--ratio {params.c[ratio]:q} --n-boot 0 --seed {params.c[seed]:q} > {log:q} 2>&1"


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
        # c's keys are the options' (--ratio): as in calibrate_initial
        c={
            "ratio": config["calibration"]["strength_ratio"],
            **{k: config["calibration"][k] for k in ("n_boot", "seed")},
        },
        fixed=json.dumps(config["calibration"]["fixed"]),
        free=",".join(config["calibration"]["free"]),
        ratio_from=lambda wc, input: (
            ["--ratio-from", input.chosen] if input.chosen else []
        ),
        ranges=json.dumps(config["ranges"]),
        bounds=json.dumps(config["calibration"]["bounds"]),
    shell:
        "bpmcal calibrate --dataset {input.dataset:q} --models {input.models:q} "
        "--lab {input.lab:q} --cards {output.cards:q} --table {output.table:q} "
        "--fixed {params.fixed:q} --free {params.free:q} --ranges {params.ranges:q} "
        "--bounds {params.bounds:q} --ratio {params.c[ratio]:q} "
        "{params.ratio_from:q} --n-boot {params.c[n_boot]:q} --seed {params.c[seed]:q} "
        "> {log:q} 2>&1"


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
        loop=loop_args(),
        opts=specimen_args(),
        bts=bts_args() if LAB_BTS else [],  # Brazilian tests only for a σt target
        dtt=dtt_args() if LAB_DTT else [],
        tri=tri_args() if LAB_TRI else [],
    shell:
        "bpmcal verify --card {input.card:q} --models {input.models:q} "
        "--out-card {output.card:q} --rounds {output.rounds:q} --run {output.run:q} "
        "--seed-runs {output.seeds:q} {params.loop:q} --threads {threads} "
        "{params.opts:q} {params.bts:q} {params.dtt:q} {params.tri:q} > {log:q} 2>&1"


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
        t={"max_rounds": config["transfer"]["max_rounds"]},
        # the first packing seed no closed loop may use (grown seed sets included)
        seed=transfer_seed(config["verification"]),
        rtol=config["verification"]["rtol"],
        margin=config["verification"]["range_margin"],
        jac=config["verification"]["jacobian_update"],
        opts=specimen_args(scale=config["transfer"]["scale"]),
        bts=bts_args() if LAB_BTS else [],  # Brazilian tests only for a σt target
        dtt=dtt_args() if LAB_DTT else [],
        tri=tri_args() if LAB_TRI else [],
    shell:
        "bpmcal transfer --card {input.card:q} --models {input.models:q} "
        "--out-card {output.card:q} --rounds {output.rounds:q} --run {output.run:q} "
        "--seed {params.seed:q} --rtol {params.rtol:q} --range-margin {params.margin:q} "
        "--jacobian-update {params.jac:q} --max-rounds {params.t[max_rounds]:q} "
        "--threads {threads} "
        "{params.opts:q} {params.bts:q} {params.dtt:q} {params.tri:q} > {log:q} 2>&1"


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
    shell:
        "bpmcal transfer-table --cards {input.cards:q} --table {output.table:q} "
        "> {log:q} 2>&1"


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
        seeds=",".join(str(s) for s in SCATTER_SEEDS),
        rtol=config["verification"]["rtol"],
        opts=specimen_args(),
    shell:
        "bpmcal scatter --card {input.card:q} --seeds {params.seeds:q} --runs {output.runs:q} "
        "--seed-runs {output.seed_runs:q} --table {output.table:q} --rtol {params.rtol:q} "
        "--threads {threads} {params.opts:q} > {log:q} 2>&1"


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
        dtt_runs=(
            [FILES.fresh_seed_dtt_run("{spec}", s) for s in FRESH_SEEDS]
            if LAB_DTT
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
        seeds=",".join(str(s) for s in FRESH_SEEDS),
        bts_runs=lambda wc, output: (
            ["--bts-runs", *output.bts_runs] if output.bts_runs else []
        ),
        dtt_runs=lambda wc, output: (
            ["--dtt-runs", *output.dtt_runs] if output.dtt_runs else []
        ),
        tri_runs=lambda wc, output: (
            ["--tri-runs", *output.tri_runs] if output.tri_runs else []
        ),
        opts=specimen_args(),
        bts=bts_args() if BTS_ON else [],  # every card's σt on the fresh seeds
        dtt=dtt_args() if LAB_DTT else [],
        tri=tri_args() if LAB_TRI else [],
    shell:
        "bpmcal fresh-seeds --card {input.card:q} --seeds {params.seeds:q} "
        "--runs {output.runs:q} {params.bts_runs:q} {params.dtt_runs:q} "
        "{params.tri_runs:q} --seed-runs {output.seed_runs:q} --threads {threads} "
        "{params.opts:q} {params.bts:q} {params.dtt:q} {params.tri:q} > {log:q} 2>&1"


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
        rtol=config["verification"]["rtol"],
    shell:
        "bpmcal fresh-seeds-table --cards {input.cards:q} "
        "--seed-runs {input.seed_runs:q} --table {output.table:q} --rtol {params.rtol:q} "
        "> {log:q} 2>&1"


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
    shell:
        "bpmcal verification-tables --cards {input.cards:q} --runs {input.runs:q} "
        "--lab {input.lab:q} --table5 {output.table5:q} --table6 {output.table6:q} "
        "--figure {output.fig6:q} > {log:q} 2>&1"
