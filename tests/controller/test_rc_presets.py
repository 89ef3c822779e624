"""Pilot presets from RC_CHANNELS bands."""

from __future__ import annotations

import re

import pytest
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


def named(tmp_path, **extra):
    band = {"min_us": 1700, "max_us": 2100, "tau_up_nm": 1.2, "tau_down_nm": 2.0, **extra}
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump({"rc_presets": {"enabled": True, "channel": 8, "presets": [band]}}))
    return p


def test_a_named_preset_carries_the_uphill_angle_and_is_checked_like_the_tables(tmp_path):
    from slopelander.controller.landing import PresetError, choose_leg_preset
    from slopelander.legs.calibration import load_calibration

    cfg = load_config(named(tmp_path, name="steep roof", angle_up_deg=22.5))
    sel = preset_for(cfg, rc(1900))
    assert (sel.name, sel.angle_up_deg, sel.tau_up_nm) == ("steep roof", 22.5, 1.2)
    chosen = choose_leg_preset(40, 2.0, None, sel, load_calibration())
    assert chosen.angle_up_deg == 22.5 and chosen.source == "pilot preset 'steep roof'"
    # without a name or an angle: numbered, and any angle will do (as before)
    plain = preset_for(load_config(named(tmp_path)), rc(1900))
    assert plain.name == "preset 1" and plain.angle_up_deg is None
    # an angle the legs cannot take is refused before the flight, naming the range
    _, hi = load_calibration().angle_range_deg
    far = preset_for(load_config(named(tmp_path, angle_up_deg=min(90.0, hi + 5.0))), rc(1900))
    with pytest.raises(PresetError, match=r"pilot preset 'preset 1'.*outside the range"):
        choose_leg_preset(40, 2.0, None, far, load_calibration())


@pytest.mark.parametrize(
    ("extra", "field"),
    [
        ({"angle_up_deg": 120}, "angle_up_deg"),
        ({"angle_up_deg": "steep"}, "angle_up_deg"),
        ({"angle_up_deg": True}, "angle_up_deg"),
        ({"name": ""}, "name"),
        ({"name": 7}, "name"),
        ({"name": "x" * 21}, "name"),
        ({"colour": "red"}, "presets[0]"),
    ],
)
def test_bad_named_presets_are_refused_with_the_field(tmp_path, extra, field):
    from slopelander.controller.config import ConfigError

    with pytest.raises(ConfigError, match=re.escape(field)):
        load_config(named(tmp_path, **extra))
