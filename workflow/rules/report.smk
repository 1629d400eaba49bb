# The report: every table and figure next to the paper's published values.


rule report:
    input:
        tables=[rules.screen.output.table3, rules.regress.output.table4,
                rules.calibrate.output.table, rules.verification_tables.output.table5,
                rules.verification_tables.output.table6, rules.impact_analyse.output.energy,
                rules.impact_analyse.output.t10,
                rules.sweep_analyse.output.table if config["ratio_sweep"]["enabled"] else []],
        scatter=rules.seed_scatter.output,
    output:
        index=f"{OUT}/report/index.md",
        config=f"{OUT}/report/config.json",
    log:
        f"{LOGS}/report.log",
    params:
        out=parent_of("index", up=2),
        report=parent_of("index"),
        config=json.dumps(config),  # JSON text, shell-quoted below; never echoed
    shell:
        "bpmcal report --outdir {params.out:q} --config-json {params.config:q} "
        "--config-out {output.config:q} --out {params.report:q} > {log:q} 2>&1"
