# Triaxial tests of the cards (one job per card and confining stress) and their strength
# envelopes (Mohr-Coulomb c, phi; Hoek-Brown mi), with the lab triaxial points if given.


rule triaxial:
    input:
        card=lambda wc: FILES.triaxial_card(wc.kind, wc.spec),
    output:
        run=FILES.triaxial_run("{kind}", "{spec}", "{s3}"),
    log:
        FILES.log("triaxial", "{kind}", "{spec}", "{s3}"),
    wildcard_constraints:
        kind="calibrated|verified",
        s3=r"[0-9.e+]+",
    priority: PRIORITY["triaxial"]
    conda:
        "../envs/bpmcal.yaml"
    threads: config["resources"]["dem_threads"]
    resources:
        runtime=config["resources"]["dem_runtime_min"],
        mem_mb=config["resources"]["dem_mem_mb"],
    params:
        settings=settings("triaxial"),
        argv=argv("triaxial"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"


_TX_CARDS = [FILES.triaxial_card(k, s) for k in TRIAX_KINDS for s in SPECIMENS]
_TX_RUNS = [
    FILES.triaxial_run(k, s, t)
    for k in TRIAX_KINDS
    for s in SPECIMENS
    for t in TRIAX_TAGS
]


rule triaxial_envelopes:
    input:
        cards=_TX_CARDS,
        runs=_TX_RUNS,
        lab=config["lab"]["csv"],
        lab_triaxial=TRIAX_LAB if TRIAX_LAB else [],
    output:
        beside(*FILES.triaxial_tables(bool(TRIAX_LAB)), FILES.figure(L.FIG_ENVELOPES)),
        table=FILES.table(L.TRIAXIAL_ENVELOPES),
        points=FILES.table(L.TRIAXIAL_POINTS),
        lab_table=FILES.table(L.TRIAXIAL_LAB) if TRIAX_LAB else [],
        fig=report(
            FILES.figure(L.FIG_ENVELOPES),
            caption="../report/envelopes.rst",
            category="Verification",
        ),
    log:
        FILES.log("triaxial_envelopes"),
    conda:
        "../envs/bpmcal.yaml"
    params:
        settings=settings("triaxial_envelopes"),
        argv=argv("triaxial_envelopes"),
    shell:
        "bpmcal {params.argv:q} > {log:q} 2>&1"
