"""The docs build hook that turns the docstrings' Sphinx roles into links
(docs/hooks/sphinx_roles.py)."""
import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("sphinx_roles",
                                              REPO / "docs" / "hooks" / "sphinx_roles.py")
roles = importlib.util.module_from_spec(spec)
spec.loader.exec_module(roles)

IDS = {"bpmcal.lab.budget.check_loading_steps": "api/lab/index.html",
       "bpmcal.lab.budget.Loading": "api/lab/index.html",
       "bpmcal.io.card.read_card": "api/io/index.html",
       "bpmcal.io.h5.read_card": "api/io/index.html",
       "bpmcal.analysis.calibration.space": "api/analysis/index.html"}


def test_a_documented_target_becomes_a_link_relative_to_the_page():
    html = '<h2 id="bpmcal.lab.budget.Loading"></h2> see :func:<code>check_loading_steps</code>.'
    out = roles.rewrite(html, "api/lab/index.html", IDS)
    assert ('<a href="#bpmcal.lab.budget.check_loading_steps"><code>check_loading_steps'
            '</code></a>.') in out
    out = roles.rewrite(html, "api/io/index.html", IDS)
    assert '<a href="../lab/index.html#bpmcal.lab.budget.check_loading_steps">' in out


def test_an_undocumented_target_keeps_its_code_without_the_role():
    out = roles.rewrite("x :data:<code>budget.MAX_BALLS</code> y", "api/lab/index.html", IDS)
    assert out == "x <code>budget.MAX_BALLS</code> y"


def test_ambiguous_names_prefer_the_enclosing_module_and_tilde_shows_the_last_part():
    html = ('<h2 id="bpmcal.io.h5"></h2> :func:<code>read_card</code> and '
            ':func:<code>~bpmcal.io.card.read_card</code>')
    out = roles.rewrite(html, "api/io/index.html", IDS)
    assert '<a href="#bpmcal.io.h5.read_card"><code>read_card</code></a> and' in out
    assert out.endswith('<a href="#bpmcal.io.card.read_card"><code>read_card</code></a>')
    assert roles.resolve("calibration.space()", IDS) == "bpmcal.analysis.calibration.space"
    assert roles.resolve("nowhere", IDS) is None
