"""Pilot presets from RC_CHANNELS bands."""

from __future__ import annotations

import yaml
from pymavlink.dialects.v20 import ardupilotmega as m

from slopelander.controller.config import load_config
from slopelander.controller.rc_presets import preset_for


def rc(ch8: int, count: int = 8):
    chans = [1500] * 18
    chans[7] = ch8
    return m.MAVLink_rc_channels_message(1000, count, *chans, 255)


def test_bands_select_presets(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text(
        yaml.safe_dump(
            {
                "rc_presets": {
                    "enabled": True,
                    "channel": 8,
                    "presets": [
                        {"min_us": 900, "max_us": 1300, "tau_up_nm": 0.5, "tau_down_nm": 1.0},
                        {"min_us": 1700, "max_us": 2100, "tau_up_nm": 1.2, "tau_down_nm": 2.0},
                    ],
                }
            }
        )
    )
    cfg = load_config(p)
    assert preset_for(cfg, rc(1100)).tau_up_nm == 0.5
    assert preset_for(cfg, rc(1900)).tau_down_nm == 2.0
    assert preset_for(cfg, rc(1500)) is None  # middle: the table decides
    assert preset_for(cfg, rc(65535)) is None  # unused channel
    assert preset_for(cfg, rc(1100, count=6)) is None  # channel not delivered
    assert preset_for(load_config(), rc(1100)) is None  # switch disabled by default
