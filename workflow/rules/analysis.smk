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
        "bpmcal screen --dataset {input:q} --out {params.screen:q} --tables {params.tables:q} "
        "--figures {params.figs:q} --threshold {params.s[threshold_pct]:q} "
        "--importance {params.s[importance]:q} --splits {params.s[n_splits]:q} "
        "--repeats {params.s[n_repeats]:q} --seed {params.s[seed]:q} > {log:q} 2>&1"


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
        "bpmcal regress --dataset {input.dataset:q} --selected {input.selected:q} "
        "--out {params.regr:q} --tables {params.tables:q} --figures {params.figs:q} "
        "--alpha-in {params.r[alpha_in]:q} --alpha-out {params.r[alpha_out]:q} "
        "--vif-max {params.r[vif_max]:q} --hierarchy {params.r[hierarchy]:q} "
        "--cv-folds {params.r[cv_folds]:q} --cv-repeats {params.r[cv_repeats]:q} "
        "--seed {params.r[seed]:q} > {log:q} 2>&1"


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
        "bpmcal calibrate --dataset {input.dataset:q} --models {input.models:q} "
        "--lab {input.lab:q} --out {params.calib0:q} --fixed {params.fixed:q} "
        "--free {params.free:q} --ranges {params.ranges:q} --bounds {params.bounds:q} "
        "--ratio {params.c[ratio]:q} --n-boot 0 --seed {params.c[seed]:q} > {log:q} 2>&1"


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
        ratio_from=lambda wc, input: ["--ratio-from", input.chosen] if input.chosen else [],
        ranges=json.dumps(config["ranges"]),
        bounds=json.dumps(config["calibration"]["bounds"]),
    shell:
        "bpmcal calibrate --dataset {input.dataset:q} --models {input.models:q} "
        "--lab {input.lab:q} --out {params.calib:q} --tables {params.tables:q} "
        "--fixed {params.fixed:q} --free {params.free:q} --ranges {params.ranges:q} "
        "--bounds {params.bounds:q} --ratio {params.c[ratio]:q} "
        "{params.ratio_from:q} --n-boot {params.c[n_boot]:q} --seed {params.c[seed]:q} "
        "> {log:q} 2>&1"


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
        verif=parent_of("card"),
        v=config["verification"],
        opts=specimen_args(),
        unreachable=["--from-unreachable"] if config["verification"]["from_unreachable"] else [],
    shell:
        "bpmcal verify --card {input.card:q} --models {input.models:q} --out {params.verif:q} "
        "--seed {params.v[seed]:q} --rtol {params.v[rtol]:q} "
        "--max-rounds {params.v[max_rounds]:q} {params.unreachable:q} --threads {threads} "
        "{params.opts:q} > {log:q} 2>&1"


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
        scatter=parent_of(0),
        seeds=",".join(str(s) for s in config["verification"]["scatter_seeds"]),
        rtol=config["verification"]["rtol"],
        opts=specimen_args(),
    shell:
        "bpmcal scatter --card {input.card:q} --out {params.scatter:q} --seeds {params.seeds:q} "
        "--rtol {params.rtol:q} --threads {threads} {params.opts:q} > {log:q} 2>&1"


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
        "bpmcal verification-tables --cards {input.cards:q} --lab {input.lab:q} "
        "--tables {params.tables:q} --figures {params.figs:q} > {log:q} 2>&1"
