"""The measurement records in docs/measurements are generated from the benchmarks' JSON
records and must be up to date: a hand edit, or a JSON re-measured without regenerating
the page, fails here (regenerate with the command docs/measurements/README.md names)."""
import json
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "benchmarks"))
#: the benchmarks' JSON records (their scripts: benchmarks/)
RESULTS = REPO / "benchmarks" / "results"

import bts_resolution  # noqa: E402


def test_the_tensile_strength_records_are_their_json_rendered():
    for date, stems in (("2026-11-26", ("loadings", "resolution", "dtt")),
                        ("2026-11-27", ("loadings", "cards")),
                        ("2026-11-28", ("specimens", "specimens_a1-seeds31-90"))):
        page = REPO / "docs" / "measurements" / f"{date}-tensile-strength.md"
        names = [f"results_bts_{s}_{date}.json" for s in stems]
        recs = [json.loads((RESULTS / n).read_text()) for n in names]
        title = page.read_text().splitlines()[0][2:]
        assert page.read_text() == bts_resolution.markdown(recs, title, names, "benchmarks"), page.name


def test_the_planted_cards_tensile_records_are_their_json_rendered():
    for page, names in (
            ("2026-11-29c-bts-size-planted.md", ("results_bts_resolution_2026-11-29_planted_u.json",
                                                 "results_bts_resolution_2026-11-29_planted_q.json")),
            ("2026-11-29g-bts-specimens-planted.md",
             ("results_bts_specimens_planted_u_2026-11-29.json",))):
        page = REPO / "docs" / "measurements" / page
        recs = [json.loads((RESULTS / n).read_text()) for n in names]
        title = page.read_text().splitlines()[0][2:]
        assert page.read_text() == bts_resolution.markdown(recs, title, list(names), "benchmarks"), page.name


def test_the_disc_size_record_is_its_json_rendered():
    """Its tables are generated (``bts_size_curve.py markdown``); the findings follow them."""
    import bts_size_curve

    page = REPO / "docs" / "measurements" / "2026-12-02-bts-disc-size.md"
    names = ["results_bts_size_validity_2026-12-02.json", "results_bts_size_curve_2026-12-02.json"]
    recs = [json.loads((RESULTS / n).read_text()) for n in names]
    text = page.read_text()
    assert text.startswith(bts_size_curve.markdown(recs, text.splitlines()[0][2:], names))


def _listed(page: str) -> set[str]:
    """The records a page of docs/measurements lists in its tables (first column)."""
    text = (REPO / "docs" / "measurements" / page).read_text()
    return set(re.findall(r"^\| \[(2[^\]]+\.md)\]\(\1\) \|", text, re.M))


def test_every_record_is_current_or_earlier_in_one_list():
    """Every record is listed once: as its topic's current record in the index, or in the
    archive of earlier records, with the record that superseded or prompted it."""
    records = {p.name for p in (REPO / "docs" / "measurements").glob("2*.md")}
    current, earlier = _listed("README.md"), _listed("archive.md")
    assert current | earlier == records, records - current - earlier
    assert not current & earlier, current & earlier
    archive = (REPO / "docs" / "measurements" / "archive.md").read_text()
    for name in earlier:
        row = next(ln for ln in archive.splitlines() if ln.startswith(f"| [{name}]"))
        later = re.findall(r"\]\((2[^)]+\.md)\)", row.split(" | ")[1])
        assert later and all(r in records and r != name for r in later), row


def test_the_navigation_holds_the_current_records_only():
    """The site's navigation lists the index, the current record of each topic and one
    archive page, not the 50-odd earlier records."""
    import yaml

    class Loader(yaml.SafeLoader):  # mkdocs.yml's !!python tags are not needed here
        pass
    Loader.add_multi_constructor("tag:yaml.org,2002:python/", lambda *a: None)
    nav = yaml.load((REPO / "mkdocs.yml").read_text(), Loader)["nav"]

    def pages(node):
        if isinstance(node, str):
            return [node]
        if isinstance(node, dict):
            return [p for v in node.values() for p in pages(v)]
        return [p for v in node for p in pages(v)]
    in_nav = {p.removeprefix("measurements/") for p in pages(nav)
              if p.startswith("measurements/2")}
    assert in_nav == _listed("README.md")
    assert "measurements/archive.md" in pages(nav)


def test_the_readme_links_to_records_that_exist():
    text = (REPO / "README.md").read_text()
    for link in re.findall(r"\((docs/measurements/[^)#]+)\)", text):
        assert (REPO / link).is_file(), link


def test_every_record_has_its_header():
    """A record says when, on which commit and host it was measured (a generated record in
    its own words, a moved one in the fixed header table; "not recorded" where unknown)."""
    for page in (REPO / "docs" / "measurements").glob("2*.md"):
        text = page.read_text().lower()
        date = page.name[:10]
        assert date in text, page.name
        for field in ("commit", "host"):
            assert field in text, (page.name, field)


def test_the_docs_link_to_records_that_exist():
    docs = REPO / "docs"
    for page in docs.rglob("*.md"):
        for link in re.findall(r"\]\(((?:\.\./)*measurements/[^)#]+)\)", page.read_text()):
            assert (page.parent / link).resolve().is_file(), (page.name, link)


def test_the_default_study_records_are_their_json_rendered():
    import study_outputs
    import study_record

    for page, pattern, render in (
            ("default-study.md", "results_default_study_*.json", study_record.markdown),
            ("default-study-results.md", "results_study_outputs_*.json", study_outputs.markdown)):
        for raw in RESULTS.glob(pattern):
            rec = json.loads(raw.read_text())
            tag = raw.stem.rsplit("_", 1)[-1]  # the date, a letter for a second record that day
            assert tag.startswith(rec["date"]), raw.name
            md = REPO / "docs" / "measurements" / f"{tag}-{page}"
            assert md.read_text() == render(rec), (md.name, "regenerate it from", raw.name)


def test_the_planted_card_record_is_its_json_rendered():
    import planted_card

    for raw in RESULTS.glob("results_planted_card_*.json"):
        rec = json.loads(raw.read_text())
        tag = raw.stem.removeprefix("results_planted_card_")  # the date, a letter for a 2nd run
        assert tag.startswith(rec["date"]), raw.name
        md = REPO / "docs" / "measurements" / f"{tag}-planted-card.md"
        assert md.read_text() == planted_card.markdown(rec), (md.name, "regenerate from", raw.name)


def test_the_fresh_seed_check_record_is_the_planted_records_rejudged():
    """Record 2026-11-28p's table is planted_card.rejudge_markdown of the records its
    command names, as they are in benchmarks/."""
    import planted_card

    page = (REPO / "docs" / "measurements" / "2026-11-28p-fresh-seed-check.md").read_text()
    cmd = re.search(r"--rejudge ([^`]+)`", page).group(1).split()
    assert len(cmd) == 6
    assert planted_card.rejudge_markdown([str(RESULTS / f) for f in cmd]).replace(
        str(RESULTS) + "/", "") in page
    import example_record

    examples = re.findall(r"`python example_record.py --rejudge (\S+) --lab (\S+)"
                          r"(?: --triaxial-seeds (\d+))?`", page)
    assert len(examples) == 3
    for rec, lab, m in examples:
        assert example_record.rejudge_markdown(str(RESULTS / rec), lab,
                                               int(m) if m else None) in page, rec


def test_the_test_tiers_record_is_its_json_rendered():
    import test_tiers

    for raw in RESULTS.glob("results_test_tiers_*.json"):
        rec = json.loads(raw.read_text())
        md = REPO / "docs" / "measurements" / f"{rec['date']}-test-tiers.md"
        assert md.read_text() == test_tiers.markdown(rec), (md.name, "regenerate from", raw.name)


def test_the_genesis_share_record_is_its_json_rendered():
    import study_genesis_share as genesis_share

    for raw in RESULTS.glob("results_study_genesis_share_*.json"):
        rec = json.loads(raw.read_text())
        md = REPO / "docs" / "measurements" / f"{rec['date']}-genesis-share.md"
        assert md.read_text() == genesis_share.markdown(rec), (md.name, "regenerate from", raw.name)


def test_the_example_study_records_are_their_json_rendered():
    import example_record

    for raw in RESULTS.glob("results_example_*.json"):
        rec = json.loads(raw.read_text())
        md = REPO / "docs" / "measurements" / rec["page"]
        assert md.read_text() == example_record.markdown(rec), (md.name, "regenerate from", raw.name)


def test_job_times_sums_each_rule_from_snakemakes_log(tmp_path):
    """The study record's time by rule: each job from its start stamp to its Finished
    stamp, summed per rule (a job that never finished is not counted)."""
    import study_record

    log = tmp_path / "time.log"
    log.write_text(
        "[Sat Nov 28 11:41:56 2026]\nlocalrule design:\n    output: a\n    jobid: 2\n"
        "    reason: x\n[Sat Nov 28 11:41:59 2026]\nFinished jobid: 2 (Rule: design)\n"
        "[Sat Nov 28 11:42:00 2026]\nrule ucs:\n    input: a\n    jobid: 7\n"
        "    wildcards: sample=s000\n[Sat Nov 28 11:42:00 2026]\nrule ucs:\n    jobid: 8\n"
        "[Sat Nov 28 11:43:40 2026]\nFinished jobid: 7 (Rule: ucs)\n"
        "[Sat Nov 28 11:44:10 2026]\nFinished jobid: 8 (Rule: ucs)\n"
        "[Sat Nov 28 11:44:11 2026]\nrule verify:\n    jobid: 9\nError in rule verify\n")
    assert study_record.job_times(log) == {"design": {"jobs": 1, "wall_s": 3.0},
                                           "ucs": {"jobs": 2, "wall_s": 100.0 + 130.0}}


def test_a_test_tiers_record_says_whether_numba_s_cache_was_warm():
    """The tiers' times depend on numba's cache: a record made now counts the compiled
    kernels before the first tier and says warm or cold (records before 2026-12 carry it
    in their note)."""
    import test_tiers

    rec = json.loads((RESULTS / "results_test_tiers_2026-11-28.json").read_text())
    for n, state in ((0, "cold"), (12, "warm")):
        rec["numba_cache"] = {"dir": ".cache/test/bpmcal/numba/x", "kernels": n, "state": state}
        text = test_tiers.markdown(rec)
        assert f"Numba cache before the first tier: **{state}** ({n} compiled kernels" in text
    nc = test_tiers.numba_cache()
    assert nc["state"] == ("warm" if nc["kernels"] else "cold") and "numba" in nc["dir"]


def test_the_cost_model_records_are_their_json_rendered():
    import cost_model

    for raw in RESULTS.glob("results_cost_model_*.json"):
        date, name = raw.stem.removeprefix("results_cost_model_").split("_", 1)
        rec = json.loads(raw.read_text())
        assert rec["date"] == date[:10], raw.name  # a second record of a day: DATEb, DATEc
        md = REPO / "docs" / "measurements" / f"{date}-cost-model-{name}.md"
        assert md.read_text() == cost_model.markdown(rec), (md.name, "regenerate from", raw.name)


def test_the_posterior_study_records_are_their_json_rendered():
    import posterior_study

    for raw in RESULTS.glob("results_posterior_study_*.json"):
        rec = json.loads(raw.read_text())
        tag = raw.stem.rsplit("_", 1)[-1]  # the date, a letter for a second record that day
        assert tag.startswith(rec["date"]), raw.name
        md = REPO / "docs" / "measurements" / f"{tag}-posterior-study.md"
        assert md.read_text() == posterior_study.markdown(rec), (md.name, "regenerate from", raw.name)
