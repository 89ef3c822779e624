"""The physics holds ArduPilot while the companion is behind
(src/slopelander_sitl/json_physics/companion_gate.py):
the waiting rule on real UDP sockets, the server holding a stand-in ArduPilot's frame until the
echo comes, and the pod's tap reading the echoes out of a MAVLink byte stream. Real ArduCopter
held by it: tests/json_physics/test_real_ardupilot.py."""

from __future__ import annotations

import socket
import threading
import time

import pytest
from pymavlink import mavutil

from slopelander_sitl.ardupilot.echo_tap import EchoTap
from slopelander_sitl.json_physics.ardupilot_side import ArduPilotSide
from slopelander_sitl.json_physics.companion_gate import (
    CATCH_UP_S,
    DESCENT_MPS,
    ECHO,
    GONE,
    LINGER_S,
    PITCH_RATE_RAD_S,
    CompanionGate,
    script_may_time,
)
from slopelander_sitl.json_physics.launch import free_udp_port, start_json_physics


def _echo(port: int, t_s: float) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(ECHO.pack(round(t_s * 1e6)), ("127.0.0.1", port))


@pytest.fixture
def gate():
    g = CompanionGate(0, lead_s=0.25, patience_s=0.6)
    yield g
    g.close()


def test_no_echo_no_wait_and_within_the_lead_no_wait(gate: CompanionGate) -> None:
    t0 = time.monotonic()
    gate.wait(100.0)  # nobody echoes: the physics runs free
    _echo(gate.port, 10.0)
    time.sleep(0.05)
    gate.wait(10.25)
    assert time.monotonic() - t0 < 0.2
    assert gate.holds == 0 and gate.echo_t == pytest.approx(10.0)


def test_past_the_lead_it_waits_for_the_echo_that_lets_it_on(gate: CompanionGate) -> None:
    _echo(gate.port, 10.0)
    sent: list[float] = []

    def later() -> None:
        time.sleep(0.15)
        _echo(gate.port, 10.05)  # not enough: 10.4 is still 0.35 s past it
        time.sleep(0.15)
        sent.append(time.monotonic())
        _echo(gate.port, 10.2)

    threading.Thread(target=later).start()
    gate.wait(10.4)
    done = time.monotonic()
    assert sent and sent[0] <= done < sent[0] + 0.1
    assert gate.holds == 1 and gate.give_ups == 0 and gate.echo_t == pytest.approx(10.2)


def test_a_silent_companion_is_given_up_after_the_patience_then_waited_for_again(
    gate: CompanionGate,
) -> None:
    _echo(gate.port, 10.0)
    t0 = time.monotonic()
    gate.wait(11.0)
    assert 0.55 < time.monotonic() - t0 < 0.9
    assert gate.give_ups == 1 and gate.echo_t is None
    gate.wait(12.0)  # runs free now
    _echo(gate.port, 11.9)  # the companion is back: held again past its lead
    t1 = time.monotonic()
    gate.wait(12.5)
    assert time.monotonic() - t1 > 0.5 and gate.give_ups == 2


def test_a_companion_that_read_everything_and_waits_lets_the_physics_run_another_lead(
    gate: CompanionGate,
) -> None:
    """The newest echo said again during a hold: the companion read its link dry and waits, so
    what the physics sent in its lead has not arrived (unsent while held). Both once waited for
    the other until the patience ran out. A repeat sent before the hold began says nothing."""
    _echo(gate.port, 10.0)
    _echo(gate.port, 10.0)  # before the hold: not counted
    threading.Timer(0.15, lambda: _echo(gate.port, 10.0)).start()
    t0 = time.monotonic()
    gate.wait(10.4)
    took = time.monotonic() - t0
    assert 0.1 < took < 0.45 and gate.grants == 1 and gate.give_ups == 0, (took, gate.summary())
    t1 = time.monotonic()
    gate.wait(10.6)  # within the granted lead (to 10.65): no hold
    gate.wait(10.65)
    assert time.monotonic() - t1 < 0.05 and gate.holds == 1
    t2 = time.monotonic()
    gate.wait(10.7)  # past it: held again, to the patience (counted from the last newer echo)
    assert time.monotonic() - t2 > 0.2 and gate.holds == 2 and gate.give_ups == 1


def test_an_echo_older_than_the_newest_during_a_hold_also_lets_the_physics_run_another_lead(
    gate: CompanionGate,
) -> None:
    """The newest echo was the relay's, during a cut, of a time the companion never saw (the cut
    dropped it): with the link back the companion, waiting, echoes its own newest, older. The
    physics once held for the whole patience then."""
    _echo(gate.port, 10.0)  # the relay's, in the cut
    threading.Timer(0.15, lambda: _echo(gate.port, 9.8)).start()  # the companion's, the link back
    t0 = time.monotonic()
    gate.wait(10.4)
    took = time.monotonic() - t0
    assert 0.1 < took < 0.45 and gate.grants == 1 and gate.give_ups == 0, (took, gate.summary())
    assert gate.echo_t == pytest.approx(10.0)


def test_a_companion_that_disconnects_is_not_waited_for(gate: CompanionGate) -> None:
    _echo(gate.port, 10.0)
    threading.Timer(0.1, lambda: _send_raw(gate.port, ECHO.pack(GONE))).start()
    t0 = time.monotonic()
    gate.wait(11.0)
    assert time.monotonic() - t0 < 0.4 and gate.echo_t is None and gate.give_ups == 0


def test_a_datagram_that_is_not_an_echo_is_counted_and_ignored(gate: CompanionGate) -> None:
    _send_raw(gate.port, b"hello")
    _echo(gate.port, 3.0)
    time.sleep(0.05)
    gate.wait(3.0)
    assert gate.rejected == 1 and gate.echo_t == pytest.approx(3.0)
    with pytest.raises(ValueError, match="positive"):
        CompanionGate(0, lead_s=0.0)


def _send_raw(port: int, data: bytes) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(data, ("127.0.0.1", port))


def test_the_server_holds_a_frame_until_the_companion_echoes() -> None:
    """A stand-in ArduPilot at 1200 Hz: free before any echo, held 0.25 s past the echo (no reply,
    only its re-sends), stepped on once a newer echo comes; the process says what it held."""
    gate_port = free_udp_port()
    with start_json_physics(lockstep_port=gate_port) as srv:
        ap = ArduPilotSide(srv.port)
        try:
            for _ in range(240):  # 0.2 s, nobody echoing
                ap.update([1000] * 4)
            _echo(gate_port, 0.1)
            time.sleep(0.05)
            with pytest.raises(TimeoutError):  # the gate's patience is 15 s
                for _ in range(600):
                    ap.update([1000] * 4, give_up_s=1.5)
            assert ap.state["timestamp"] == pytest.approx(0.35, abs=1.5 / 1200)
            held_at = ap.frame_counter
            _echo(gate_port, 0.3)
            assert ap.recv_fdm([1000] * 4, give_up_s=2.0)
            assert ap.frame_counter == held_at + 1 and ap.state["timestamp"] > 0.35
        finally:
            ap.close()
        srv.stop()
    assert "holds=1 " in srv.summary and "give_ups=0" in srv.summary, srv.summary


def _frames(*msgs) -> bytes:
    mav = mavutil.mavlink.MAVLink(None, srcSystem=1, srcComponent=191)
    mav.WIRE_PROTOCOL_VERSION = "2.0"
    return b"".join(bytes(m.pack(mav)) for m in msgs)


def test_the_tap_reads_the_echoes_out_of_the_companions_bytes() -> None:
    """Echo answers (tc1 != 0) are sent on, in microseconds, whatever the chunking; a time request
    (tc1 == 0), other messages, line noise and a damaged echo are not; closing says the companion
    is gone."""
    ml = mavutil.mavlink
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(1.0)
    tap = EchoTap(rx.getsockname()[1])
    damaged = bytearray(_frames(ml.MAVLink_timesync_message(122, 40_000_000_000)))
    damaged[-1] ^= 0xFF  # its checksum
    stream = (
        _frames(ml.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
        + b"\x00line noise\x13"
        + bytes(damaged)
        + _frames(
            ml.MAVLink_timesync_message(123, 41_250_000_000),  # an echo: 41.25 s
            ml.MAVLink_timesync_message(0, 5),  # a request for the autopilot's time
            ml.MAVLink_timesync_message(124, 41_270_000_000),
        )
    )
    for i in range(0, len(stream), 3):
        tap(stream[i : i + 3])
    tap.close()
    got = [ECHO.unpack(rx.recv(64))[0] for _ in range(3)]
    rx.close()
    assert got == [41_250_000, 41_270_000, GONE]
    assert tap.sent == 2


#: wall seconds within which 30 frames that are not paced must pass: half of what pacing them to
#: real time takes (0.29 s). A pace call costs microseconds, but on a loaded 2-core machine the
#: test process itself can be descheduled for tens of ms (0.05 s failed in a loaded suite,
#: 2026-12-06): the bound tells paced from free, not how fast the machine is
FREE_S = 0.145


def test_near_the_ground_it_keeps_to_real_time_and_above_it_runs_free() -> None:
    """With a companion echoing, frames below the height are paced to the wall clock (a frame
    of 10 ms takes 10 ms); above it, or with nobody echoing, they are not paced at all."""
    g = CompanionGate(0, real_time_below_m=2.0)
    try:
        _echo(g.port, 100.0)
        time.sleep(0.05)
        g.wait(0.0)

        def run(height_m: float, frames: int = 30, dt: float = 0.01) -> float:
            t0 = time.monotonic()
            for i in range(frames):
                g.pace(1.0 + i * dt, height_m)
            return time.monotonic() - t0

        assert run(1.0) >= 0.29 - 0.01  # 30 frames of 10 ms: 0.29 s after the first
        assert run(3.0) < FREE_S
        g.reset()  # the companion gone
        assert run(1.0) < FREE_S
        assert g.paced_s > 0.25
    finally:
        g.close()
    with pytest.raises(ValueError, match="positive"):
        CompanionGate(0, real_time_below_m=0.0)


def test_near_the_ground_a_stall_is_not_caught_up_above_real_time() -> None:
    """After a hold or a stall near the ground the physics goes on at real time from where it is,
    catching up at most CATCH_UP_S: a burst above real time lets the script run late."""
    g = CompanionGate(0, real_time_below_m=2.0)
    try:
        _echo(g.port, 100.0)
        time.sleep(0.05)
        g.wait(0.0)
        for i in range(10):
            g.pace(1.0 + i * 0.01, 1.0)
        time.sleep(0.15)  # held for the companion, or not scheduled
        w0 = time.monotonic()
        for i in range(10, 21):
            g.pace(1.0 + i * 0.01, 1.0)
        took = time.monotonic() - w0  # 10 frames of 10 ms after the first, less the catch-up
        assert CATCH_UP_S <= 0.01 and took >= 0.1 - 0.01 - 0.01, took
    finally:
        g.close()


def test_near_the_ground_real_time_is_kept_only_while_the_script_may_time_and_a_second_after() -> None:
    """Below the height, frames in which the script times nothing (resting on the pad, hovering
    for the legs) run free, unless the script may have timed something within LINGER_S of
    physics time before (the impact read just after a contact that stopped the vehicle)."""
    g = CompanionGate(0, real_time_below_m=2.0)
    try:
        _echo(g.port, 1000.0)
        time.sleep(0.05)
        g.wait(0.0)

        def run(t0: float, timed: list[bool], dt: float = 0.01) -> float:
            w0 = time.monotonic()
            for i, on in enumerate(timed):
                g.pace(t0 + i * dt, 1.0, on)
            return time.monotonic() - w0

        assert run(1.0, [False] * 30) < FREE_S  # still on the ground: free
        assert run(2.0, [True] * 30) >= 0.29 - 0.01  # a descent: real time
        # one timed frame, then still: real time goes on for LINGER_S, then stops
        frames = round(LINGER_S / 0.01)
        assert run(3.0, [True] + [False] * frames) >= LINGER_S - 0.02
        assert run(3.0 + (frames + 1) * 0.01 + 0.02, [False] * 30) < FREE_S
    finally:
        g.close()


def test_what_the_script_may_be_timing() -> None:
    """A descent (the cut), a pitching landing (the impact), reverse thrust (its duration): yes.
    Resting, hovering, climbing: no."""
    assert script_may_time(-0.5, 0.0, False)  # the 0.5 m/s descent
    assert script_may_time(0.0, PITCH_RATE_RAD_S * 2, False)  # pivoting onto the downhill foot
    assert script_may_time(0.0, 0.0, True)  # resting under reverse thrust
    assert not script_may_time(0.0, 0.0, False)  # resting, hovering
    assert not script_may_time(1.0, 0.05, False)  # the take-off
    assert not script_may_time(-DESCENT_MPS / 2, 0.0, False)  # a hover's drift
