"""The error of an invalid study configuration or lab table, in a leaf module that
``study.config`` and ``study.lab_data`` both import (neither imports the other's error)."""


class ConfigError(ValueError):
    """The study configuration is invalid; the message lists every problem by key."""
