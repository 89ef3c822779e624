"""The companion-computer side: what runs on the vehicle during a landing.

Runtime dependencies only (numpy, pyyaml, the standard library): nothing here may import
scipy, matplotlib, numba, :mod:`slopelander.model` or :mod:`slopelander.envelope` at import time.
"""

from slopelander.controller.table import (
    SCHEMA as TABLE_SCHEMA,
)
from slopelander.controller.table import (
    LookupTable,
    OutOfTableRange,
    Preset,
    TableError,
)

__all__ = ["TABLE_SCHEMA", "LookupTable", "OutOfTableRange", "Preset", "TableError"]
