"""The simulated board on an external clock: board time is only what the vehicle feeds it.

In-process on a real pty (no wall-clock timing; the firmware on this CPython, so a test can
look at the plant), plus one board process that is fed no time.
"""

from __future__ import annotations

import math
import os
import select
import time

import pytest

from slopelander.legs import codec, messages
from slopelander_sitl.legboard.control import BoardControl, ControlError
from slopelander_sitl.legboard.server import MAX_ADVANCE_S, BoardServer, FaultSpec

TICK_S = 0.004  # the firmware's tick


@pytest.fixture
def external():
    """A board on the external clock, its firmware in this process, opened; closed at the end."""
    made = []

    def make(**kw) -> BoardServer:
        srv = BoardServer(clock="external", runtime="cpython", **kw)
        srv.open()
        made.append(srv)
        return srv

    yield make
    for srv in made:
        srv.close()


def test_board_time_follows_the_times_fed_and_never_goes_back(external):
    srv = external()
    start = srv.control({"op": "state"})["time_s"]
    assert 0.0 < start < 0.1  # the firmware's power-up probe, before anyone can talk to it
    reply = srv.control({"op": "advance", "to_s": 1.25})
    assert reply["ok"] and reply["clock"] == "external" and reply["clock_s"] == 1.25
    # the firmware ticks every 4 ms: board time is the last tick not past the time fed
    assert 1.25 - TICK_S < reply["time_s"] <= 1.25 + 1e-9
    assert len(reply["legs"]) == messages.N_LEGS and reply["runtime"] == "cpython"
    held = srv.control({"op": "advance", "to_s": 0.5})  # a time behind the board's holds it
    assert held["time_s"] == reply["time_s"] and held["clock_s"] == 1.25
    assert srv.advance(1.25) == reply["time_s"]


@pytest.mark.parametrize(
    "to_s, error",
    [
        (math.nan, "finite"),
        (math.inf, "finite"),
        ("soon", "could not convert"),
        (MAX_ADVANCE_S + 1.0, "ahead of board time"),
    ],
)
def test_bad_times_are_refused_with_a_reason_and_leave_the_board_alone(external, to_s, error):
    srv = external()
    before = srv.time_s()
    with pytest.raises(ValueError, match=error):
        srv.advance(to_s)
    state = srv.state()
    assert state["time_s"] == before and state["clock_s"] is None


def test_a_wall_clock_board_refuses_to_be_fed_time():
    srv = BoardServer()
    with pytest.raises(ValueError, match="--clock external"):
        srv.advance(1.0)
    with pytest.raises(ValueError, match="unknown clock"):
        BoardServer(clock="vehicle")


def test_scheduled_faults_fall_due_in_fed_time(external):
    srv = external(faults=(FaultSpec.parse("stuck:1@0.5"),))
    plant = srv.runner.board.plant
    srv.advance(0.49)
    assert not plant.legs[1].stuck
    srv.advance(0.51)
    assert plant.legs[1].stuck and not plant.legs[0].stuck


def _frames(fd: int, want: int, decoder: codec.Decoder) -> list:
    """Frames from the pty until ``want`` have arrived (bytes the board already wrote; the
    deadline only ends a failing test)."""
    got: list = []
    deadline = time.monotonic() + 10.0
    while len(got) < want and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.5)
        if ready:
            got += [f.message for f in decoder.feed(os.read(fd, 4096))]
    return got


def test_status_reports_come_at_the_fed_board_times_and_stop_when_time_stands_still(external):
    srv = external()
    fd = os.open(srv.slave_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        os.write(fd, codec.encode(messages.Hello(messages.PROTOCOL_VERSION, 100), 1))
        deadline = time.monotonic() + 10.0
        while not srv.runner.board.fw.hello and time.monotonic() < deadline:
            srv._wait_io(0.5)
        dec = codec.Decoder()
        first = _frames(fd, 2, dec)
        assert isinstance(first[0], messages.HelloReply), first
        t0 = first[0].board_time_ms
        assert isinstance(first[1], messages.Status) and first[1].board_time_ms == t0  # at once
        srv.advance(t0 / 1000 + 1.0)
        reports = _frames(fd, 10, dec)
        assert [r.board_time_ms for r in reports] == list(range(t0 + 100, t0 + 1001, 100)), reports
        srv.advance(t0 / 1000 + 1.0)  # the same time again: nothing new is due
        srv._wait_io(0.0)
        assert _frames_now(fd, dec) == []
    finally:
        os.close(fd)


def _frames_now(fd: int, decoder: codec.Decoder) -> list:
    ready, _, _ = select.select([fd], [], [], 0.2)
    return [f.message for f in decoder.feed(os.read(fd, 4096))] if ready else []


def test_a_board_process_fed_no_time_stands_still(sim_board):
    board = sim_board("--clock", "external")
    with BoardControl(board.control) as ctl:
        before = ctl.state()
        assert before["clock"] == "external" and before["clock_s"] is None
        # the observation window is wall time; on the wall clock at 20x this would be 10 s of board time
        time.sleep(0.5)
        after = ctl.state()
        assert after["time_s"] == before["time_s"] < 0.1
        reply = ctl.advance(0.2)
        assert 0.2 - TICK_S < reply["time_s"] <= 0.2 + 1e-9
        with pytest.raises(ControlError, match="finite"):
            ctl.advance(math.nan)
        assert ctl.state()["time_s"] == reply["time_s"]
