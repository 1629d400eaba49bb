"""The one seed scheme of a card's packings, and the one retry loop.

Every packing a card's tests use derives from a packing seed s (a design row's, a
closed-loop or fresh seed) by three offsets, composed in this order:

- **replicate** j (:func:`replicate_seed`): specimen j of a tensile strength measured on
  several specimens (``tensile_specimens``), s + j x :data:`REPLICATE_STRIDE` (j = 0: s
  itself, the UCS test's packing);
- **replacement** m (:func:`replacement_seed`): a per-sample test's run file that was
  invalid (its fracture not where the test needs it) replaced by a new run on
  + m x :data:`REPLACEMENT_STRIDE`, m <= :data:`MAX_REPLACEMENTS` (``stages.measure``);
- **retest** k (:func:`retest_seed`): a Brazilian disc discarded by the ISRM rule inside
  one Brazilian test and another disc tested, + k x :data:`RETEST_STEP` (mod 2**32),
  k <= ``BTSSettings.retests`` (``runner.bts_test``).

:func:`packing_seed_gap` shows that no two of them share a packing for seeds closer than
its gap (the replicate stride was 1,000,000: then retest 1 of seed s, s + 1,000,003, was
specimen 1 of seed s + 3, and two seeds shared that disc).

Both retries, the test's ISRM retest and the stage's replacement, are :func:`retry`: the
one loop that runs attempts until one is usable. They stay two levels because they are
two things: a retest is the laboratory's practice within one Brazilian test (one run
file, recording ``discs`` and ``discarded``), a replacement is the study's, for every
test with a validity check (direct tension too), and writes a run file per attempt that
the closed loop's journal and seed tables name (``<test>_seed``, ``<test>_invalid``).
"""
from __future__ import annotations

#: the step between the packing seeds of a Brazilian test's successive discs (a large
#: prime, so that the retest discs of neighbouring seeds do not coincide)
RETEST_STEP = 1_000_003
#: an invalid per-sample run is replaced on seed + m x REPLACEMENT_STRIDE (m = 1, 2, ...),
#: at most MAX_REPLACEMENTS times, before the seed's strength counts as a failed measurement
REPLACEMENT_STRIDE = 100_000
MAX_REPLACEMENTS = 3
#: specimen j of a tensile strength on several specimens: seed + j x REPLICATE_STRIDE.
#: The stride keeps every packing seed of every seed below 100,000 apart from every other
#: (:func:`packing_seed_gap`: the smallest difference of two offsets is the replacement
#: stride) and below 2**32
REPLICATE_STRIDE = 20_000_003


def retest_seed(seed: int, k: int) -> int:
    """The packing seed of the ``k``-th disc tested after an invalid one (``k`` = 0: the
    first disc, ``seed`` itself), in [0, 2**32)."""
    return (int(seed) + int(k) * RETEST_STEP) % 2 ** 32


def replacement_seed(seed: int, m: int) -> int:
    """The packing seed of the ``m``-th replacement of an invalid run on ``seed``."""
    return int(seed) + int(m) * REPLACEMENT_STRIDE


def replicate_seed(seed: int, j: int) -> int:
    """The packing seed of specimen ``j`` (0, 1, ...) of packing ``seed``'s tensile test."""
    return int(seed) + int(j) * REPLICATE_STRIDE


def packing_seed_gap(max_specimens: int, max_retests: int = 10) -> tuple[int, int]:
    """(the smallest nonzero difference between two offsets from a packing seed, the
    largest offset) over every replicate j < ``max_specimens``, replacement m <=
    :data:`MAX_REPLACEMENTS` and retest k <= ``max_retests`` (the offset j x
    REPLICATE_STRIDE + m x REPLACEMENT_STRIDE + k x RETEST_STEP): two seeds closer than
    the gap never share a packing, and a seed below 2**32 minus the largest offset stays a
    valid packing seed."""
    steps = (REPLICATE_STRIDE, REPLACEMENT_STRIDE, RETEST_STEP)
    reach = (max_specimens - 1, MAX_REPLACEMENTS, max_retests)
    gap = min(abs(a * steps[0] + b * steps[1] + c * steps[2])
              for a in range(-reach[0], reach[0] + 1) for b in range(-reach[1], reach[1] + 1)
              for c in range(-reach[2], reach[2] + 1) if (a, b, c) != (0, 0, 0))
    return gap, sum(r * s for r, s in zip(reach, steps))


def retry(attempt, tries: int, usable, discard=None):
    """The one retry loop: ``attempt(k)`` for k = 0, 1, ... until its result is
    ``usable(result)`` or ``tries`` attempts ran; ``discard(k, result)`` is told of each
    unusable result before the next attempt (the results are not kept: a lab run holds
    its particles). Returns (the last result, its k)."""
    if tries < 1:
        raise ValueError(f"tries={tries!r}: expected at least one attempt")
    for k in range(tries):
        r = attempt(k)
        if usable(r) or k == tries - 1:
            return r, k
        if discard is not None:
            discard(k, r)
