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
            *(
                (
                    FILES.posterior_learning("{spec}"),
                    FILES.posterior_learning_figure("{spec}"),
                )
                if POSTERIOR_CURVE
                else []
            ),
        ),
        card=FILES.posterior_card("{spec}"),
        table=FILES.posterior_table("{spec}"),
        predictions=FILES.posterior_predictions("{spec}"),
        netcdf=FILES.posterior_netcdf("{spec}"),
        figure=FILES.posterior_pairs("{spec}"),
        refine=FILES.posterior_refine("{spec}"),
        draws=FILES.posterior_draws("{spec}"),
        learning=FILES.posterior_learning("{spec}") if POSTERIOR_CURVE else [],
        learning_figure=(
            FILES.posterior_learning_figure("{spec}") if POSTERIOR_CURVE else []
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
        settings=settings("posterior"),
        argv=argv("posterior"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


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
        settings=settings("posterior_predictive"),
        argv=argv("posterior_predictive"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
