"""MkDocs hook: the figure markers out of every page before it is rendered.

A quoted figure is marked in the Markdown as ``<!--fig:KEY-->VALUE<!--/fig-->`` and a
record link as ``<!--rec:KEY-->[text](path)<!--/rec-->`` (``benchmarks/figures.py``
refreshes them). Where a wrapped line starts with a marker, Python-Markdown takes the
line for an HTML block: the paragraph breaks there, and inside a list the items after it
render as stray text. The site needs only the values, so the markers are dropped here and
the values and links stay.
"""
from __future__ import annotations

import re

MARKER = re.compile(r"<!--(?:(?:fig|rec):[A-Za-z0-9_.]+|/fig|/rec)-->")


def strip_markers(markdown: str) -> str:
    """``markdown`` without its figure and record-link markers (values and links kept)."""
    return MARKER.sub("", markdown)


def on_page_markdown(markdown: str, **kwargs) -> str:
    return strip_markers(markdown)
