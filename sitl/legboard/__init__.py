"""The simulated leg board: physics, the protocol server on a pty, its control channel."""

from sitl.legboard.control import BoardControl, ControlError
from sitl.legboard.physics import BoardParams, LegBoardPhysics
from sitl.legboard.server import BoardServer, FaultSpec

__all__ = [
    "BoardControl",
    "BoardParams",
    "BoardServer",
    "ControlError",
    "FaultSpec",
    "LegBoardPhysics",
]
