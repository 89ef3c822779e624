"""The companion's serial port and its MAVLink instance in f450-fsa.parm, by ArduPilot's numbering.

ArduPilot numbers its MAVLink instances by counting, from SERIAL0 up, the serial ports whose
SERIALn_PROTOCOL is a MAVLink one (GCS::setup_uarts, ``find_serial(SerialProtocol_MAVLink, i)``;
AP_SerialManager::protocol_match counts MAVLink 1, MAVLink 2 and high-latency MAVLink alike), and
instance i takes its stream rates from the MAV{i+1}_ parameters (4.7; SR{i}_ before). SERIAL0 (USB)
is always MAVLink. So the companion on TELEM2 (SERIAL2), with TELEM1 a MAVLink radio, is MAV3_:
MAV2_ would set the radio's rates (50 Hz raw sensors on a 57600 baud radio link).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PARM = REPO / "firmware_params" / "f450-fsa.parm"
#: ArduPilot's parameter documentation, in the reference folder (the ``reference`` fixture:
#: $SLOPELANDER_ARDUPILOT_REFERENCE, else shared/reference beside or above the checkout)
PARAMS_DOC = "ardupilot-copter-params.tsv"


def read_parm(path: Path) -> dict[str, tuple[float, str]]:
    """NAME -> (value, comment) of a .parm file."""
    out = {}
    for line in path.read_text().splitlines():
        body, _, comment = line.partition("#")
        if body.strip():
            name, value = re.split(r"[\s,]+", body.strip())
            out[name] = (float(value), comment.strip())
    return out


def mavlink_protocols(params_doc: Path) -> set[int]:
    """The SERIALn_PROTOCOL values that make a port MAVLink, from ArduPilot's parameter documentation."""
    for line in params_doc.read_text().splitlines():
        cells = line.split("\t")
        if cells[0] == "SERIAL1_PROTOCOL":
            pairs = (v.split("=", 1) for v in cells[3].split(";") if "=" in v)
            return {int(k) for k, name in pairs if name.startswith("MAVLink")}
    raise AssertionError("SERIAL1_PROTOCOL missing from the reference")


def companion_instance(parm: dict[str, tuple[float, str]], mav: set[int]) -> tuple[int, int]:
    """(serial port number, MAVn_ number) of the port whose protocol line names the companion."""
    ports = [
        int(m.group(1))
        for name, (_, comment) in parm.items()
        if (m := re.fullmatch(r"SERIAL(\d+)_PROTOCOL", name)) and "companion" in comment
    ]
    assert len(ports) == 1, f"exactly one SERIALn_PROTOCOL line should name the companion, got {ports}"
    port = ports[0]
    assert int(parm[f"SERIAL{port}_PROTOCOL"][0]) in mav, "the companion's port must speak MAVLink"
    count = 1  # SERIAL0 is always MAVLink
    for n in range(1, port + 1):
        key = f"SERIAL{n}_PROTOCOL"
        assert key in parm, f"{key} is not set: the companion's MAVLink instance depends on it"
        count += int(parm[key][0]) in mav
    return port, count


@pytest.mark.parametrize("path", [PARM, PARM.with_name("sitl.parm")], ids=lambda p: p.name)
def test_the_companion_streams_are_set_on_its_own_mavlink_instance(path: Path, reference: Path):
    parm = read_parm(path)
    mav = mavlink_protocols(reference / PARAMS_DOC)
    assert {1, 2} <= mav
    port, n = companion_instance(parm, mav)
    assert (port, n) == (2, 3)  # TELEM2, behind USB and the TELEM1 radio
    rates = {name for name in parm if re.fullmatch(r"MAV\d+_\w+", name)}
    assert rates, "no stream rates set for the companion"
    wrong = sorted(r for r in rates if not r.startswith(f"MAV{n}_"))
    assert not wrong, f"stream rates on another MAVLink instance than the companion's MAV{n}_: {wrong}"
    names = {line.split("\t")[0] for line in (reference / PARAMS_DOC).read_text().splitlines()[2:]}
    assert {f"SERIAL{port}_PROTOCOL", f"SERIAL{port}_BAUD", *rates} <= names


def test_the_instance_count_follows_ardupilots_rule():
    """The rule itself, on port layouts where the answer is known."""
    mav = {1, 2}
    base = {"SERIAL2_PROTOCOL": (2.0, "the companion")}
    assert companion_instance({**base, "SERIAL1_PROTOCOL": (2.0, "radio")}, mav) == (2, 3)
    assert companion_instance({**base, "SERIAL1_PROTOCOL": (5.0, "GPS")}, mav) == (2, 2)
    with pytest.raises(AssertionError, match="SERIAL1_PROTOCOL is not set"):
        companion_instance(base, mav)
