"""Test-wide settings.

Hypothesis runs derandomized by default, so the test command gives the same verdict on every run
and every machine; ``HYPOTHESIS_PROFILE=explore`` draws fresh examples to hunt for new failures."""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))
