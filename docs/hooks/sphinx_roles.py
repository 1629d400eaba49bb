"""MkDocs hook: the Sphinx roles of the docstrings (``:func:`name```) as links in the site.

The docstrings are written for ``help()`` and for the source, where a role reads well;
mkdocstrings renders them as text (``:func:<code>name</code>``). After the build this hook
rewrites every page of the site: a role whose target is documented on an API page (an
element id such as ``bpmcal.lab.budget.check_loading_steps``) becomes a link to it, any
other role keeps its code and loses the prefix. A target matches an id that is it or ends
with ``.`` + it (``~`` and a leading ``.`` are dropped); among several, the one sharing the
longest dotted prefix with the object whose documentation contains the role is taken.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|data|attr|mod|obj|exc|const):<code>([^<]+)</code>")
ANCHOR = re.compile(r'id="(bpmcal(?:\.[A-Za-z_][A-Za-z0-9_]*)*)"')


def collect_ids(site: Path) -> dict[str, str]:
    """Every documented object's id -> the site-relative page that holds it."""
    ids = {}
    for page in sorted(site.rglob("*.html")):
        rel = page.relative_to(site).as_posix()
        for m in ANCHOR.finditer(page.read_text(encoding="utf-8")):
            ids.setdefault(m.group(1), rel)
    return ids


def _common(a: str, b: str) -> int:
    n = 0
    for x, y in zip(a.split("."), b.split(".")):
        if x != y:
            break
        n += 1
    return n


def resolve(target: str, ids: dict[str, str], context: str = "") -> str | None:
    """The id a role's ``target`` names, or None."""
    t = target.strip().lstrip("~").lstrip(".")
    t = t[:-2] if t.endswith("()") else t
    cands = [i for i in ids if i == t or i.endswith("." + t)]
    if not cands:
        return None
    return max(cands, key=lambda i: (_common(i, context), -len(i), i))


def rewrite(html: str, page: str, ids: dict[str, str]) -> str:
    """``html`` of site page ``page`` with its roles as links or plain code."""
    anchors = [(m.start(), m.group(1)) for m in ANCHOR.finditer(html)]
    out, last, k, context = [], 0, 0, ""
    for m in ROLE.finditer(html):
        while k < len(anchors) and anchors[k][0] < m.start():
            context = anchors[k][1]
            k += 1
        text = m.group(1)
        shown = text.lstrip("~").split(".")[-1] if text.startswith("~") else text.lstrip(".")
        code = f"<code>{shown}</code>"
        target = resolve(text, ids, context)
        if target is not None:
            href = os.path.relpath(ids[target], os.path.dirname(page) or ".")
            href = ("" if ids[target] == page else href) + "#" + target
            code = f'<a href="{href}">{code}</a>'
        out.append(html[last:m.start()])
        out.append(code)
        last = m.end()
    out.append(html[last:])
    return "".join(out)


def on_post_build(config, **kwargs):
    site = Path(config["site_dir"])
    ids = collect_ids(site)
    for page in site.rglob("*.html"):
        text = page.read_text(encoding="utf-8")
        if ROLE.search(text):
            page.write_text(rewrite(text, page.relative_to(site).as_posix(), ids),
                            encoding="utf-8")
