"""Every measured figure the README and the docs quote comes from one generated source,
``docs/measurements/figures.json`` (``benchmarks/figures.py``, from the benchmarks' JSON
records): a marked figure equals its generated value, figures.json is up to date, and a
page outside ``docs/measurements/`` holds no unmarked measured figure (a time, a speed
ratio, a percentage, a load average, a memory size) unless it is a method constant of the
short allowlist below. Quote a measurement as ``<!--fig:KEY-->VALUE<!--/fig-->`` or link
its record in docs/measurements/; never copy the number."""
import json
import re
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "benchmarks"))

import figures  # noqa: E402

#: what a measured figure looks like in prose (after code, links and marked figures are
#: taken out): a duration, a speed ratio ("1.88×", "3.1 × the runs"; "50 × 100 mm" is a
#: size), a percentage, a load average, a memory size or a throughput
MEASURED = re.compile(
    r"\d(?:[\d.,]*\d)?\s*(?:[–-]\s*\d(?:[\d.,]*\d)?\s*)?"
    r"(?:min\b|minutes?\b|hours?\b|h\b|CPU[- ]\w+|core-\w+|s\b|ms\b|µs\b|%|MB\b|GB\b|kB\b|"
    r"×(?!\s*\d)|M particle)"
    r"|load(?: average)?(?: of| at)? ~?\d")

#: method constants that look like measurements: (pattern, why it is not a measurement)
ALLOWED = [
    (r"10 % screening threshold|screening threshold of 10 %|10 % of the importance",
     "the paper's screening threshold (a method choice)"),
    (r"tensile share 60 %|tensile share of 60 %|60 % tensile", "the ratio sweep's target"),
    (r"40–60 % of the peak", "the window of the E and ν fit (method)"),
    (r"400 MB \+ 4 kB per ball", "the resource guard's estimate (its formula)"),
    (r"80 % of the machine's memory", "the --mem-budget-mb default"),
    (r"15 % or more of the failure's cracks", "the Brazilian validity rule's threshold"),
    (r"1000 × its tensile strength|strength ×1000|1000 ×", "the end caps' strength factor"),
    (r"1\.5 × the disc's", "the ISRM jaw radius"),
    (r"`rtol` \(1 %\)|rtol 1 %|1 % tolerance|tolerance of 1 %|below 1 %",
     "the verification's tolerance (a config value)"),
    (r"~0\.2 s numba calls|numba calls of (?:about|~)\s?0\.2 s",
     "the engine's designed chunk length (bpmcal.lab.stepping)"),
    (r"10 ms|40 ms", "impact.duration_ms: the old and the current default (method)"),
    (r"middle 20 %|middle fifth|bottom 40 %|top 40 %", "the crack-height bands (definitions)"),
    (r"~1 min|about a minute", "the smoke study's order of magnitude, a design goal of CI"),
    (r"2 × the seed CV", "the transfer's tolerance (its formula)"),
    (r"0\.8 × the minimum", "PFC's timestep safety factor"),
    (r"95 % intervals|default 2\.5-97\.5 %", "the bootstrap intervals' level (a method choice)"),
    (r"seed CV above 5 %", "issue 24's σt precision target (bts_resolution.CV_TARGET)"),
    (r"\(default 2 %\) of a range", "the inversion's distinct-solution distance (a default)"),
    (r"would take more than 10 s|longer than 10 s if", "the loading screen's limit "
     "(lab.budget.HOPELESS_S, a method constant)"),
    (r"\(4\.55 %\)|probability 4\.55 %", "the two-sided level of 2 normal standard errors "
     "(the fresh-seed check's, a method constant)"),
    (r"90 % (?:interval|HDI|highest-density)", "the posterior's interval probability "
     "(posterior.hdi_prob, a config value)"),
    (r"within 2 % of a posterior sd|within 2 % \(the test", "the closed-form posterior "
     "test's tolerance (a method constant of the test)"),
]
ALLOWED_RE = re.compile("|".join(f"(?:{p})" for p, _ in ALLOWED))

FIGS = json.loads((REPO / "docs" / "measurements" / "figures.json").read_text())


def _fence(m) -> str:
    """A fenced code block blanked except its comments (``# ...`` after a command): a
    comment is prose, and where a figure's copy once drifted (the README's first lines)."""
    out = []
    for line in m.group(0).split("\n"):
        c = re.search(r"(?:^|\s)#\s", line)
        out.append(" " * c.start() + line[c.start():] if c else " " * len(line))
    return "\n".join(out)


def _prose(text: str) -> str:
    """The page without what is not prose: fenced code, inline code, HTML comments other
    than markers, link targets and marked figures (kept as blanks, lines preserved)."""
    def blank(m):
        return re.sub(r"[^\n]", " ", m.group(0))
    text = figures.MARK.sub(blank, text)
    text = re.sub(r"```.*?```", _fence, text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", blank, text)
    text = re.sub(r"<!--.*?-->", blank, text, flags=re.S)
    text = re.sub(r"\]\([^)]*\)", blank, text)
    return text


def unmarked(text: str) -> list[tuple[int, str]]:
    """(line, match) of every measured-looking figure outside the allowlist."""
    prose = _prose(text)
    allowed = [m.span() for m in ALLOWED_RE.finditer(prose)]
    out = []
    for m in MEASURED.finditer(prose):
        if any(a <= m.start() < b for a, b in allowed):
            continue
        out.append((prose.count("\n", 0, m.start()) + 1, m.group(0)))
    return out


def test_figures_json_is_generated_from_the_records():
    assert (REPO / "docs" / "measurements" / "figures.json").read_text() == figures.render(), (
        "docs/measurements/figures.json is stale: python benchmarks/figures.py")


@pytest.mark.parametrize("page", figures.pages(), ids=lambda p: str(p.relative_to(REPO)))
def test_every_marked_figure_is_the_generated_value(page):
    for key, value in figures.MARK.findall(page.read_text()):
        assert key in FIGS, f"{page.name}: unknown figure {key}"
        assert value == FIGS[key]["text"], (
            f"{page.name}: {key} is {value!r}, generated {FIGS[key]['text']!r} "
            "(python benchmarks/figures.py refreshes the markers)")


@pytest.mark.parametrize("page", figures.pages(), ids=lambda p: str(p.relative_to(REPO)))
def test_every_record_link_is_the_figures_record(page):
    for key, _, path in figures.REC.findall(page.read_text()):
        assert key in FIGS, f"{page.name}: unknown figure {key}"
        want = figures.record_link(key, FIGS, page)
        assert path == want, (f"{page.name}: the record of {key} is {want}, the page links "
                              f"{path} (python benchmarks/figures.py refreshes it)")
        assert (page.parent / path).is_file(), f"{page.name}: {path} does not exist"


def test_a_stale_record_link_is_refreshed():
    text = "<!--rec:study.wall_min-->[record](docs/measurements/old.md)<!--/rec-->"
    out = figures.refresh(text, FIGS, REPO / "README.md")
    assert out == (f"<!--rec:study.wall_min-->[record]({FIGS['study.wall_min']['record']})"
                   "<!--/rec-->")


@pytest.mark.parametrize("page", figures.pages(), ids=lambda p: str(p.relative_to(REPO)))
def test_no_unmarked_measured_figure(page):
    found = unmarked(page.read_text())
    assert not found, (f"{page.relative_to(REPO)}: measured figures not taken from "
                       "docs/measurements/figures.json (mark them, link the record, or, for a "
                       "method constant, extend ALLOWED with the reason): "
                       + "; ".join(f"line {ln}: {s!r}" for ln, s in found))


def test_every_figure_names_an_existing_source_and_record():
    for key, f in FIGS.items():
        assert (REPO / f["source"]).is_file(), (key, f["source"])
        assert (REPO / f["record"]).is_file(), (key, f["record"])


#: sentences of the README before the measurement records existed (commit 9e061cd): the
#: check must catch every one of them
OLD_README = [
    '```bash\npip install -e ".[test]" && snakemake --cores 2   # (~30 min here, ~50 CPU-min)\n```',
    "the same study took **26.3 min wall and 42.8 CPU-min** (2,506 s user + 59 s system)",
    "14.16 against 7.53 M particle-steps/s in the median, **1.88×** (pairs 1.89, 1.91, 1.84)",
    "Halving the default speed changes σc by 1.1 % (median; 0.75–1.7 %) and E by < 0.03 %.",
    "load average at ~7): from SIGINT to the exit",
    "Peak memory 187 MB (10k) and 224 MB (30k)",
    "polishing brings the RMS error for 3.1 × the runs (7.9 → 24.7 per loop)",
]


@pytest.mark.parametrize("sentence", OLD_README)
def test_the_check_catches_the_old_readme(sentence):
    assert unmarked(sentence), sentence


def test_the_check_passes_marked_and_allowlisted_figures():
    key = "study.wall_min"
    text = (f"takes <!--fig:{key}-->{FIGS[key]['text']}<!--/fig--> min; the paper's 10 % "
            "screening threshold; `--duration-ms 40`; a 50 × 100 mm specimen")
    assert unmarked(text) == []
