"""The configuration reference in Markdown, generated from the config schema
(:func:`schema_reference`): the reference part of config/README.md, so that the two
cannot disagree (tests/unit/study/test_config_doc.py). Regenerate it with
``python -m bpmcal.study.config workflow/schemas/config.schema.yaml``.
"""
from __future__ import annotations

import json
import re

from .. import params as P


def _allowed(node: dict) -> str:
    """The values a schema node accepts, in words."""
    if "enum" in node:
        return " \\| ".join("null" if v is None else str(v) for v in node["enum"])
    t = node.get("type")
    if t == "array":
        n = ""
        if node.get("minItems") == node.get("maxItems") and "minItems" in node:
            n = f"{node['minItems']} "
        elif "minItems" in node:
            n = f"≥ {node['minItems']} "
        inner = _allowed(node.get("items", {}))
        return f"list of {n}{inner or 'items'}".strip()
    word = re.fullmatch(r"\^(\w+)\$", node.get("pattern", ""))  # an integer or a word
    if word and isinstance(t, list) and "string" in t:
        rest = _allowed({k: v for k, v in node.items() if k != "pattern"})
        return f"{rest} or {word.group(1)}" if rest else word.group(1)
    a = node.get("exclusiveMinimum", node.get("minimum"))
    b = node.get("exclusiveMaximum", node.get("maximum"))
    lo = "(" if "exclusiveMinimum" in node or a is None else "["
    hi = ")" if "exclusiveMaximum" in node or b is None else "]"
    if a is None and b is None:
        return ""
    return f"{lo}{'-∞' if a is None else _num(a)}, {'∞' if b is None else _num(b)}{hi}"


def _num(x) -> str:
    """A bound as the reference writes it: an integer in full (a seed's 4294967295), a
    float in its shortest form."""
    return str(x) if isinstance(x, int) and not isinstance(x, bool) else f"{x:g}"


def _type(node: dict) -> str:
    t = node.get("type", "")
    if isinstance(t, list):
        t = " or ".join(t)
    if t == "array":
        t = f"list of {node.get('items', {}).get('type', 'items')}"
    return t


def _default(node: dict, required: bool) -> str:
    if "default" in node:
        return f"`{json.dumps(node['default'], ensure_ascii=False)}`"
    return "required" if required else "–"


def _nested(prefix: str, node: dict) -> list[str]:
    """The rows of a subsection's keys (``refine.max_runs``), one level at a time."""
    rows, req = [], set(node.get("required", []))
    for key, sub in node.get("properties", {}).items():
        meaning = " ".join(str(sub.get("description", "")).split())
        rows.append(f"| `{prefix}.{key}` | {_type(sub)} | {_default(sub, key in req)} | "
                    f"{_allowed(sub) or '–'} | {meaning or '–'} |")
        if sub.get("type") == "object" and sub.get("properties"):
            rows += _nested(f"{prefix}.{key}", sub)
    return rows


def schema_reference(schema: dict) -> str:
    """Every section and key of the config schema as Markdown tables (type, default,
    allowed values, meaning): the reference part of config/README.md, generated from the
    schema so that the two cannot disagree (tests/unit/study/test_config_doc.py)."""
    out = []
    top = schema["properties"]
    for sec, node in top.items():
        out.append(f"### `{sec}`\n")
        desc = " ".join(str(node.get("description", "")).split())
        if node.get("type") != "object":
            out.append(f"{desc}\n")
            out.append("| type | default | allowed |\n|---|---|---|")
            out.append(f"| {_type(node)} | {_default(node, sec in schema.get('required', []))} "
                       f"| {_allowed(node) or '–'} |\n")
            continue
        out.append(f"{desc}\n")
        out.append("| key | type | default | allowed | meaning |\n|---|---|---|---|---|")
        req = set(node.get("required", []))
        for key, sub in node.get("properties", {}).items():
            meaning = " ".join(str(sub.get("description", "")).split())
            props = sub.get("properties", {})
            if sub.get("type") == "object" and set(props) <= set(P.PARAMS) and props:
                items = ", ".join(f"`{k}` {_allowed(v) or _type(v)}" for k, v in props.items())
                meaning = f"{meaning} Keys, each optional: {items}.".strip()
            out.append(f"| `{key}` | {_type(sub)} | {_default(sub, key in req)} | "
                       f"{_allowed(sub) or '–'} | {meaning or '–'} |")
            if sub.get("type") == "object" and props and not set(props) <= set(P.PARAMS):
                out += _nested(key, sub)  # a subsection: its keys as key.sub rows
        out.append("")
    return "\n".join(out).rstrip() + "\n"

