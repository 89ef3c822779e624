"""The leg board: serial protocol, torque ↔ current calibration and the driver.

``slopelander.legs.codec`` is shared with the simulated board (``slopelander_sitl.legboard``); the
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
    AngleOutOfRange,
    BoardDisconnected,
    BoardReconnected,
    CalibrationError,
    CommandRejected,
    LegBoardError,
    LegFault,
    LegNotConverged,
    LegTimeout,
    OperationCancelled,
    OperationPending,
    OperationSuperseded,
    ProtocolError,
    TorqueOutOfRange,
    WriteQueueFull,
)

__all__ = [
    "AngleOutOfRange",
    "BoardDisconnected",
    "BoardInfo",
    "BoardReconnected",
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
    "OperationCancelled",
    "OperationPending",
    "OperationSuperseded",
    "PairMap",
    "ProtocolError",
    "TorqueOutOfRange",
    "WriteQueueFull",
    "load_calibration",
]
