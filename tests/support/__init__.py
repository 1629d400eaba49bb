"""Helpers shared by the test folders (importable as ``support``: tests/ is on pytest's
pythonpath, see pyproject.toml): the paper's parameter set and small-specimen settings
(``support.paper``), and the repository, config merging and Snakemake runs
(``support.repo``). A folder's own helpers stay beside its tests."""
