"""config/README.md documents every section and key of the config schema: its reference
part is the schema rendered by ``bpmcal.study.config.schema_reference``, and must be up to
date (regenerate it with the command the README names)."""
import re

from support.repo import REPO
from support.repo import SCHEMA as SCHEMA_FILE

from bpmcal.study.config import load_schema, schema_reference

SCHEMA = load_schema(SCHEMA_FILE)
README = (REPO / "config" / "README.md").read_text()


def keys(node, prefix=""):
    out = []
    for k, sub in node.get("properties", {}).items():
        out.append(f"{prefix}{k}")
        if prefix == "":
            out += keys(sub, f"{k}.")
    return out


def test_reference_is_the_schema_rendered():
    m = re.search(r"<!-- BEGIN schema reference -->\n(.*)<!-- END schema reference -->",
                  README, re.S)
    assert m, "config/README.md lost its reference markers"
    assert m.group(1) == schema_reference(SCHEMA), (
        "config/README.md is out of date: python -m bpmcal.study.config "
        "workflow/schemas/config.schema.yaml")


def test_every_section_and_key_is_documented_with_a_meaning():
    for k in keys(SCHEMA):
        section, _, key = k.partition(".")
        assert f"### `{section}`" in README, section
        if key:
            row = next((ln for ln in README.splitlines() if ln.startswith(f"| `{key}` |")), None)
            assert row is not None, k
            assert not row.rstrip().endswith("| – |"), f"{k}: no meaning in the schema"


def test_the_check_can_fail():
    broken = {**SCHEMA, "properties": {**SCHEMA["properties"],
                                       "compression": {**SCHEMA["properties"]["compression"], "properties": {
                                           **SCHEMA["properties"]["compression"]["properties"],
                                           "new_key": {"type": "number", "default": 1.0}}}}}
    assert schema_reference(broken) != schema_reference(SCHEMA)
