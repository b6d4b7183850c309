"""The evaluation's default settings, importable without the evaluation itself (the daemon's CLI parser uses them)."""

DEFAULT_MATCH_DISTANCE_M = 2.0  # a track's centre within this of a vessel's hull footprint can match it
DEFAULT_MAX_DISTANCE_M = 100.0  # the daemon's [output] max_distance_m default
DEFAULT_MIN_RETURNS = 3  # returns in a 0.1 s window that make a vessel one to track (a cluster needs 3 points)
