"""Bidirectional ("3D") ESC: PWM in microseconds to the model's signed rotor command.

1500 +- 30 us is the neutral deadband (stopped); above it forward thrust command
(pwm - 1500) / 500, below it reverse. The model's rotors hold the reversal delay themselves.
"""

from __future__ import annotations

from collections.abc import Sequence

NEUTRAL_US = 1500
DEADBAND_US = 30
MIN_PULSE_US = 800
FRONT, REAR = (0, 2), (1, 3)  # ArduPilot quad X: motors 1, 3 front; 2, 4 rear (0-based channels)


def pwm_to_command(pwm: float) -> float:
    """Rotor command in [-1, 1] for a PWM pulse width in microseconds. Below 800 us there is no
    valid pulse (ArduPilot reports 0 for an output it does not drive): the ESC stays stopped."""
    if pwm < MIN_PULSE_US or abs(pwm - NEUTRAL_US) <= DEADBAND_US:
        return 0.0
    return max(-1.0, min(1.0, (pwm - NEUTRAL_US) / 500.0))


def command_to_pwm(u: float) -> int:
    """PWM that asks the ESC for rotor command ``u`` (inverse of ``pwm_to_command``)."""
    return round(NEUTRAL_US + 500.0 * max(-1.0, min(1.0, u)))


def planar_rotor_commands(pwm: Sequence[float]) -> tuple[float, float]:
    """(left, right) rotor commands of the planar model for the four motor outputs of a quad X:
    the rear pair is the model's left (-x) rotor, the front pair its right (+x) rotor."""
    rear = 0.5 * (pwm_to_command(pwm[REAR[0]]) + pwm_to_command(pwm[REAR[1]]))
    front = 0.5 * (pwm_to_command(pwm[FRONT[0]]) + pwm_to_command(pwm[FRONT[1]]))
    return rear, front
