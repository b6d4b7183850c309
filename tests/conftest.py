"""Shared test helpers: where the public captures live, and a skip when they are not there."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
OWN_FIXTURES = REPO / "tests" / "fixtures"
# CI clones the repo with shared/ beside it; a developer checkout has it one level up as well.
SHARED = Path(os.environ.get("USV_TRACKER_SHARED", REPO.parent / "shared"))
SHARED_FIXTURES = SHARED / "fixtures"


@pytest.fixture
def shared_fixtures() -> Path:
    if not SHARED_FIXTURES.is_dir():
        pytest.skip(f"public captures not found at {SHARED_FIXTURES} (set USV_TRACKER_SHARED to the shared/ folder)")
    return SHARED_FIXTURES
