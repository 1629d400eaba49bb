# Dataset -> screening (Table 3) -> stepwise regression (Table 4) -> calibration to the
# lab specimens -> closed-loop DEM verification (Tables 5, 6, Fig. 6).

SCREEN = f"{OUT}/screening"
REGR = f"{OUT}/regression"
CALIB = f"{OUT}/calibration"
CALIB0 = f"{OUT}/calibration_initial"
VERIF = f"{OUT}/verification"
TABLES = f"{OUT}/tables"
FIGS = f"{OUT}/figures"


rule screen:
    input:
        DATASET,
    output:
        selected=f"{SCREEN}/selected.json",
        table3=f"{TABLES}/table3_importance.csv",
        table3_md=f"{TABLES}/table3_importance.md",
        fig=report(f"{FIGS}/screening_importance.png", caption="../report/screening.rst",
                   category="Calibration"),
    log:
        f"{LOGS}/screen.log",
    params:
        figs=parent_of("fig"),
        screen=parent_of("selected"),
        tables=parent_of("table3"),
        s=config["screening"],
    shell:
        "bpmcal screen --dataset {input} --out {params.screen} --tables {params.tables} --figures {params.figs} "
        "--threshold {params.s[threshold_pct]} --importance {params.s[importance]} "
        "--splits {params.s[n_splits]} --repeats {params.s[n_repeats]} "
        "--seed {params.s[seed]} > {log} 2>&1"


rule regress:
    input:
        dataset=DATASET,
        selected=f"{SCREEN}/selected.json",
    output:
        models=f"{REGR}/models.json",
        table4=f"{TABLES}/table4_terms.csv",
        equations=f"{REGR}/equations.md",
        fig=report(f"{FIGS}/regression_fit.png", caption="../report/regression.rst",
                   category="Calibration"),
    log:
        f"{LOGS}/regress.log",
    params:
        figs=parent_of("fig"),
        regr=parent_of("models"),
        tables=parent_of("table4"),
        r=config["regression"],
    shell:
        "bpmcal regress --dataset {input.dataset} --selected {input.selected} --out {params.regr} "
        "--tables {params.tables} --figures {params.figs} --alpha-in {params.r[alpha_in]} "
        "--alpha-out {params.r[alpha_out]} --vif-max {params.r[vif_max]} "
        "--hierarchy {params.r[hierarchy]} --cv-folds {params.r[cv_folds]} "
        "--cv-repeats {params.r[cv_repeats]} --seed {params.r[seed]} > {log} 2>&1"


rule calibrate_initial:
    input:
        dataset=DATASET,
        models=f"{REGR}/models.json",
        lab=config["lab"]["csv"],
    output:
        cards=expand(f"{CALIB0}/{{spec}}.yaml", spec=SPECIMENS),
    log:
        f"{LOGS}/calibrate_initial.log",
    params:
        calib0=parent_of("cards"),
        c=config["calibration"],
        fixed=json.dumps(config["calibration"]["fixed"]),
        free=",".join(config["calibration"]["free"]),
        ranges=json.dumps(config["ranges"]),
        bounds=json.dumps(config["calibration"]["bounds"]),
    shell:
        "bpmcal calibrate --dataset {input.dataset} --models {input.models} --lab {input.lab} "
        "--out {params.calib0} --fixed '{params.fixed}' --free {params.free} "
        "--ranges {params.ranges:q} --bounds {params.bounds:q} "
        "--ratio {params.c[ratio]} --n-boot 0 --seed {params.c[seed]} > {log} 2>&1"


rule calibrate:
    input:
        dataset=DATASET,
        models=f"{REGR}/models.json",
        lab=config["lab"]["csv"],
        chosen=SWEEP_CHOSEN if config["ratio_sweep"]["enabled"] else [],
    output:
        cards=expand(f"{CALIB}/{{spec}}.yaml", spec=SPECIMENS),
        table=f"{TABLES}/calibration.csv",
    log:
        f"{LOGS}/calibrate.log",
    params:
        calib=parent_of("cards"),
        tables=parent_of("table"),
        c=config["calibration"],
        fixed=json.dumps(config["calibration"]["fixed"]),
        free=",".join(config["calibration"]["free"]),
        ratio=(lambda wc, input: f"--ratio-from {input.chosen}" if input.chosen
               else f"--ratio {config['calibration']['ratio']}"),
        ranges=json.dumps(config["ranges"]),
        bounds=json.dumps(config["calibration"]["bounds"]),
    shell:
        "bpmcal calibrate --dataset {input.dataset} --models {input.models} --lab {input.lab} "
        "--out {params.calib} --tables {params.tables} --fixed '{params.fixed}' --free {params.free} "
        "--ranges {params.ranges:q} --bounds {params.bounds:q} "
        "{params.ratio} --n-boot {params.c[n_boot]} --seed {params.c[seed]} > {log} 2>&1"


rule verify:
    input:
        card=f"{CALIB}/{{spec}}.yaml",
        models=f"{REGR}/models.json",
    output:
        card=f"{VERIF}/{{spec}}/card.yaml",
        rounds=f"{VERIF}/{{spec}}/rounds.csv",
    log:
        f"{LOGS}/verify/{{spec}}.log",
    threads: config["resources"]["ucs_threads"]
    resources:
        runtime=config["resources"]["ucs_runtime_min"] * config["verification"]["max_rounds"],
        mem_mb=config["resources"]["ucs_mem_mb"],
    params:
        verif=parent_of("card", up=2),
        v=config["verification"],
        opts=specimen_args(),
        unreachable="--from-unreachable" if config["verification"]["from_unreachable"] else "",
    shell:
        "bpmcal verify --card {input.card} --models {input.models} --out {params.verif}/{wildcards.spec} "
        "--seed {params.v[seed]} --rtol {params.v[rtol]} --max-rounds {params.v[max_rounds]} "
        "{params.unreachable} --threads {threads} {params.opts} > {log} 2>&1"


rule seed_scatter:
    input:
        card=f"{CALIB}/{SPECIMENS[0]}.yaml",
    output:
        f"{VERIF}/seed_scatter/seed_scatter.csv",
    log:
        f"{LOGS}/seed_scatter.log",
    threads: config["resources"]["ucs_threads"]
    resources:
        runtime=config["resources"]["ucs_runtime_min"] * len(config["verification"]["scatter_seeds"]),
        mem_mb=config["resources"]["ucs_mem_mb"],
    params:
        verif=parent_of(0, up=2),
        seeds=",".join(str(s) for s in config["verification"]["scatter_seeds"]),
        rtol=config["verification"]["rtol"],
        opts=specimen_args(),
    shell:
        "bpmcal scatter --card {input.card} --out {params.verif}/seed_scatter --seeds {params.seeds} "
        "--rtol {params.rtol} --threads {threads} {params.opts} > {log} 2>&1"


rule verification_tables:
    input:
        cards=expand(f"{VERIF}/{{spec}}/card.yaml", spec=SPECIMENS),
        lab=config["lab"]["csv"],
    output:
        table5=f"{TABLES}/table5_verification.csv",
        table6=f"{TABLES}/table6_prepeak_energy.csv",
        fig6=report(f"{FIGS}/fig6_stress_strain.png", caption="../report/fig6.rst",
                    category="Verification"),
    log:
        f"{LOGS}/verification_tables.log",
    params:
        figs=parent_of("fig6"),
        tables=parent_of("table5"),
    shell:
        "bpmcal verification-tables --cards {input.cards} --lab {input.lab} --tables {params.tables} "
        "--figures {params.figs} > {log} 2>&1"
