# The posterior of every verified card (bpmcal posterior): what its lab targets pin and
# leave free, each parameter's interval, reach, the untargeted predictions' spread; the
# surrogate learns from the design, the closed loop's seed runs and the fresh seeds.


rule posterior:
    input:
        card=FILES.verified_card("{spec}"),
        dataset=FILES.dataset,
        models=FILES.models,
        loop=FILES.verification_seeds("{spec}"),
        fresh=FILES.fresh_seed_runs("{spec}") if FRESH_SEEDS_ON else [],
    output:
        beside(
            FILES.posterior_table("{spec}"),
            FILES.posterior_predictions("{spec}"),
            FILES.posterior_pairs("{spec}"),
            FILES.posterior_refine("{spec}"),
            FILES.posterior_draws("{spec}"),
        ),
        card=FILES.posterior_card("{spec}"),
        table=FILES.posterior_table("{spec}"),
        predictions=FILES.posterior_predictions("{spec}"),
        netcdf=FILES.posterior_netcdf("{spec}"),
        figure=FILES.posterior_pairs("{spec}"),
        refine=FILES.posterior_refine("{spec}"),
        draws=FILES.posterior_draws("{spec}"),
        learning=(
            [
                FILES.posterior_learning("{spec}"),
                *beside(FILES.posterior_learning("{spec}")),
                FILES.posterior_learning_figure("{spec}"),
                *beside(FILES.posterior_learning_figure("{spec}")),
            ]
            if POSTERIOR_CURVE
            else []
        ),
    log:
        FILES.log("posterior", "{spec}"),
    priority: PRIORITY["posterior"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["loop_threads"]  # refinement seeds side by side
    resources:
        runtime=config["resources"]["dem_runtime_min"]
        * (1 + config["posterior"]["refine"]["max_runs"]),
        mem_mb=config["resources"]["dem_mem_mb"] * config["resources"]["loop_threads"],
    params:
        p={
            k: config["posterior"][k]
            for k in (
                "surrogate",
                "seed",
                "hdi_prob",
                "rhat_max",
                "ess_min",
                "max_steps",
            )
        },
        r=config["posterior"]["refine"],
        n_draws=config["posterior"]["predictive"]["draws"],
        fresh=lambda wc, input: ["--fresh-seeds", input.fresh] if input.fresh else [],
        learning=lambda wc, output: (
            [
                "--learning",
                FILES.posterior_learning(wc.spec),
                "--learning-figure",
                FILES.posterior_learning_figure(wc.spec),
            ]
            if output.learning
            else []
        ),
        opts=specimen_args(),
        bts=bts_args() if LAB_BTS else [],
        dtt=dtt_args() if LAB_DTT else [],
        tri=tri_args() if LAB_TRI or TRI_ON else [],
    shell:
        "bpmcal posterior --card {input.card:q} --dataset {input.dataset:q} "
        "--models {input.models:q} --loop-seeds {input.loop:q} {params.fresh:q} "
        "--out-card {output.card:q} --table {output.table:q} "
        "--predictions {output.predictions:q} --netcdf {output.netcdf:q} "
        "--figure {output.figure:q} --refine-runs {output.refine:q} "
        "--draws {output.draws:q} --n-draws {params.n_draws:q} {params.learning:q} "
        "--surrogate {params.p[surrogate]:q} --posterior-seed {params.p[seed]:q} "
        "--hdi-prob {params.p[hdi_prob]:q} --rhat-max {params.p[rhat_max]:q} "
        "--ess-min {params.p[ess_min]:q} --sampler-max-steps {params.p[max_steps]:q} "
        "--refine-max-runs {params.r[max_runs]:q} --refine-ratio {params.r[ratio]:q} "
        "--refine-seeds {params.r[seeds]:q} --refine-seed {params.r[seed]:q} "
        "--threads {threads} {params.opts:q} {params.bts:q} {params.dtt:q} {params.tri:q} "
        "> {log:q} 2>&1"


rule posterior_predictive:
    input:
        draws=FILES.posterior_draws("{spec}"),
        envelopes=FILES.table(L.TRIAXIAL_ENVELOPES) if _PRED_ENV else [],
        # the card's own reference impact (the impact's card, when it is the verified one)
        card_impact=lambda wc: (
            FILES.impact_run(IMPACT_V0)
            if _PRED_IMPACT and wc.spec == IMPACT_SPEC and not TRANSFER_ON
            else []
        ),
    output:
        beside(FILES.posterior_predictive("{spec}")),
        table=FILES.posterior_predictive("{spec}"),
        tri=_PRED_TRI,
        impact=_PRED_IMP,
    log:
        FILES.log("posterior_predictive", "{spec}"),
    priority: PRIORITY["posterior_predictive"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["loop_threads"]  # draws side by side
    resources:
        runtime=config["resources"]["dem_runtime_min"]
        * max(1, _PRED_N)
        * (len(_PRED_S3) + 2 * _PRED_IMPACT),
        mem_mb=config["resources"]["dem_mem_mb"] * config["resources"]["loop_threads"],
    params:
        # what the job runs, as plain values (the params trigger compares them: impact
        # off leaves fewer outputs, which alone would rerun nothing)
        plan={"draws": _PRED_N, "sigma3": _PRED_S3, "impact": _PRED_IMPACT},
        sigma3=",".join(f"{x:g}" for x in _PRED_S3),
        t={k: config["triaxial"][k] for k in ("seed", "servo_alpha")},
        i={
            k: config["impact"][k]
            for k in (
                "scale",
                "velocity",
                "hammer_mass_kg",
                "dp_ratio",
                "anvil_fric",
                "duration_ms",
                "record_us",
                "seed",
            )
        },
        impact=lambda wc, output: (
            ["--impact-runs", *output.impact] if output.impact else []
        ),
        env=lambda wc, input: (
            ["--envelopes", input.envelopes] if input.envelopes else []
        ),
        card_impact=lambda wc, input: (
            ["--card-impact", input.card_impact] if input.card_impact else []
        ),
        opts=specimen_args(ucs=False),
    shell:
        "bpmcal predictive --draws {input.draws:q} --specimen {wildcards.spec:q} "
        "--table {output.table:q} --sigma3 {params.sigma3:q} --tri-runs {output.tri:q} "
        "{params.impact:q} {params.env:q} {params.card_impact:q} "
        "--triaxial-seed {params.t[seed]:q} --servo-alpha {params.t[servo_alpha]:q} "
        "--impact-seed {params.i[seed]:q} --impact-scale {params.i[scale]:q} "
        "--velocity {params.i[velocity]:q} --hammer-mass {params.i[hammer_mass_kg]:q} "
        "--dp-ratio {params.i[dp_ratio]:q} --anvil-fric {params.i[anvil_fric]:q} "
        "--duration-ms {params.i[duration_ms]:q} --record-us {params.i[record_us]:q} "
        "--threads {threads} {params.opts:q} > {log:q} 2>&1"
