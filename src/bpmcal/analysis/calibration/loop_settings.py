"""The closed loop's settings as one value: :class:`LoopSettings`, every option of a
closed loop on the DEM (``bpmcal verify``; the study's ``verification`` section), and
the one table of their limits that everything taking them shares: the dataclass
(validated once, when it is built), :class:`~.closed_loop.ClosedLoop`'s keywords
(:func:`check_loop_value`), the ``bpmcal verify`` and ``transfer`` options (generated from
the fields: ``bpmcal.cli.options.add_loop_args``) and the jobs' command line
(``bpmcal.cli.options.loop_argv``, through ``bpmcal.cli.jobs``). The config schema
states the same names, defaults and limits (``tests/workflow/test_defaults.py`` holds
them equal).

A new loop setting is a field here (its default, its :class:`Limit` and its help line),
its key in ``workflow/schemas/config.schema.yaml`` (with ``config/config.yaml`` and the
generated ``config/README.md``), and the code that uses it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from bpmcal.params import AUTO_ROUNDS, ROUNDS_PER_FREE

from ...io.checks import BadInput

#: the most tensile specimens a packing seed may measure σt on (``tensile_specimens``;
#: ``bpmcal.lab.seeds.packing_seed_gap`` proves their packings apart)
MAX_TENSILE_SPECIMENS = 50
#: the most rounds of a closed loop
MAX_ROUNDS = 50
#: how the measured rounds correct the closed loop's Jacobian (``step_rule.StepRule``)
UPDATES = ("broyden", "history")


def _number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
        v, (bool, np.bool_))


def _whole(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


@dataclass(frozen=True)
class Limit:
    """What a setting accepts: ``kind`` "int", "float", "bool" or "choice" (one of
    ``words``); a number within ``lo`` .. ``hi`` (None: unbounded; open ends as told), or
    one of ``words`` ("auto"); None too with ``null``. ``what`` says what the value is,
    in messages."""

    kind: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    null: bool = False
    words: tuple = ()
    what: str = ""

    @property
    def bounds(self) -> tuple:
        """(low, low open, high, high open): compared with the config schema's (tests)."""
        return (self.lo, self.lo_open, self.hi, self.hi_open)

    def _range(self) -> str:
        if self.kind == "int":
            if self.hi is None:
                return f"an integer >= {int(self.lo)}"
            return f"an integer in {int(self.lo)} .. {int(self.hi)}"
        a = "-inf" if self.lo is None else f"{self.lo:g}"
        b = "inf" if self.hi is None else f"{self.hi:g}"
        return (f"a number in {'(' if self.lo_open or self.lo is None else '['}{a}, {b}"
                f"{')' if self.hi_open or self.hi is None else ']'}")

    def expected(self) -> str:
        """What the setting accepts, as a message says it."""
        if self.kind == "bool":
            text = "true or false"
        elif self.kind == "choice":
            text = f"one of {', '.join(self.words)}"
        else:
            text = self._range() + "".join(f", or {w!r}" for w in self.words)
        if self.null:
            text += ", or none"
        return text + (f" ({self.what})" if self.what else "")

    def accepts(self, v) -> bool:
        if v is None:
            return self.null
        if self.kind == "bool":
            return isinstance(v, (bool, np.bool_))
        if isinstance(v, str) or self.kind == "choice":
            return isinstance(v, str) and v in self.words
        if not (_whole(v) if self.kind == "int" else _number(v)) or not math.isfinite(float(v)):
            return False
        x = float(v)
        low = self.lo is None or (x > self.lo if self.lo_open else x >= self.lo)
        high = self.hi is None or (x < self.hi if self.hi_open else x <= self.hi)
        return low and high

    def check(self, name: str, v):
        """``v`` as the setting ``name`` (int, float, bool or a word), or BadInput (a
        ValueError) naming it and what is expected."""
        if not self.accepts(v):
            raise BadInput(f"{name}={v!r}: expected {self.expected()}")
        if v is None or isinstance(v, str):
            return v
        return {"int": int, "float": float, "bool": bool}[self.kind](v)

    def parse(self, text: str, name: str):
        """A command-line value ``text`` of the option ``name`` as the setting (a number
        or a word; a bool is an option's switch, not parsed)."""
        if text in self.words:
            return text
        try:
            v = int(text, 10) if self.kind == "int" else float(text)
        except ValueError:
            v = None
        if v is None or not self.accepts(v):
            raise BadInput(f"{name}={text!r}: expected {self.expected()}")
        return self.check(name, v)


def _setting(default, limit: Limit, help: str, *, needs: tuple = ()):
    """A field of :class:`LoopSettings`: its ``default``, ``limit`` and ``help`` line (the
    command's: ``{d}`` the default, ``{stride}`` the tensile specimens' seed stride);
    ``needs``: when the workflow passes it (``tensile``:
    a σt target; ``triaxial``: a σ1 target; a field's name: that field set)."""
    return field(default=default, metadata={"limit": limit, "help": help, "needs": needs})


@dataclass(frozen=True)
class LoopSettings:
    """Every option of a closed loop on the DEM (module docs), validated when it is
    built (BadInput naming the field and what it accepts). What each does:
    :func:`bpmcal.stages.verification.verify` and ``docs/methods/calibration.md``."""

    seed: int = _setting(1, Limit("int", 0, 2 ** 32 - 1, what="a packing seed"),
                         "first packing seed of the DEM runs (default {d})")
    seeds_per_round: int = _setting(
        3, Limit("int", 1, 50, what="packing seeds per round"),
        "packing seeds per round (--seed, --seed + 1, ...); the loop steers their mean "
        "(default {d})")
    max_seeds: int = _setting(
        10, Limit("int", 1, 200, what="the most seeds of a grown seed set"),
        "the seed set may grow to this many seeds once the means are within --grow-within "
        "tolerances but their standard errors are too large to state them to --rtol "
        "(default {d}; at most --seeds-per-round: no growth)")
    grow_within: float = _setting(
        2.0, Limit("float", 1.0, what="a factor on the tolerance"),
        "the seed set grows once every mean is within this many tolerances (a few seeds' "
        "spread can understate the scatter, so close to the targets the loop steers the "
        "grown set, not those seeds; 1: only once within tolerance; default {d:g})")
    rtol: float = _setting(0.01, Limit("float", 0.0, 1.0, lo_open=True,
                                       what="a relative tolerance"),
                           "relative tolerance (default {d:g})")
    max_rounds: int | str = _setting(
        AUTO_ROUNDS, Limit("int", 1, MAX_ROUNDS, words=(AUTO_ROUNDS,),
                           what=f"{ROUNDS_PER_FREE} rounds per free parameter"),
        f"rounds at most, each of --seeds-per-round DEM runs, or {AUTO_ROUNDS} "
        f"({ROUNDS_PER_FREE} per free parameter: 6 for the paper's three, 8 with both "
        "strengths free; default {d})")
    range_margin: float = _setting(
        0.25, Limit("float", 0.0, 1.0, what="a fraction of a range's width"),
        "the closed loop may leave each design range (the card's ranges) by this fraction "
        "of its width, inside the parameter's physical domain and never past the card's "
        "calibration bounds; the card lists what ends outside (default {d:g}; 0: stay "
        "inside)")
    polish: bool = _setting(
        True, Limit("bool"),
        "when the loop converges with a mean more than one standard error from its target "
        "and a round is left, take one more full Newton step towards the targets on the "
        "same seeds; kept if within tolerance (default {d})")
    jacobian_update: str = _setting(
        "broyden", Limit("choice", words=UPDATES, what="the Jacobian's update rule"),
        "how the measured rounds correct the closed loop's Jacobian: broyden (the secant "
        "between consecutive rounds) or history (a local linear fit to every round, the "
        "regression's Jacobian its prior; docs/methods/calibration.md) (default {d})")
    tensile_specimens: int = _setting(
        3, Limit("int", 1, MAX_TENSILE_SPECIMENS, what="tensile specimens per packing seed"),
        "a seed's sigma_t (Brazilian or direct tension) is the mean of this many valid "
        "specimens, packed with seed + j x {stride:,}; the card records it and the "
        "transfer and the fresh-seed check measure sigma_t the same way (default {d})")
    tensile_seed_cv: float | None = _setting(
        None, Limit("float", 0.0, 1.0, lo_open=True, hi_open=True, null=True,
                    what="the seed CV of sigma_t to aim at; none: a fixed count"),
        "adapt the tensile specimens per seed to the card: once the specimens measured "
        "scatter too much for --tensile-specimens of them to average to this seed CV (read "
        "over 5 seeds, missed at most 1 time in 10), later seeds and the round just "
        "started get more, up to --max-tensile-specimens (default: a fixed count)",
        needs=("tensile",))
    max_tensile_specimens: int | None = _setting(
        None, Limit("int", 1, MAX_TENSILE_SPECIMENS, null=True,
                    what="the most tensile specimens per seed; none: tensile_specimens"),
        "the most tensile specimens per seed --tensile-seed-cv may ask for (default: "
        "--tensile-specimens, no raise)", needs=("tensile", "tensile_seed_cv"))
    triaxial_seeds: int | None = _setting(
        None, Limit("int", 2, 200, null=True,
                    what="how many of the loop's seeds run the triaxial test; none: every "
                         "seed"),
        "with a triaxial-strength target (tri_MPa), only the first N seeds of the loop's "
        "seed set run the triaxial test, so a set grown to --max-seeds judges the other "
        "targets on more packings (default: every seed)", needs=("triaxial",))
    from_unreachable: bool = _setting(
        False, Limit("bool"),
        "run the closed loop even when the card's inversion is unreachable (default: do "
        "not; the verified card says why)")

    def __post_init__(self):
        for f in fields(self):
            object.__setattr__(self, f.name, f.metadata["limit"].check(
                f.name, getattr(self, f.name)))

    @property
    def seeds(self) -> list[int]:
        """The packing seeds of a round: ``seed``, ``seed + 1``, ... (``seeds_per_round``)."""
        return [self.seed + i for i in range(self.seeds_per_round)]

    @property
    def most_tensile_specimens(self) -> int:
        """The most tensile specimens per seed an adaptive count may reach
        (``max_tensile_specimens``, never below ``tensile_specimens``)."""
        return max(self.max_tensile_specimens or self.tensile_specimens,
                   self.tensile_specimens)


#: field name -> its Limit (the one table of the closed loop's limits)
LIMITS = {f.name: f.metadata["limit"] for f in fields(LoopSettings)}


def check_loop_value(setting: str, value, name: str | None = None):
    """``value`` checked as the closed-loop setting ``setting`` (:data:`LIMITS`), or
    BadInput (a ValueError) naming it as ``name`` (default the setting's: a keyword of
    :class:`~.closed_loop.ClosedLoop` may be named otherwise, ``margin``, ``update``)."""
    return LIMITS[setting].check(name or setting, value)
