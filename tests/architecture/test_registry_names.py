"""The contact-model registry (``bpmcal.params``) is the only place in src/ that spells a
card parameter's name: every other module takes the names from it (``P.RMIN``,
``model.free``, ``model.strength``, ``model.material`` ...), so a model added to the
registry reaches the design, calibration, sweep, lab tests and engine material without an
edit elsewhere. A source scan of every string literal that is a registered parameter
name; docstrings and messages that mention a name inside a sentence are not literals of
a name. Two modules are exempt, for the reasons below."""
import ast
from pathlib import Path

import pytest

from bpmcal import params as P

SRC = Path(__file__).resolve().parents[2] / "src" / "bpmcal"
REGISTRY = SRC / "params.py"

#: module -> why it may spell names
EXEMPT = {
    "dem/material.py": "the engine's material: its fields are the contact laws' SI quantities "
                       "below the registry (pb_emod in Pa, not the card's pb_emod_GPa); the "
                       "dimensionless ones (pb_kratio, fric, fj_nr ...) coincide with a card name",
    "study/paper.py": "the paper's published Table 2 and equations, whose parameters are the "
                      "parallel-bond card's by definition",
}


def name_literals(text: str, names) -> list[str]:
    """``line N: 'name'`` for every string constant of ``text`` equal to one of ``names``,
    docstrings left out."""
    tree = ast.parse(text)
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and n.body and isinstance(n.body[0], ast.Expr)
            and isinstance(n.body[0].value, ast.Constant)}
    return sorted((f"line {n.lineno}: {n.value!r}" for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs
            and n.value in names), key=lambda s: int(s.split(":")[0][5:]))


SOURCES = sorted(p for p in SRC.rglob("*.py")
                 if p != REGISTRY and p.relative_to(SRC).as_posix() not in EXEMPT)


def test_the_registry_and_the_exempt_modules_are_there():
    assert REGISTRY.exists() and len(SOURCES) > 50
    for rel in EXEMPT:
        assert (SRC / rel).exists(), rel
    assert name_literals(REGISTRY.read_text(), P.ALL_PARAMS)  # the registry does spell them


@pytest.mark.parametrize("path", SOURCES, ids=[p.relative_to(SRC).as_posix() for p in SOURCES])
def test_no_module_outside_the_registry_spells_a_parameter_name(path):
    bad = name_literals(path.read_text(), P.ALL_PARAMS)
    assert not bad, (f"{path.relative_to(SRC)} spells parameter names (take them from "
                     "bpmcal.params: P.RMIN, model.free, model.strength, ...): " + "; ".join(bad))


def test_the_scan_can_fail():
    text = ('"""A docstring naming pb_coh_MPa is prose."""\n'
            'x = p["pb_coh_MPa"]\n'
            'free = ("fj_emod_GPa", "fj_kratio")\n'
            'msg = f"calibration.fixed.rmin_mm {v}"\n'  # a name inside a sentence: prose
            'key = "fj_nr"\n')
    assert name_literals(text, P.ALL_PARAMS) == [
        "line 2: 'pb_coh_MPa'", "line 3: 'fj_emod_GPa'", "line 3: 'fj_kratio'", "line 5: 'fj_nr'"]
