"""``bpmcal`` loads only what the command it runs needs (the promise of ``bpmcal.cli``'s
module doc): importing the command and setting up a DEM job (``bpmcal sample``, 150 per
study: its parser, its settings and the stage that runs it) loads no xgboost, statsmodels
or matplotlib, and importing ``bpmcal.cli`` alone loads neither pandas nor the engine.
Checked in a fresh interpreter through ``sys.modules``."""
import json
import subprocess
import sys

#: the analysis and plotting libraries a DEM job must not pay for
HEAVY = ("xgboost", "statsmodels", "matplotlib", "sklearn", "shap")

PROBE = """
import contextlib, io, json, sys

def loaded(names):
    return sorted(n for n in names if n in sys.modules)

WATCH = {watch!r}
import bpmcal.cli as cli
out = {{"import": loaded(WATCH)}}
with contextlib.redirect_stdout(io.StringIO()) as text:
    rc = cli.main(["sample", "--help"])
assert rc == 0 and "--bts-out" in text.getvalue(), rc
args = cli.build_parser(only="sample").parse_args(["sample", "--params", "p.yaml", "--out",
                                                   "o.h5", "--bts-out", "b.h5", "--dtt-out",
                                                   "d.h5"])
cli.run_geometry(args), cli.run_settings(args)
cli.bts_disc_of(args, "bts_"), cli.bts_settings_of(args, "bts_")
cli.dtt_cylinder_of(args, "dtt_"), cli.dtt_settings_of(args, "dtt_")
out["parser"] = loaded(WATCH)
import bpmcal.stages.runs  # what cmd_sample imports to run the tests
{extra}
out["job"] = loaded(WATCH)
print(json.dumps(out))
"""


def probe(extra: str = "") -> dict:
    """The watched modules loaded at each step of a ``bpmcal sample`` set-up, in a fresh
    interpreter (``extra``: a statement run before the last step)."""
    watch = HEAVY + ("pandas", "numba")
    r = subprocess.run([sys.executable, "-c", PROBE.format(watch=watch, extra=extra)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_a_dem_job_loads_no_analysis_or_plotting_library():
    out = probe()
    assert out["import"] == [], "import bpmcal.cli loads " + ", ".join(out["import"])
    assert not set(out["parser"]) & {*HEAVY, "pandas"}, out["parser"]
    assert not set(out["job"]) & set(HEAVY), out["job"]
    assert "numba" in out["job"]  # the probe did reach the engine


def test_the_probe_can_fail():
    """A set-up that imports a plotting library is seen."""
    out = probe("import matplotlib")
    assert "matplotlib" in out["job"] and "matplotlib" not in out["parser"]
