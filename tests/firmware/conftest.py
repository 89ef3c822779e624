"""Fixtures of the firmware tests; the pieces they are made of live in script_bench.py (a module
with its own name, so that these tests import it whatever else pytest collects first)."""

from script_bench import bench, reference  # noqa: F401 - fixtures, registered by import
