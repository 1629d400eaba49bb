"""No config text is spliced into a shell command: every command of the DAG, printed by a
dry run, splits (as the shell would) into arguments that carry the config's paths and text
whole. The real runs are in test_smoke.py (hostile title, a space in outdir) and the
rejected values in test_smoke.py's config errors."""
import json
import shlex

import yaml
from support.repo import copy_workflow, run_snakemake

OUTDIR = "out dir/study, one"
TITLE = "x'; touch PWNED; echo '\" $(touch PWNED) `touch PWNED` && rm -rf ~"


def test_every_command_of_the_dag_quotes_config_text(tmp_path):
    wf = copy_workflow(tmp_path / "wf")
    (wf / "config" / "names.yaml").write_text(
        yaml.safe_dump({"outdir": OUTDIR, "study": {"name": TITLE}}))
    r = run_snakemake(wf, "-n", "-p", "--configfile", "config/smoke.yaml", "config/names.yaml",
                      timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    text = r.stdout + r.stderr
    commands = [ln.split("Shell command: ", 1)[1] for ln in text.splitlines()
                if "Shell command: " in ln and not ln.endswith("Shell command: None")]
    rules = {c.split()[1] for c in commands}
    assert {"design", "sample", "ucs", "gather", "screen", "regress", "calibrate", "verify", "scatter",
            "verification-tables", "sweep-plan", "sweep-analyse", "impact", "impact-analyse",
            "report"} <= rules, rules
    for c in commands:
        argv = shlex.split(c)  # what the shell passes to bpmcal
        assert argv[0] == "bpmcal"
        redirect = argv.index(">")
        assert argv[redirect + 1].startswith(OUTDIR + "/logs/"), c  # the log, whole
        text_args = {argv[i + 1] for i, a in enumerate(argv) if a == "--config-json"}
        for a in set(argv) - text_args:
            # a path under outdir is one argument, never split at its space or comma
            assert a == OUTDIR or a.startswith(OUTDIR + "/") or "out dir" not in a, (a, c)
        paths = [a for a in argv if a.startswith(OUTDIR)]
        assert paths, c
        if argv[1] == "report":
            cfg = json.loads(argv[argv.index("--config-json") + 1])
            assert cfg["study"]["name"] == TITLE and cfg["outdir"] == OUTDIR
    assert not list(tmp_path.rglob("PWNED*"))
    assert not (wf / "out dir").exists()  # a dry run writes nothing
