# The report: every table and figure next to the paper's published values. It reads the
# study's files through bpmcal.io.study_files (the files declared here) and writes its own.

_POSTERIOR_FILES = (
    FILES.posterior_report_files(SPECIMENS, POSTERIOR_CURVE, PREDICTIVE_SPECS)
    if POSTERIOR_ON
    else []
)
_REPORT_OUT = FILES.report_outputs(
    SWEEP_ON, REFERENCE, TRIAX_ON, bool(TRIAX_LAB), FRESH_SEEDS_ON, _POSTERIOR_FILES
)


rule report:
    input:
        **FILES.report_inputs(
            SPECIMENS,
            IMPACT_V0,
            SWEEP_ON,
            TRIAX_ON,
            bool(TRIAX_LAB),
            FRESH_SEEDS_ON,
            _POSTERIOR_FILES,
        ),
        # σt at the lab's disc size (workflow/rules/bts_size.smk; none: no lab diameter)
        bts_size=[
            f
            for s in BTS_SIZE_SPECS
            for f in (FILES.bts_size_sizes(s), FILES.bts_size_fit(s))
        ],
    output:
        [f for f in _REPORT_OUT if f not in (FILES.report_index, FILES.report_config)],
        index=FILES.report_index,
        config=FILES.report_config,
    log:
        FILES.log("report"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        # the config as JSON text (shell-quoted in argv; never echoed)
        settings=settings("report"),
        argv=argv("report"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
