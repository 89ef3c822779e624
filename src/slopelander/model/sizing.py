"""The paper's energy sizing of the friction joints (Sec. III)."""

from __future__ import annotations

import math


def required_joint_torque(
    mass: float, speed: float, travel_deg: float, joints: int = 4, safety: float = 1.2
) -> float:
    """Friction torque per joint (N*m) so that ``joints`` joints sliding through their
    travel dissipate the impact's kinetic energy with a safety factor: W = tau * dtheta."""
    if mass <= 0 or speed < 0 or travel_deg <= 0 or joints < 1 or safety <= 0:
        raise ValueError("mass, travel, joints and safety must be positive, speed not negative")
    energy = 0.5 * mass * speed * speed
    return safety * energy / (joints * math.radians(travel_deg))
