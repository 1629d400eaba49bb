"""Paired-result guards of the loading protocol of issue 53 (the ``new`` protocol of
docs/measurements/2026-12-02-loading-protocol.md): the UCS test's fast approach until the
first crack, ramped down over 5 wave transits, and the Brazilian test's approach until
0.6 % of the disc's bonds have broken (the default study's loading, config/config.yaml),
give the responses of the constant-velocity loading they replaced (the approach until the
first crack of the Brazilian test), on the same design samples and packings, in fewer steps.

The samples are three cheap ones of the default study's 150 (845-961 balls in the
cylinder, among the fewest; one valid disc each; s085, as cheap, is left out: its disc's
post-peak tail is longer under the new protocol, so it saves no Brazilian steps), each with its own
packing seed and the study's specimens and settings. The tolerances are the largest sizes
of the per-sample changes measured on the record's 150 samples, with room (σt: but one): a change
of the loading that moves a response systematically (a ramp that rings through the fit
window, an approach into the split) exceeds them."""
from dataclasses import replace

import numpy as np
import pytest
import yaml
from support.repo import REPO

from bpmcal.lab.brazilian import BTSSettings
from bpmcal.lab.runner import Geometry, bts_geometry, bts_test, ucs_test
from bpmcal.lab.ucs import UCSSettings
from bpmcal.study.config import validate_config
from bpmcal.study.design import lhs_design

pytestmark = pytest.mark.slow  # 3 samples x (2 UCS + 2 Brazilian tests): about a minute

#: three cheap design samples of the default study (module docstring)
SAMPLES = ("s106", "s029", "s089")
#: the record's new protocol: the settings it changes
NEW_UCS = {"approach_velocity": 0.1, "approach_ramp": 5.0}
NEW_BTS = {"approach_damage": 0.006}
#: per-sample tolerances [%] of the new loading against the old one (module docstring;
#: the record's largest sizes on 150 samples: 3.7, 1.0, 1.4 % and, for sigma_t on the same
#: disc, 10.4 % on one sample, s068, 2.2 % on every other)
TOL = {"ucs_MPa": 5.0, "E_GPa": 1.5, "nu": 2.0, "bts_MPa": 2.5}


@pytest.fixture(scope="module")
def study():
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    validate_config(cfg, REPO / "workflow" / "schemas" / "config.schema.yaml", base_dir=REPO)
    st = cfg["study"]
    design = lhs_design(cfg["ranges"], st["n_samples"], st["lhs_seed"],
                        optimization=st["lhs_optimization"])
    sp, c, b = cfg["specimen"], cfg["compression"], cfg["bts"]
    geo = Geometry(scale=sp["scale"], diameter_mm=sp["diameter_mm"], height_mm=sp["height_mm"],
                   sigma0_MPa=sp["sigma0_MPa"], relax_ratio=sp["relax_ratio"],
                   genesis=sp["genesis"], install_gap_mm=sp["install_gap_mm"])
    disc = bts_geometry(scale=b["scale"], diameter_mm=b["diameter_mm"],
                        thickness_mm=b["thickness_mm"], sigma0_MPa=sp["sigma0_MPa"],
                        relax_ratio=sp["relax_ratio"], genesis=sp["genesis"],
                        install_gap_mm=sp["install_gap_mm"])
    ucs = UCSSettings(**{k: v for k, v in c.items() if k in UCSSettings.__dataclass_fields__})
    bts = BTSSettings(**{k: v for k, v in b.items() if k in BTSSettings.__dataclass_fields__})
    return design, geo, disc, ucs, bts


def _sample(design, sid):
    row = design[design["sample_id"] == sid].iloc[0]
    params = {k: float(row[k]) for k in design.columns if k not in ("sample_id", "seed")}
    return params, int(row["seed"])


def _paired(test, params, seed, where, old, new, cache):
    """The summaries of one sample's test under the old and the new loading settings."""
    def run(settings):
        return test(params, seed, where, settings, cache=cache, threads=1,
                    keep_particles=False).summary
    return run(old), run(new)


def test_the_study_loads_with_the_new_protocol(study):
    """The guards compare the study's loading with the old one: the study's config uses the
    new settings (else they would compare a loading with itself)."""
    _, _, _, ucs, bts = study
    assert {k: getattr(ucs, k) for k in NEW_UCS} == NEW_UCS
    assert {k: getattr(bts, k) for k in NEW_BTS} == NEW_BTS
    assert ucs.approach_velocity > ucs.platen_velocity


@pytest.mark.parametrize("sid", SAMPLES)
def test_the_ucs_approach_keeps_sigma_c_E_and_nu(study, sid, cache):
    design, geo, _, ucs, _ = study
    params, seed = _sample(design, sid)
    old, new = _paired(ucs_test, params, seed, geo, replace(ucs, approach_velocity=0.0), ucs,
                       cache)
    assert new["steps"] < 0.92 * old["steps"]
    for k in ("ucs_MPa", "E_GPa", "nu"):
        assert new[k] == pytest.approx(old[k], rel=TOL[k] / 100), k


@pytest.mark.parametrize("sid", SAMPLES)
def test_the_brazilian_approach_keeps_sigma_t(study, sid, cache):
    design, _, disc, _, bts = study
    params, seed = _sample(design, sid)
    old, new = _paired(bts_test, params, seed, disc, replace(bts, approach_damage=0.0), bts,
                       cache)
    assert old["bts_valid"] and new["bts_valid"]
    assert new["disc_seed"] == old["disc_seed"]  # the same disc: the same specimen
    assert new["steps"] < 0.85 * old["steps"]
    assert new["bts_MPa"] == pytest.approx(old["bts_MPa"], rel=TOL["bts_MPa"] / 100)
    assert np.isfinite(new["approach_strain"]) and new["approach_strain"] > 0
