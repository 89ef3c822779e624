"""The leg board: serial protocol, torque ↔ current calibration and the driver.

``slopelander.legs.codec`` is shared with the simulated board (``sitl.legboard``); the
driver needs only pyserial and pyyaml (no scipy), so it runs on the companion.
"""

from slopelander.legs.calibration import Calibration, LegCurve, load_calibration
from slopelander.legs.driver import (
    BoardInfo,
    BoardStatus,
    LegBoard,
    LegResult,
    LegStatus,
    Operation,
    PairMap,
)
from slopelander.legs.errors import (
    BoardDisconnected,
    CalibrationError,
    CommandRejected,
    LegBoardError,
    LegFault,
    LegNotConverged,
    LegTimeout,
    ProtocolError,
    TorqueOutOfRange,
)

__all__ = [
    "BoardDisconnected",
    "BoardInfo",
    "BoardStatus",
    "Calibration",
    "CalibrationError",
    "CommandRejected",
    "LegBoard",
    "LegBoardError",
    "LegCurve",
    "LegFault",
    "LegNotConverged",
    "LegResult",
    "LegStatus",
    "LegTimeout",
    "Operation",
    "PairMap",
    "ProtocolError",
    "TorqueOutOfRange",
    "load_calibration",
]
