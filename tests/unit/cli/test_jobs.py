"""bpmcal.cli.jobs: one builder of every study job's command, read by the workflow's rules
(each rule names its files and runs ``bpmcal {params.argv:q}``) and by the benchmarks.
(The dry-run commands of the study configs are compared with the rules' in
tests/workflow; here: every job's command is one the CLI parses, carries the config's
values, and is the only place the workflow maps config keys to options.)"""
import re

import pytest
import yaml
from support.repo import REPO, SCHEMA

from bpmcal.analysis.calibration.loop_settings import LoopSettings
from bpmcal.cli import build_parser
from bpmcal.cli.jobs import JOBS, _tokens, job_argv, job_options
from bpmcal.study.config import validate_config

RULES = REPO / "workflow" / "rules"


def _config(*names, **over):
    cfg = {}
    for n in names:
        cfg.update(yaml.safe_load((REPO / "config" / n).read_text()))
    for k, v in over.items():
        cfg[k] = {**cfg.get(k, {}), **v}
    validate_config(cfg, SCHEMA, base_dir=REPO, note=lambda line: None)
    return cfg


@pytest.fixture(scope="module")
def cfg():
    return _config("config.yaml")


def _files(cfg, job, targets=()):
    """A path for every file and wildcard the job's command names (a list where the
    option takes several)."""
    ns = {"input": {}, "output": {}, "wildcards": {}}
    for t in _tokens(cfg, job, targets, None):
        if not isinstance(t, str) and t.key:
            ns[t.source][t.key] = f"{t.source}_{t.key}"
    ns["wildcards"] = {k: "1.5" if k in ("v", "s3") else v for k, v in ns["wildcards"].items()}
    return ns


def _parse(argv):
    return build_parser(only=argv[0]).parse_args(argv)


def _rules():
    return {m for f in RULES.glob("*.smk")
            for m in re.findall(r"^rule (\w+):", f.read_text(), re.M)}


def test_every_rule_runs_the_command_of_its_job_and_nothing_else():
    """One source: every rule of the workflow (but `all`) is a job of JOBS, its shell is
    the job's argv, and no rule file maps a config key to an option by hand."""
    assert _rules() - {"all"} == set(JOBS)
    for f in RULES.glob("*.smk"):
        text = f.read_text()
        for rule, body in re.findall(r"^rule (\w+):\n(.*?)(?=^rule |\Z)", text, re.M | re.S):
            assert 'shell:\n        "bpmcal {params.argv:q} > {log:q} 2>&1"' in body, rule
            assert f'argv=argv("{rule}")' in body, rule
        assert not re.search(r'"--[a-z]', text), f"{f.name}: an option typed in a rule file"


@pytest.mark.parametrize("targets", [(), ("bts", "dtt", "tri")])
@pytest.mark.parametrize("job", sorted(JOBS))
def test_every_jobs_command_parses(cfg, job, targets, tmp_path):
    """The command of every job, with and without every lab target, is one ``bpmcal``
    accepts (an option the CLI lost, or a value it refuses, fails here, before a study)."""
    if "tri" in targets:
        cfg = _config("config.yaml", triaxial={"design_sigma3_MPa": 10.0})
    files = _files(cfg, job, targets)
    if job == "bts_size":  # a job only for a lab row with its own disc size
        lab = tmp_path / "lab.csv"
        lab.write_text("specimen,ucs_MPa,E_GPa,nu,bts_MPa,bts_diameter_mm\n"
                       "B1,60,14,0.25,8,50\n")
        cfg = {**cfg, "lab": {**cfg["lab"], "csv": str(lab)}}
        files["wildcards"]["spec"] = "B1"
    argv = job_argv(cfg, job, threads=2, targets=targets, **files)
    assert _parse(argv).cmd == argv[0]
    if job == "bts_size":
        assert argv[argv.index("--lab-diameter") + 1] == "50"


def test_the_disc_size_job_has_no_diameter_without_a_lab_row_that_gives_one(cfg):
    """No lab row with a diameter: the job has no command (and the rule no job)."""
    with pytest.raises(KeyError, match="wildcards spec"):
        job_argv(cfg, "bts_size", threads=2, **_files(cfg, "bts_size"))


def test_the_command_carries_the_configs_values():
    cfg = _config("config.yaml", verification={"max_rounds": 7, "grow_within": 1.5},
                  compression={"damping": 0.6}, bts={"stop_drop": 0.4})
    a = _parse(job_argv(cfg, "verify", threads=3, targets={"bts"}, **_files(cfg, "verify")))
    from bpmcal.cli.options import loop_settings_of

    assert loop_settings_of(a) == LoopSettings(**{
        k: v for k, v in cfg["verification"].items() if k not in ("scatter_seeds",
                                                                   "fresh_seeds")})
    assert (a.damping, a.bts_stop_drop, a.threads, a.scale) == (0.6, 0.4, 3, 0.4)
    plain = _parse(job_argv(cfg, "verify", targets=(), **_files(cfg, "verify")))
    assert plain.tensile_seed_cv == LoopSettings().tensile_seed_cv  # no σt target: not passed
    s = _parse(job_argv(cfg, "sample", threads=1, **_files(cfg, "sample")))
    assert s.bts_out == "output_bts" and s.bts_stop_drop == 0.4 and s.failed_ok


def test_the_settings_are_the_command_without_files_and_threads(cfg):
    """What a rule hands Snakemake's params trigger: every config value of the command,
    none of its files (a changed file name alone reruns nothing)."""
    for job in set(JOBS) - {"bts_size"}:  # its command needs a lab disc size (above)
        files = _files(cfg, job)
        argv = job_argv(cfg, job, threads=5, **files)
        opts = job_options(cfg, job)
        it = iter(argv)
        assert all(any(o == a for a in it) for o in opts), job  # a subsequence, in order
        names = {v for ns in files.values() for v in ns.values()}
        assert not names & set(opts), job
    changed = _config("config.yaml", screening={"seed": 99})
    assert job_options(changed, "screen") != job_options(cfg, "screen")
    assert job_options(changed, "regress") == job_options(cfg, "regress")


def test_a_missing_file_is_refused_and_an_optional_one_left_out(cfg):
    with pytest.raises(KeyError, match="--card"):
        job_argv(cfg, "verify", output={"card": "c", "rounds": "r", "run": "x"}, targets=())
    argv = job_argv(cfg, "verify", input={"card": "c", "models": "m"},
                    output={"card": "v", "rounds": "r", "run": "x"}, threads=1, targets=())
    assert "--seed-runs" not in argv and argv[:3] == ["verify", "--card", "c"]
    with pytest.raises(KeyError, match="job 'nope'"):
        job_options(cfg, "nope")
    with pytest.raises(ValueError, match=r"targets \['sigma'\]"):
        job_options(cfg, "verify", targets={"sigma"})


def test_fresh_seeds_carry_the_direct_tension_settings_when_the_study_runs_that_test():
    """dtt.enabled without a lab σt,d target: the fresh seeds measure the card's σt,d as a
    prediction, so their command carries the direct-tension settings; off, it does not."""
    on = _config("config.yaml", dtt={"enabled": True, "grip_velocity": 0.02})
    a = _parse(job_argv(on, "fresh_seeds", threads=1, targets=(),
                        **_files(on, "fresh_seeds")))
    assert a.dtt_runs == ["output_dtt_runs"] and a.dtt_grip_velocity == 0.02
    off = _config("config.yaml", dtt={"grip_velocity": 0.02})
    b = _parse(job_argv(off, "fresh_seeds", threads=1, targets=(),
                        output={k: v for k, v in _files(off, "fresh_seeds")["output"].items()
                                if k != "dtt_runs"},
                        input=_files(off, "fresh_seeds")["input"]))
    assert b.dtt_runs is None and "--dtt-grip-velocity" not in job_argv(
        off, "fresh_seeds", threads=1, targets=(), **_files(off, "fresh_seeds"))
