"""TI AWR1843 (xWR18xx and compatible) out-of-box mmWave demo: CLI configuration, data-port frames.

Modules, one job each:

* ``profile``  parses a TI ``.cfg`` and derives the chirp design numbers (frame period, bins, v_max).
* ``cli``      drives the text CLI port (one line in flight, prompt-synchronised).
* ``parser``   turns the binary data-port stream into ``RadarFrame`` objects (and encodes frames for tests).
* ``expected`` says which frames belong to the configuration sent (chip, firmware, TLVs, range bins).
* ``sources``  live serial source and file replay behind one ``frames(stop)`` iterator.
* ``inspect``  per-frame summaries of a raw data-port dump (``usv-tracker decode``).
"""

from __future__ import annotations

from drivers.awr1843.errors import RadarConfigError, RadarPortError, RadarProfileError

__all__ = ["RadarConfigError", "RadarPortError", "RadarProfileError"]
