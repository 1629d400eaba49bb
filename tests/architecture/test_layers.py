"""The layers of src/bpmcal only call downward (docs/architecture.md): every import in
every module, also one inside a function, names a module of its own layer or of a layer
below. A module that imports upward (e.g. dem/ importing lab/, a stage importing the
report) fails this test."""
import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "bpmcal"

#: the layers, bottom up (docs/architecture.md)
LAYERS = [
    {"bpmcal", "bpmcal.params", "bpmcal.portable"},
    {"bpmcal.dem"},
    {"bpmcal.io"},
    {"bpmcal.lab"},
    {"bpmcal.study"},
    {"bpmcal.analysis"},
    {"bpmcal.plots"},
    {"bpmcal.stages"},
    {"bpmcal.report"},
    {"bpmcal.cli"},
]


def layer_of(module: str) -> int:
    """The layer of a module of the package (its package's, or its own for a top module)."""
    parts = module.split(".")
    for depth in (2, 1):
        name = ".".join(parts[:depth])
        for i, layer in enumerate(LAYERS):
            if name in layer:
                return i
    raise KeyError(module)


def module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import of the package in a source file."""
    return imports_in(path.read_text(), module_name(path), path.name == "__init__.py")


def _is_module(name: str) -> bool:
    p = SRC.parent / Path(*name.split("."))
    return p.with_suffix(".py").exists() or p.is_dir()


def imports_in(text: str, mod: str, is_package: bool = False) -> list[tuple[int, str]]:
    """(line, absolute module) of every import of the package in ``text``, the source of
    module ``mod``, wherever it stands (also inside functions)."""
    package = mod if is_package else mod.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.startswith("bpmcal")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("bpmcal"):
                # "from . import x" / "from .io import layout": the imported names may be modules
                out.append((node.lineno, target))
                out += [(node.lineno, f"{target}.{a.name}") for a in node.names
                        if _is_module(f"{target}.{a.name}")]
    return out


SOURCES = sorted(SRC.rglob("*.py"))


def test_every_module_has_a_layer():
    for f in SOURCES:
        layer_of(module_name(f))


@pytest.mark.parametrize("path", SOURCES, ids=[str(f.relative_to(SRC)) for f in SOURCES])
def test_imports_only_go_down(path):
    me = layer_of(module_name(path))
    up = [f"line {line}: {target} (layer {layer_of(target)} > {me})"
          for line, target in imports(path) if layer_of(target) > me]
    assert not up, f"{path.relative_to(SRC)} imports upward: " + "; ".join(up)


def test_the_check_can_fail():
    """The parser sees relative, absolute and function-level imports: an engine module that
    imported the lab or a stage would be caught."""
    text = "def f():\n    from ..lab import runner\n    import bpmcal.stages.runs\n"
    found = [t for _, t in imports_in(text, "bpmcal.dem.probe")]
    assert "bpmcal.lab.runner" in found and "bpmcal.stages.runs" in found
    assert all(layer_of(t) > layer_of("bpmcal.dem.probe") for t in found)
