"""The posterior over a card's free parameters given its lab targets (issue: "How sure is
the card"). One concept per module:

- :mod:`.gp` — :class:`BasisGP`, a Gaussian process with an explicit (stepwise) basis and
  per-point noise, fitted by type-II maximum likelihood;
- :mod:`.surrogate` — the runs of a response as points, the ``gp`` and ``stepwise``
  surrogates and the held-out test that chooses between them (:func:`fit_surrogate`);
- :mod:`.sampler` — emcee to convergence (R-hat, ESS, autocorrelation) (:func:`sample`);
- :mod:`.identify` — what the targets pin and leave free (:func:`identifiability`) and
  which test would pin the rest (:func:`best_test`);
- :mod:`.posterior` — the likelihood, the posterior and the reach test
  (:func:`fit_posterior` → :class:`PosteriorResults`).

The method: ``docs/methods/posterior.md``. Pure: no files.
"""
from .gp import BasisGP, fit_basis_gp
from .identify import best_test, identifiability
from .posterior import (
    REACH_ALPHA,
    PosteriorResults,
    PosteriorSettings,
    Problem,
    fit_posterior,
    reach_test,
)
from .sampler import Chains, sample
from .surrogate import (
    LOG_RESPONSES,
    SOURCES,
    TENSILE_SHARE,
    ResponseSurrogate,
    fit_surrogate,
    from_scale,
    tensile_share,
    to_scale,
)

__all__ = ["BasisGP", "fit_basis_gp", "best_test", "identifiability", "REACH_ALPHA",
           "PosteriorResults", "PosteriorSettings", "Problem", "fit_posterior", "reach_test",
           "Chains", "sample", "LOG_RESPONSES", "SOURCES", "TENSILE_SHARE", "ResponseSurrogate",
           "fit_surrogate", "from_scale", "tensile_share", "to_scale"]
