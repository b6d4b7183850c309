"""The one error a tracker's configuration raises: a value that cannot work, named in the message."""

from __future__ import annotations


class ConfigError(ValueError):
    """A tracker configuration value that cannot work; the message names the key and why.

    A ValueError, so callers that only know "bad value" still catch it; the daemon's own ConfigError (a list of
    problems from a whole TOML file) derives from it.
    """
