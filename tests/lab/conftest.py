from lab_util import cache  # noqa: F401  (fixture)
