"""``slopelander map`` and ``table`` live in :mod:`slopelander.envelope_cli`, outside this package,
so that parsing their arguments does not import the envelope's science (scipy, matplotlib)."""

from slopelander.envelope_cli import register, run_map, run_table, thrust_end

__all__ = ["register", "run_map", "run_table", "thrust_end"]
