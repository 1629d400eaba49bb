"""No function in src/bpmcal takes more than :data:`MAX_PARAMETERS` parameters (``self``
and ``cls`` not counted; ``*args``/``**kwargs`` count one each), outside the numba
kernels (decorated ``@jit``, ``@jit_parallel``, ``@njit`` or the inlined ``@_inl``: their arguments are the
engine's arrays, structure-of-arrays by design); there are no exceptions. A setting that
crosses several functions travels as one settings value (a frozen dataclass), not as one
more parameter of each: a new long signature fails this test (issue 54)."""
import ast
from pathlib import Path

import pytest
from support.source import functions

SRC = Path(__file__).resolve().parents[2] / "src" / "bpmcal"
MAX_PARAMETERS = 12
KERNEL_DECORATORS = {"jit", "jit_parallel", "njit", "_inl"}

def _decorator_name(d) -> str:
    node = d.func if isinstance(d, ast.Call) else d
    return node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")


def parameter_counts(text: str) -> list[tuple[str, int]]:
    """(qualified name, parameters) of every function in ``text`` that is no numba kernel,
    nested functions and methods included."""
    out = []
    for name, fn in functions(text):
        if {_decorator_name(d) for d in fn.decorator_list} & KERNEL_DECORATORS:
            continue
        a = fn.args
        names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
        n = len(names) - (1 if names[:1] in (["self"], ["cls"]) else 0)
        out.append((name, n + (a.vararg is not None) + (a.kwarg is not None)))
    return out


SOURCES = sorted(SRC.rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=[str(f.relative_to(SRC)) for f in SOURCES])
def test_no_long_signature(path):
    rel = path.relative_to(SRC).as_posix()
    bad = [f"{name} ({n})" for name, n in parameter_counts(path.read_text())
           if n > MAX_PARAMETERS]
    assert not bad, (f"{rel}: functions with more than {MAX_PARAMETERS} parameters: "
                     f"{', '.join(bad)} (pass a settings value instead)")


def test_the_check_can_fail():
    args = ", ".join(f"a{i}" for i in range(13))
    text = (f"def f({args}):\n    pass\n\nclass C:\n    def m(self, {args}):\n        pass\n"
            f"\n@jit\ndef k({args}):\n    pass\n\ndef g(*a, **k):\n    pass\n")
    assert parameter_counts(text) == [("f", 13), ("C.m", 13), ("g", 2)]
