"""The lab layer drives the engine only through the public API of ``dem.model.Model``
(docs/architecture.md): no module of src/bpmcal/lab/ touches the engine's
structure-of-arrays (``B`` balls, ``W`` walls, ``Bd`` bonds, ``S`` wall slots, ``P``
pairs) or its parameter vectors (``prm``, ``iprm``, ``eacc``) — whatever the name of the
variable holding the model. A source scan of every attribute access."""
import ast
from pathlib import Path

import pytest

LAB = Path(__file__).resolve().parents[2] / "src" / "bpmcal" / "lab"

#: engine internals of Model (attribute names of the model object)
INTERNALS = {"B", "W", "Bd", "S", "P", "prm", "iprm", "eacc"}


def internal_accesses(text: str) -> list[str]:
    """``line N: expr`` for every ``<anything>.<internal>`` attribute access in ``text``
    (also ``getattr(x, "<internal>")`` with a literal name)."""
    out = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Attribute) and node.attr in INTERNALS:
            out.append(f"line {node.lineno}: {ast.unparse(node)}")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in ("getattr", "setattr") and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and node.args[1].value in INTERNALS):
            out.append(f"line {node.lineno}: {ast.unparse(node)}")
    return out


SOURCES = sorted(LAB.rglob("*.py"))


def test_lab_modules_found():
    assert len(SOURCES) >= 5 and any(p.name == "triaxial.py" for p in SOURCES)


@pytest.mark.parametrize("path", SOURCES, ids=[p.name for p in SOURCES])
def test_lab_uses_only_the_model_api(path):
    bad = internal_accesses(path.read_text())
    assert not bad, (f"lab/{path.name} reaches into Model internals (use the Model "
                     "accessors): " + "; ".join(bad))


def test_the_scan_can_fail():
    """Reads, writes, indexing, chains through another object and getattr are caught;
    public accessors and unrelated names are not."""
    text = ("y = m.B.pos[:, 1]\n"
            "self.m.W.radv[w] = v\n"
            "ns = int(model.iprm[3])\n"
            "s = sp.model.Bd.state\n"
            "W = m.W\n"
            "f = getattr(m, 'S')\n"
            "ok = m.positions[:, 1] + m.wall_radius(w) + m.bond_states.sum() + m.Bx\n")
    bad = internal_accesses(text)
    assert [b.split(":")[0] for b in bad].count("line 1") == 1
    assert {b.split(":")[0] for b in bad} == {f"line {i}" for i in range(1, 7)}
