from dem_util import mat  # noqa: F401  (fixture)
