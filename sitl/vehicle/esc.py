"""Bidirectional ("3D") ESC: PWM in microseconds to the model's signed rotor command.

1500 +- 30 us is the neutral deadband (stopped); above it forward thrust command
(pwm - 1500) / 500, below it reverse. The model's rotors hold the reversal delay themselves.
"""

from __future__ import annotations

NEUTRAL_US = 1500
DEADBAND_US = 30


def pwm_to_command(pwm: float) -> float:
    """Rotor command in [-1, 1] for a PWM pulse width in microseconds."""
    if abs(pwm - NEUTRAL_US) <= DEADBAND_US:
        return 0.0
    return max(-1.0, min(1.0, (pwm - NEUTRAL_US) / 500.0))


def command_to_pwm(u: float) -> int:
    """PWM that asks the ESC for rotor command ``u`` (inverse of ``pwm_to_command``)."""
    return round(NEUTRAL_US + 500.0 * max(-1.0, min(1.0, u)))
