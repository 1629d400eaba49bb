"""The docs build hook that drops the figure markers before a page is rendered
(docs/hooks/figure_markers.py): a wrapped line that starts with a marker no longer breaks
its paragraph or its list."""
import importlib.util
import sys
from pathlib import Path

import markdown

REPO = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("figure_markers",
                                              REPO / "docs" / "hooks" / "figure_markers.py")
hook = importlib.util.module_from_spec(spec)
spec.loader.exec_module(hook)
sys.path.insert(0, str(REPO / "benchmarks"))
import figures  # noqa: E402

PAGE = """- **First.** The study ran in
  <!--fig:study.wall_min-->38.8<!--/fig--> min
  (<!--rec:study.wall_min-->[record](measurements/x.md)<!--/rec-->).
- **Second.** More.
"""


def test_the_markers_go_and_the_values_and_links_stay():
    out = hook.strip_markers(PAGE)
    assert "<!--" not in out
    assert "  38.8 min\n  ([record](measurements/x.md))." in out
    assert figures.MARK.sub(lambda m: m.group(2), PAGE).replace(
        "<!--rec:study.wall_min-->", "").replace("<!--/rec-->", "") == out


def test_a_list_with_a_marker_at_a_line_start_renders_as_a_list_only_without_markers():
    broken = markdown.markdown(PAGE)
    assert broken.count("<li>") < 2  # the reason for the hook: Python-Markdown's HTML block
    html = markdown.markdown(hook.on_page_markdown(PAGE, page=None))
    assert html.count("<li>") == 2 and "- <strong>" not in html
    assert '38.8 min\n  (<a href="measurements/x.md">record</a>).</li>' in html


def test_every_docs_page_that_quotes_figures_is_rendered_without_stray_items():
    for page in (REPO / "docs").rglob("*.md"):
        html = markdown.markdown(hook.strip_markers(page.read_text()), extensions=["tables"])
        assert "\n- <strong>" not in html, page
