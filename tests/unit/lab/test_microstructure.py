"""The strength scatter, as PFC's material-modeling package draws it: per contact, a
Gaussian of the card's mean and standard deviation truncated at zero (a negative draw is
drawn again, fistPkg's ``ft_valNormDist``), from the packing seed.

- the draws have the truncated Gaussian's mean and standard deviation within their
  sampling error, nothing below zero, and sd = 0 gives the mean exactly, drawing nothing;
- on a specimen every bond (flat joint) has its own pair, independently, with the card's
  statistics; the same seed gives the same strengths, another seed others;
- sd = 0 is today's specimen bit for bit: a card without the keys, a card with sd 0 and a
  card whose contacts are given the means explicitly run the same UCS test to the last
  bit (the comparison with the commit before the scatter is a measurement record:
  docs/measurements/2026-12-02-strength-scatter.md);
- a negative or NaN sd is one line, exit 2, no output file (CLI), and a named config
  error.
"""
import math

import numpy as np
import pytest
import yaml
from scipy import stats
from support.paper import A1, FAST, FJ1, SMALL
from support.repo import REPO, SCHEMA

from bpmcal import params as P
from bpmcal.cli import main
from bpmcal.lab.microstructure import truncated_normal
from bpmcal.lab.runner import make_specimen
from bpmcal.lab.ucs import run_ucs
from bpmcal.study.config import ConfigError, validate_config

#: a scatter as P&C's (mean +- sd, sd/mean ~ 0.23) and a heavily truncated one
SCATTER = {"pb_ten_sd_MPa": 10.0, "pb_coh_sd_MPa": 7.0}


def _truncated(mean, sd):
    """Mean and sd of the Gaussian (mean, sd) conditioned on >= 0 (scipy)."""
    d = stats.truncnorm(-mean / sd, np.inf, loc=mean, scale=sd)
    return d.mean(), d.std()


@pytest.mark.parametrize("mean, sd", [(175.0, 40.0), (10.0, 10.0), (0.0, 5.0)])
def test_draws_have_the_truncated_gaussians_mean_and_sd(mean, sd):
    n = 200_000
    x = truncated_normal(np.random.default_rng(1), mean, sd, n)
    assert x.shape == (n,) and x.min() >= 0.0
    mu, s = _truncated(mean, sd)
    # sampling errors: s/sqrt(n) for the mean, about s/sqrt(2n) for the sd (4 of them)
    assert abs(x.mean() - mu) < 4 * s / math.sqrt(n)
    assert abs(x.std() - s) < 4 * s / math.sqrt(2 * n) * 1.5  # (a truncated tail: wider)
    if mean / sd > 4:  # truncation hardly matters (P&C's card): the card's mean and sd
        assert mu == pytest.approx(mean, rel=1e-4) and s == pytest.approx(sd, rel=1e-3)
    else:  # it does here: the draws are not those of the untruncated Gaussian
        assert x.mean() - mean > 10 * s / math.sqrt(n)
    # the truncation is PFC's redraw, not a clip: no mass piles up at zero
    assert np.count_nonzero(x == 0.0) == 0


def test_sd_zero_is_the_mean_exactly_and_draws_nothing():
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    x = truncated_normal(rng, 31.7, 0.0, 10)
    assert (x == 31.7).all() and rng.bit_generator.state == state


@pytest.fixture(scope="module")
def scattered(cache):
    return make_specimen({**A1, **SCATTER}, 3, SMALL, cache=cache)


def test_every_bond_draws_its_own_strengths_with_the_cards_statistics(scattered):
    m = scattered.model
    ten, coh = (a / 1e6 for a in m.bond_strengths)
    n = ten.size
    assert n > 500
    for x, mean, sd in ((ten, A1["pb_ten_MPa"], 10.0), (coh, A1["pb_coh_MPa"], 7.0)):
        mu, s = _truncated(mean, sd)
        assert abs(x.mean() - mu) < 4 * s / math.sqrt(n)
        assert abs(x.std() - s) < 4 * s / math.sqrt(2 * n) * 1.5
        assert np.unique(x).size == n  # one value per contact
    assert abs(np.corrcoef(ten, coh)[0, 1]) < 4 / math.sqrt(n)  # drawn independently
    r = scattered.report
    assert r["strength_ten_mean_MPa"] == pytest.approx(ten.mean())
    assert r["strength_coh_sd_MPa"] == pytest.approx(coh.std())


def test_the_strengths_follow_the_packing_seed(scattered, cache):
    again = make_specimen({**A1, **SCATTER}, 3, SMALL, cache=cache).model.bond_strengths
    assert all((a == b).all() for a, b in zip(again, scattered.model.bond_strengths))
    other = make_specimen({**A1, **SCATTER}, 4, SMALL, cache=cache).model.bond_strengths[0]
    assert other.size != again[0].size or not (other == again[0]).all()


def test_a_flat_joint_draws_one_pair_per_joint(cache):
    sp = make_specimen({**FJ1, "fj_ten_sd_MPa": 2.0}, 3, SMALL, cache=cache)
    ten, coh = sp.model.bond_strengths
    assert np.unique(ten).size == ten.size  # per joint (its elements share it)
    assert (coh == FJ1["fj_coh_MPa"] * 1e6).all()  # no sd: the mean, exactly


def test_sd_zero_reproduces_the_run_bit_for_bit(cache):
    """Three ways to ask for no scatter run the same UCS test to the last bit: the card
    without the keys (as before the scatter existed), with sd 0, and with every bond given
    the means explicitly through the per-contact strengths."""
    assert P.validate_params({**A1, "pb_ten_sd_MPa": 0.0, "pb_coh_sd_MPa": 0}) == \
        P.validate_params(A1)  # a card at sd 0 is the card without the keys
    runs = []
    for card, explicit in ((A1, False), ({**A1, "pb_ten_sd_MPa": 0.0}, False), (A1, True)):
        sp = make_specimen(card, 3, SMALL, cache=cache)
        assert sp.report.get("strength_ten_sd_MPa") is None  # nothing drawn
        ten, coh = sp.model.bond_strengths
        assert (ten == A1["pb_ten_MPa"] * 1e6).all() and (coh == A1["pb_coh_MPa"] * 1e6).all()
        if explicit:
            sp.model.set_bond_strengths(ten.copy(), coh.copy())
        runs.append(run_ucs(sp, FAST))
    a = runs[0]
    for b in runs[1:]:
        timing = {"wall_s"}  # (the one entry that is the host's, not the run's)
        assert {k: v for k, v in a.summary.items() if k not in timing} == \
            {k: v for k, v in b.summary.items() if k not in timing}
        assert a.series.keys() == b.series.keys()
        for k in a.series:
            assert np.array_equal(a.series[k], b.series[k]), k


def test_scatter_changes_the_run(scattered, cache):
    """The scatter is not inert: with it, the same packing fails otherwise."""
    base = run_ucs(make_specimen(A1, 3, SMALL, cache=cache), FAST).summary
    s = run_ucs(scattered, FAST).summary
    assert s["ucs_MPa"] != base["ucs_MPa"]
    assert s["E_GPa"] == pytest.approx(base["E_GPa"], rel=0.02)  # stiffnesses untouched


@pytest.mark.parametrize("bad, needle", [("-1", "pb_ten_sd_MPa=-1 MPa is outside"),
                                         ("nan", "pb_ten_sd_MPa=nan")])
def test_bad_sd_on_the_command_line_is_one_line_exit_2_no_file(tmp_path, capsys, bad, needle):
    card = tmp_path / "a1.yaml"
    card.write_text(yaml.safe_dump(A1))
    out = tmp_path / "out" / "r.h5"
    rc = main(["ucs", "--params", str(card), "--out", str(out), "--set",
               f"pb_ten_sd_MPa={bad}"])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert lines[0].startswith("bpmcal ucs: error: ") and needle in lines[0], err
    assert not out.exists() and not any((tmp_path / "out").rglob("*")) \
        if (tmp_path / "out").exists() else True


def test_bad_sd_in_a_card_file_is_refused_the_same_way(tmp_path, capsys):
    card = tmp_path / "a1.yaml"
    card.write_text(yaml.safe_dump({**A1, "pb_coh_sd_MPa": -3.0}))
    out = tmp_path / "r.h5"
    assert main(["ucs", "--params", str(card), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pb_coh_sd_MPa=-3" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("key, value, needle", [
    ("ranges", {"pb_ten_sd_MPa": [-1.0, 5.0]}, "ranges.pb_ten_sd_MPa[0]: -1.0"),
    ("ranges", {"pb_coh_sd_MPa": [0.0, float("nan")]}, "ranges.pb_coh_sd_MPa[1]: nan"),
    ("fixed", {"pb_ten_sd_MPa": -2.0}, "calibration.fixed.pb_ten_sd_MPa: -2.0")])
def test_bad_sd_in_the_config_is_named(key, value, needle):
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    node = cfg["ranges"] if key == "ranges" else cfg["calibration"]["fixed"]
    node.update(value)
    with pytest.raises(ConfigError) as e:
        validate_config(cfg, SCHEMA, base_dir=REPO)
    assert needle in str(e.value), str(e.value)


def test_the_config_can_hold_a_scatter_fixed_or_free_it():
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    cfg["ranges"]["pb_ten_sd_MPa"] = [0.0, 10.0]
    cfg["calibration"]["fixed"]["pb_ten_sd_MPa"] = 5.0  # held fixed, inside its range
    validate_config(cfg, SCHEMA, base_dir=REPO)
    del cfg["calibration"]["fixed"]["pb_ten_sd_MPa"]
    cfg["calibration"]["free"] = ["pb_emod_GPa", "pb_kratio", "pb_coh_MPa", "pb_ten_sd_MPa"]
    validate_config(cfg, SCHEMA, base_dir=REPO)


def test_a_design_carries_a_ranged_sd_and_leaves_an_unused_one_out(tmp_path):
    from bpmcal.stages.runs import params_from_design
    from bpmcal.study.design import lhs_design

    ranges = {k: list(v) for k, v in P.table2_ranges().items()}
    d = lhs_design({**ranges, "pb_ten_sd_MPa": [0.0, 10.0]}, 8, 1)
    assert d["pb_ten_sd_MPa"].between(0, 10).all() and d["pb_ten_sd_MPa"].nunique() == 8
    assert "pb_coh_sd_MPa" not in d.columns  # no range, no fixed value: 0, left out
    f = tmp_path / "design.csv"
    d.to_csv(f, index=False)
    card, _, _ = params_from_design(f, "s003")
    assert card["pb_ten_sd_MPa"] == pytest.approx(d["pb_ten_sd_MPa"][3])
    assert "pb_coh_sd_MPa" not in card
    assert list(lhs_design(ranges, 8, 1).columns) == ["sample_id", *P.PARAM_NAMES, "seed"]
