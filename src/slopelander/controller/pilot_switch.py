"""The pilot's preset switch during a landing: a change of the RC band re-applies that preset.

``slopelander land`` reads the switch once before the landing (:func:`rc_presets.preset_for`);
this watches it afterwards. When the selected band changes, the new torques go to the legs at
once (the board settles them in its own time) while the vehicle is not yet committed to the
touchdown: in PRESET, LEGS_WAIT, CHECKS and DESCEND (these go back to LEGS_WAIT, so the descent
pauses until every leg reports the new preset) and READY. Once the reflex is armed (ARMED and
after) or on the ground, a change is reported and ignored: the legs must not move under load.
Back to no band (centre, or the switch off) means the preset the landing was started with.
"""

from __future__ import annotations

from slopelander.controller.config import Config, RcPreset
from slopelander.controller.rc_presets import preset_for

APPLY_IN = ("PRESET", "LEGS_WAIT", "CHECKS", "DESCEND", "READY")
WAIT_AGAIN = ("CHECKS", "DESCEND")


class PresetSwitch:
    """Tracks the band the switch selects; :meth:`update` returns a change once."""

    def __init__(self, cfg: Config, first_msg=None) -> None:
        self.cfg = cfg
        self.selected: RcPreset | None = preset_for(cfg, first_msg)
        self._seen = first_msg

    def update(self, msg) -> tuple[bool, RcPreset | None]:
        """(changed, selected preset or None for the landing's own preset) for the newest RC_CHANNELS."""
        if msg is None or msg is self._seen or not self.cfg["rc_presets.enabled"]:
            return False, self.selected
        self._seen = msg
        sel = preset_for(self.cfg, msg)
        if sel == self.selected:
            return False, sel
        self.selected = sel
        return True, sel
