"""bpmcal.stages: one function per job of the workflow, above ``analysis`` and ``plots``.

A stage reads the files it is given, checks them and its output paths before any work
(bad input: one error naming the value, nothing written), calls ``lab``, ``analysis`` and
``plots``, and writes exactly the files it is given. File names come from
``bpmcal.io.study_files`` (the rules declare them), never from a stage.

- :mod:`.runs` — DEM run files (``ucs``, ``bts``, ``dtt``, ``triaxial``, ``impact``) and failure
  records;
- :mod:`.dataset` — the design and the gathered dataset (``study.smk``);
- :mod:`.screening`, :mod:`.regression`, :mod:`.calibration` — Tables 3 and 4, the cards
  (``analysis.smk``);
- :mod:`.verification` (the closed loop), :mod:`.seed_scatter`, :mod:`.verification_tables`
  (Tables 5, 6), :mod:`.transfer`, :mod:`.fresh_seeds` — the cards checked on the DEM
  (``analysis.smk``); :mod:`.loop_runs` — the closed loop's runs and their journal;
  :mod:`.measure` — a seed's measurements, the seed scheme and the DEM runners
  (``RUNNERS``) of all of them;
- :mod:`.posterior`, :mod:`.posterior_data`, :mod:`.predictive` — a card's posterior and
  its predictive runs (``posterior.smk``);
- :mod:`.ratio_sweep` — the strength-ratio sweep; :mod:`.impact_energy` — the impact
  analysis (both ``fracture.smk``);
- :mod:`.triaxial` — the cards' triaxial strength envelopes (``triaxial.smk``);
- :mod:`.inputs`, :mod:`.progress` — reading checked inputs; progress on stderr.
- :mod:`.pool` — a stage's independent runs (a round's seeds) side by side on its CPUs;
  :mod:`.journal` — the finished runs of a closed loop, read again when it resumes.

``docs/architecture.md`` shows how to add a stage.
"""
import inspect


def defaults_of(f) -> dict:
    """The keyword defaults of a function or class (its ``__init__``): how the stages and
    the ``bpmcal`` command take their defaults from the settings they set."""
    return {k: p.default for k, p in inspect.signature(f).parameters.items()
            if p.default is not inspect.Parameter.empty}
