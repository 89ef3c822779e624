"""The pilot's preset switch: an RC channel's PWM band picks a torque preset from the settings.

A channel that is unused (0 or 65535 in RC_CHANNELS), outside every band, or a switch turned off
(``rc_presets.enabled: false``) selects nothing: the lookup table decides.
"""

from __future__ import annotations

from slopelander.controller.config import Config, RcPreset

UNUSED = (0, 65535)


def pwm_of(msg, channel: int) -> int | None:
    """The PWM (µs) of a 1-based channel in an RC_CHANNELS message, None if unused or absent."""
    if not 1 <= channel <= 18 or msg.get_type() != "RC_CHANNELS" or channel > msg.chancount:
        return None
    v = getattr(msg, f"chan{channel}_raw")
    return None if v in UNUSED else int(v)


def preset_for(cfg: Config, msg) -> RcPreset | None:
    """The pilot's preset selected by ``msg`` (RC_CHANNELS), or None to use the table."""
    if not cfg["rc_presets.enabled"] or msg is None:
        return None
    pwm = pwm_of(msg, int(cfg["rc_presets.channel"]))
    if pwm is None:
        return None
    for p in cfg.rc_presets:
        if p.min_us <= pwm < p.max_us:
            return p
    return None
