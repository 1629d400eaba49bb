"""Every key of the config's specimen, compression and bts sections reaches the DEM jobs that use
it (the sample job ``bpmcal sample`` with its Brazilian test, verify, transfer): the commands
of a dry run are parsed by the ``bpmcal`` parser itself and each option's value is
compared with the config. (A Brazilian option the rule forgot to pass runs the
study's discs at the command's default, silently: the approach speed and post-peak stop of
the default study once did.)"""
import shlex

import pytest
import yaml
from support.repo import copy_workflow, run_snakemake

from bpmcal.cli import build_parser

pytestmark = pytest.mark.slow  # a Snakemake dry run of the smoke study with every key set

#: a value for every key, unlike every default and every shipped config
OVERLAY = {
    "specimen": {"diameter_mm": 51.5, "height_mm": 101.5, "sigma0_MPa": 0.137,
                 "genesis": "bpmcal", "install_gap_mm": 0.0371, "relax_ratio": 0.0137},
    "compression": {"platen_velocity": 0.173, "damping": 0.613, "stop_drop": 0.713,
                    "max_strain": 0.0313, "platen_fric": 0.0137, "record_strain": 2.37e-5,
                    "end_cap": 1.37, "end_cap_factor": 137.0, "approach_velocity": 0.237,
                    "approach_ramp": 3.7, "density_scaling": 0.437},
    "bts": {"enabled": True, "diameter_mm": 71.3, "thickness_mm": 36.7, "scale": 0.437,
            "loading": "jaws", "jaw_ratio": 1.37, "contact_cap": 1.37,
            "contact_cap_factor": 137.0, "central_zone": 0.437, "retests": 7,
            "platen_velocity": 0.0237, "approach_velocity": 0.137, "approach_damage": 0.0037,
            "stop_drop": 0.237,
            "post_peak_strain": 0.000437, "platen_fric": 0.337, "damping": 0.637,
            "max_strain": 0.0437, "record_strain": 1.37e-5, "min_balls_across": 13.7,
            "density_scaling": 0.337},
    "transfer": {"enabled": True},
    "verification": {"range_margin": 0.137, "polish": False, "jacobian_update": "history",
                     "grow_within": 1.37,
                     "tensile_specimens": 3, "tensile_seed_cv": 0.037,
                     "max_tensile_specimens": 13},
    # a lab with a sigma_t target: the closed loops run Brazilian tests too (without one
    # they get no --bts-* options, so that a bts key does not rerun them)
    "lab": {"csv": "config/lab/lac_du_bonnet.csv"},
    "study": {"reference": "none"},
}
#: config key -> option destination where the names differ
DEST = {"diameter_mm": "diameter", "height_mm": "height", "thickness_mm": "thickness",
        "sigma0_MPa": "sigma0", "install_gap_mm": "install_gap", "scale": "scale"}


@pytest.fixture(scope="module")
def commands(tmp_path_factory):
    wf = copy_workflow(tmp_path_factory.mktemp("wf"))
    (wf / "config" / "keys.yaml").write_text(yaml.safe_dump(OVERLAY))
    r = run_snakemake(wf, "-n", "-p", "--configfile", "config/smoke.yaml", "config/keys.yaml",
                      timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    out = {}
    for ln in (r.stdout + r.stderr).splitlines():
        if "Shell command: " not in ln or ln.endswith("Shell command: None"):
            continue
        argv = shlex.split(ln.split("Shell command: ", 1)[1])
        argv = argv[:argv.index(">")]
        cmd = argv[1]
        out.setdefault(cmd, build_parser(only=cmd).parse_args(argv[1:]))
    return out


def _expect(a, section, keys, prefix=""):
    for k in keys:
        dest = prefix + DEST.get(k, k)
        assert hasattr(a, dest), f"{a.cmd} has no option for {section}.{k}"
        want = OVERLAY[section][k]
        got = getattr(a, dest)
        assert got == want, f"{section}.{k} = {want!r} reaches `bpmcal {a.cmd}` as {got!r}"


def test_the_sample_job_gets_every_specimen_and_compression_key(commands):
    a = commands["sample"]
    _expect(a, "specimen", OVERLAY["specimen"])
    _expect(a, "compression", OVERLAY["compression"])


@pytest.mark.parametrize("cmd", ["sample", "verify", "transfer"])
def test_every_brazilian_test_runs_with_the_studys_bts_section(commands, cmd):
    """The sample job's Brazilian test (``bpmcal sample --bts-out``, its disc with the
    cylinder's genesis options) and the closed loops' (a card with a σt target)."""
    a = commands[cmd]
    if cmd == "sample":
        assert a.bts_out is not None and a.bts_out.endswith(".h5")
    _expect(a, "bts", [k for k in OVERLAY["bts"] if k != "enabled"], prefix="bts_")
    _expect(a, "specimen", OVERLAY["specimen"])
    _expect(a, "compression", OVERLAY["compression"])


@pytest.mark.parametrize("cmd", ["verify", "transfer"])
def test_both_closed_loops_search_the_same_widened_box(commands, cmd):
    """The transfer starts from a verified card that may lie past a design range: it must
    be allowed the same margin, or its first round would be refused."""
    _expect(commands[cmd], "verification", ["range_margin"])


def test_the_verification_gets_its_polish_switch(commands):
    _expect(commands["verify"], "verification", ["polish"])


def test_the_verification_gets_its_seed_growth_factor(commands):
    _expect(commands["verify"], "verification", ["grow_within"])


def test_the_closed_loop_gets_its_tensile_specimen_count(commands):
    # the transfer and the fresh-seed check read it from the verified card
    _expect(commands["verify"], "verification", ["tensile_specimens"])


def test_the_closed_loop_of_a_tensile_target_gets_its_seed_cv_and_cap(commands):
    # the count adapts to the card's specimen scatter (a lab with σt: the overlay's)
    _expect(commands["verify"], "verification", ["tensile_seed_cv", "max_tensile_specimens"])


@pytest.mark.parametrize("cmd", ["verify", "transfer"])
def test_both_closed_loops_get_the_jacobian_update_rule(commands, cmd):
    _expect(commands[cmd], "verification", ["jacobian_update"])


def test_the_closed_loop_of_a_triaxial_target_gets_its_seed_cap(tmp_path):
    """verification.triaxial_seeds reaches `bpmcal verify` when σ1 is a target (the
    flat-joint Lac du Bonnet study with its triaxial overlay); without one it is no option
    (the smoke study's verify command above has none)."""
    wf = copy_workflow(tmp_path)
    (wf / "config" / "cap.yaml").write_text(yaml.safe_dump(
        {"verification": {"triaxial_seeds": 7, "max_seeds": 13}}))
    r = run_snakemake(wf, "-n", "-p", "--configfile", "config/examples/lac_du_bonnet_fj.yaml",
                      "config/examples/lac_du_bonnet_fj_triaxial.yaml", "config/cap.yaml",
                      timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    verify = [shlex.split(ln.split("Shell command: ", 1)[1]) for ln in
              (r.stdout + r.stderr).splitlines() if "Shell command: bpmcal verify" in ln]
    assert verify
    for argv in verify:
        a = build_parser(only="verify").parse_args(argv[1:argv.index(">")])
        assert a.triaxial_seeds == 7 and a.max_seeds == 13


def test_no_triaxial_target_no_seed_cap(commands):
    assert commands["verify"].triaxial_seeds is None
