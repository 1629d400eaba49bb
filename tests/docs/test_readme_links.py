"""The README's relative links lead somewhere: every linked file exists, and a linked
heading exists in that file (GitHub's anchor of a Markdown heading). The docs pages are
checked by ``mkdocs build --strict`` in CI; the README is not part of the site."""
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _anchor(heading: str) -> str:
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def test_every_relative_link_of_the_readme_exists():
    text = (REPO / "README.md").read_text()
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links
    for link in links:
        if re.match(r"[a-z]+://", link):
            continue
        path, _, anchor = link.partition("#")
        target = REPO / path
        assert target.exists(), link
        if anchor:
            heads = re.findall(r"^#+ (.+)$", target.read_text(), flags=re.M)
            assert anchor in {_anchor(h) for h in heads}, link


def test_the_readme_stays_short_and_starts_with_the_two_commands():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= 200
    head = "\n".join(lines[:6])
    assert 'pip install -e ".[test]" && snakemake --cores 2' in head
    assert 'pip install -e ".[test]" && python -m pytest -q -ra -n 2 --dist loadfile' in head
