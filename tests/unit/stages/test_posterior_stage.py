"""The posterior stage end to end on a synthetic study (no DEM): a design and a closed
loop's seed runs drawn from known response functions with packing scatter, a card
calibrated on them; ``bpmcal posterior`` writes the card with its posterior, the tables,
the NetCDF and the figures, holds the planted parameters inside its intervals, and refuses
bad input in one line with exit code 2 and no output file."""

import numpy as np
import pandas as pd
import pytest
import yaml
from support.synthetic import FIXED, RANGES, TRUTH, calibrate_b1, models, write_models

from bpmcal.cli import main

CV = 0.03  # packing scatter of one specimen (relative)


def _truth_responses(P: pd.DataFrame, rng) -> pd.DataFrame:
    """The synthetic rock: the regression's models (the surrogate's basis can follow them)
    plus a smooth term they do not hold, each run with CV scatter."""
    ms = models()
    out = {}
    for r, m in ms.items():
        y = m.predict(P) * (1 + 0.05 * np.sin(P["pb_emod_GPa"] / 7.0))
        out[r] = y * (1 + CV * rng.standard_normal(len(P)))
    return pd.DataFrame(out, index=P.index)


def _study(tmp_path, lab_se=None):
    rng = np.random.default_rng(7)
    n = 120
    U = rng.uniform(0, 1, (n, len(RANGES)))
    P = pd.DataFrame({k: lo + U[:, j] * (hi - lo) for j, (k, (lo, hi)) in enumerate(RANGES.items())})
    df = pd.concat([P, _truth_responses(P, rng)], axis=1)
    df.insert(0, "sample_id", [f"s{i:03d}" for i in range(n)])
    df["status"], df["seed"] = "ok", np.arange(n)
    df = df.drop(columns=["bts_MPa"])
    df.to_csv(tmp_path / "dataset.csv", index=False)
    write_models(tmp_path / "models.json", {k: v for k, v in models().items() if k != "bts_MPa"})
    truth = {**FIXED, **TRUTH, "pb_ten_MPa": 1.4 * TRUTH["pb_coh_MPa"]}
    point = pd.DataFrame([truth])
    y = {r: float(models()[r].predict(point)[0] * (1 + 0.05 * np.sin(truth["pb_emod_GPa"] / 7)))
         for r in ("ucs_MPa", "E_GPa", "nu")}
    lab = {"specimen": "B1", **y, "u_pre_MJm3": 0.2}
    if lab_se:
        lab.update({f"{r}_se": v for r, v in lab_se.items()})
    pd.DataFrame([lab]).to_csv(tmp_path / "lab.csv", index=False)
    out = tmp_path / "cal"
    out.mkdir()
    assert calibrate_b1(tmp_path, out, options=["--ratio", "1.4"]) == 0
    card = yaml.safe_load((out / "B1.yaml").read_text())
    # a closed loop's rounds around the truth, 3 seeds each, and its card at the last one
    rows = []
    for k, f in enumerate((1.08, 0.96, 1.01, 1.0), start=1):
        p = {**truth, "pb_emod_GPa": truth["pb_emod_GPa"] * f,
             "pb_coh_MPa": truth["pb_coh_MPa"] / f}
        p["pb_ten_MPa"] = 1.4 * p["pb_coh_MPa"]
        pts = pd.DataFrame([p] * 3)
        resp = _truth_responses(pts, rng)
        for s in range(3):
            rows.append({"round": k, "seed": s + 1, **p, "status": "ok",
                         **resp.iloc[s].to_dict(), "cracks_tension": 100 + s,
                         "cracks_shear": 50 + 2 * s})
    pd.DataFrame(rows).to_csv(tmp_path / "seeds.csv", index=False)
    card["verification"] = {"status": "converged", "parameters": truth, "range_margin": 0.25,
                            "geometry": {"scale": 0.4}}
    (tmp_path / "card.yaml").write_text(yaml.safe_dump(card))
    return tmp_path, truth


def _args(d, card="card.yaml", out="post"):
    o = d / out
    return ["posterior", "--card", str(d / card), "--dataset", str(d / "dataset.csv"),
            "--models", str(d / "models.json"), "--loop-seeds", str(d / "seeds.csv"),
            "--out-card", str(o / "card.yaml"), "--table", str(o / "parameters.csv"),
            "--predictions", str(o / "predictions.csv"), "--netcdf", str(o / "posterior.nc"),
            "--figure", str(o / "pairs.png"), "--learning", str(o / "learning.csv"),
            "--learning-figure", str(o / "learning.png"), "--draws", str(o / "draws.csv"),
            "--refine-max-runs", "0", "--quiet"]


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    d, truth = _study(tmp_path_factory.mktemp("post"), lab_se={"ucs_MPa": 1.0, "E_GPa": 0.2,
                                                              "nu": 0.004})
    assert main(_args(d)) == 0
    return d, truth


def test_the_stage_writes_its_outputs_and_the_card_says_what_is_pinned(done):
    import arviz as az

    d, truth = done
    o = d / "post"
    for f in ("card.yaml", "parameters.csv", "parameters.md", "predictions.csv", "posterior.nc",
              "pairs.png", "pairs.pdf", "learning.csv", "learning.png", "draws.csv"):
        assert (o / f).is_file(), f
    post = yaml.safe_load((o / "card.yaml").read_text())["posterior"]
    assert post["status"] == "converged"
    assert post["sampler"]["rhat_max"] <= 1.01
    assert min(post["sampler"]["ess_bulk_min"], post["sampler"]["ess_tail_min"]) >= 400
    assert "pin" in post["identifiability"]
    for p in ("pb_emod_GPa", "pb_kratio", "pb_coh_MPa"):
        lo, hi = post["parameters"][p]["hdi"]
        assert lo <= truth[p] <= hi, (p, lo, hi, truth[p])
    idata = az.from_netcdf(o / "posterior.nc")
    assert set(idata.groups()) >= {"posterior", "sample_stats", "posterior_predictive",
                                   "observed_data"}
    assert set(idata.posterior.data_vars) >= {"pb_emod_GPa", "pb_kratio", "pb_coh_MPa",
                                              "pb_ten_MPa"}
    curve = pd.read_csv(o / "learning.csv")
    assert curve["data"].iloc[0] == "design" and curve["dem_runs_near_card"].iloc[-1] == 12
    assert curve["width_pct_of_range"].iloc[-1] < curve["width_pct_of_range"].iloc[0]


def test_the_stage_is_deterministic(done):
    d, _ = done
    assert main(_args(d, out="again")) == 0
    a = pd.read_csv(d / "post" / "parameters.csv")
    b = pd.read_csv(d / "again" / "parameters.csv")
    pd.testing.assert_frame_equal(a, b)


def _bad(d, edit, capsys, dataset=None):
    card = yaml.safe_load((d / "card.yaml").read_text())
    edit(card)
    (d / "bad.yaml").write_text(yaml.safe_dump(card))
    args = _args(d, card="bad.yaml", out="bad")
    if dataset is not None:
        args[args.index("--dataset") + 1] = str(dataset)
    capsys.readouterr()
    code = main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err
    assert not (d / "bad" / "card.yaml").exists() and not (d / "bad" / "posterior.nc").exists()
    return err[0]


@pytest.mark.parametrize("se", [-0.5, float("nan"), "x"])
def test_a_bad_standard_error_is_one_line_and_no_output(done, capsys, se):
    d, _ = done
    msg = _bad(d, lambda c: c.update(target_se={"ucs_MPa": se}), capsys)
    assert "target_se.ucs_MPa" in msg


def test_a_card_outside_its_prior_is_refused(done, capsys):
    d, _ = done

    def edit(c):
        c["verification"]["parameters"]["pb_kratio"] = 9.5  # beyond 5 + 0.25 x 4
    msg = _bad(d, edit, capsys)
    assert "outside its prior box" in msg and "pb_kratio" in msg


def test_an_empty_design_is_refused(done, capsys):
    d, _ = done
    df = pd.read_csv(d / "dataset.csv")
    df["status"] = "failed"
    df.to_csv(d / "failed.csv", index=False)
    msg = _bad(d, lambda c: None, capsys, dataset=d / "failed.csv")
    assert "status ok" in msg


def test_refinement_refuses_another_specimen_than_the_loops(done, capsys):
    d, _ = done
    args = _args(d, out="bad")
    args[args.index("--refine-max-runs") + 1] = "2"
    args += ["--scale", "0.5"]
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "another specimen than the card's closed loop" in err and "scale" in err
    assert not (d / "bad" / "card.yaml").exists()
