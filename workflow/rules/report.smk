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
        config=json.dumps(config),
    shell:
        "echo '{params.config}' > {output.config} && "
        "bpmcal report --outdir {params.out} --config {output.config} --out {params.out}/report > {log} 2>&1"
