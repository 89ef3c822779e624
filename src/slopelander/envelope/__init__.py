"""Landing envelopes, optimal presets and the lookup table (paper Sec. V as a tool).

>>> from slopelander.envelope import MapAxes, choose_presets      # doctest: +SKIP
>>> m = choose_presets(Model.default(), MapAxes.build(5, 0.25), "rvt")

Sweeps run on every local core (``run_sweep``) or on a Dask cluster (``client=``).
"""

from slopelander.envelope.axes import AxesError, MapAxes
from slopelander.envelope.cluster import ClusterError, ClusterVersionError
from slopelander.envelope.maps import (
    LandingMap,
    envelope_area,
    fly_presets,
    max_slope,
    reach_per_speed,
    summary,
)
from slopelander.envelope.presets import (
    STRATEGIES,
    TORQUE_LEVELS,
    Strategy,
    StrategyError,
    choose_presets,
    linear_uphill_angle,
    preset_score,
)
from slopelander.envelope.robustness import robustness_map
from slopelander.envelope.sweep import SweepError, run_sweep
from slopelander.envelope.table import build_table, neighbour_margin, write_table
from slopelander.envelope.uncertainty import parameter_sets, uncertainty_maps

__all__ = [
    "STRATEGIES",
    "TORQUE_LEVELS",
    "AxesError",
    "ClusterError",
    "ClusterVersionError",
    "LandingMap",
    "MapAxes",
    "Strategy",
    "StrategyError",
    "SweepError",
    "build_table",
    "choose_presets",
    "envelope_area",
    "fly_presets",
    "linear_uphill_angle",
    "max_slope",
    "neighbour_margin",
    "parameter_sets",
    "preset_score",
    "reach_per_speed",
    "robustness_map",
    "run_sweep",
    "summary",
    "uncertainty_maps",
    "write_table",
]
