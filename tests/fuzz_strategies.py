"""Hypothesis strategies and settings shared by the property tests of the parsers (``tests/test_fuzz_*.py``)."""

from __future__ import annotations

import random

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from tests.conftest import SHARED_FIXTURES
from tests.fuzz_targets import Target, mutate

# Each property test takes a few seconds: modest example counts, and no deadline, because a machine shared with
# other jobs can stall any single example (bench/fuzz.py measures the time per input instead).
FUZZ = settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example],
)

needs_public_captures = pytest.mark.skipif(
    not SHARED_FIXTURES.is_dir(),
    reason=f"public captures not found at {SHARED_FIXTURES} (set USV_TRACKER_SHARED to the shared/ folder)",
)

# Numbers where parsers break: zero, signs, the edges of the integer widths on the wire, floats past them.
EDGE_INTS = st.sampled_from(
    [0, 1, -1, 2, 7, 255, 256, 511, 512, 65535, 65536, 2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**63, 10**30]
)


def mutated(target: Target, which: str) -> st.SearchStrategy[bytes]:
    """Havoc mutations of the target's seeds ('own' or 'public'); hypothesis shrinks the mutation choices.

    The seeds are read when the first example is drawn, not when the test module is imported: where the public
    captures are absent their tests are skipped (``needs_public_captures``) and must not fail the collection."""

    def build() -> st.SearchStrategy[bytes]:
        seeds = target.seeds(which)
        assert seeds, f"{target.name} has no {which} seeds"
        return st.builds(
            lambda i, rnd: mutate(seeds[i % len(seeds)], rnd, seeds, target.max_len),
            st.integers(0, len(seeds) - 1),
            st.randoms(use_true_random=False),
        )

    return st.deferred(build)


def randoms() -> st.SearchStrategy[random.Random]:
    return st.randoms(use_true_random=False)
