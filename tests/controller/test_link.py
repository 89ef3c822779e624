"""The companion link against a small autopilot peer over real UDP sockets."""

from __future__ import annotations

import socket
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav2

from slopelander.controller.clock import ManualClock
from slopelander.controller.link import COMPANION_COMPONENT, Link, LinkError

mavlink = mavutil.mavlink


def free_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Peer:
    """An autopilot stand-in speaking real MAVLink: heartbeats, ACKs on demand, timestamps."""

    def __init__(self, port: int, system: int = 7) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=system, source_component=1, dialect="ardupilotmega"
        )
        self.received: list = []

    def heartbeat(self) -> None:
        self.conn.mav.heartbeat_send(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mavlink.MAV_STATE_STANDBY
        )

    def drain(self, wait: float = 0.05) -> list:
        end = time.monotonic() + wait
        got = []
        while time.monotonic() < end:
            m = self.conn.recv_match(blocking=True, timeout=0.01)
            if m is not None:
                got.append(m)
        self.received += got
        return got


@pytest.fixture
def pair():
    port = free_port()
    clk = ManualClock(100.0)
    link = Link(f"udpin:127.0.0.1:{port}", link_loss_s=1.5, monotonic=clk)
    peer = Peer(port)
    yield link, peer, clk
    link.close()
    peer.conn.close()


def settle(link: Link, peer: Peer, rounds: int = 5) -> list:
    got = []
    for _ in range(rounds):
        time.sleep(0.01)
        link.poll()
        got += peer.drain(0.02)
    return got


def found(link: Link, peer: Peer) -> None:
    peer.heartbeat()
    settle(link, peer)
    assert link.info is not None


def test_finds_autopilot_takes_its_system_id_and_heartbeats_as_companion(pair):
    link, peer, _ = pair
    found(link, peer)
    assert (link.info.system, link.info.component) == (7, 1)
    assert link.info.vehicle_type == mavlink.MAV_TYPE_QUADROTOR
    hbs = [m for m in peer.received if m.get_type() == "HEARTBEAT"]
    assert hbs, "companion sent no heartbeat"
    assert hbs[-1].type == mavlink.MAV_TYPE_ONBOARD_CONTROLLER
    assert hbs[-1].get_srcSystem() == 7 and hbs[-1].get_srcComponent() == COMPANION_COMPONENT
    assert "QUADROTOR" in link.info.describe() and "script not heard" in link.info.describe()


def test_firmware_and_script_reported(pair):
    link, peer, clk = pair
    found(link, peer)
    v = (4 << 24) | (5 << 16) | (7 << 8)
    peer.conn.mav.autopilot_version_send(0, v, 0, 0, 0, b"\0" * 8, b"\0" * 8, b"\0" * 8, 0, 0, 0)
    peer.conn.mav.named_value_float_send(10, b"SL_VER", 1.0)
    settle(link, peer)
    assert link.info.firmware == "4.5.7"
    assert link.script_present and link.info.script_version == 1.0
    clk.advance(1.5)
    assert link.script_present  # no autopilot time went by: a stalled vehicle, not a silent script
    # 1.5 s of the autopilot's time without SL_ news, its telemetry arriving all along
    for ms in range(60, 1511, 50):
        peer.conn.mav.system_time_send(0, ms)
    settle(link, peer)
    assert not link.script_present


def test_a_telemetry_gap_is_not_taken_for_silent_sensors_or_script(pair):
    """What the link missed during a gap says nothing about the vehicle: ages count from where the
    telemetry resumed, so the first message after a cut does not make every reading stale."""
    link, peer, _ = pair
    found(link, peer)
    peer.conn.mav.system_time_send(0, 1000)
    peer.conn.mav.named_value_float_send(1000, b"SL_STATE", 0.0)
    settle(link, peer)
    assert link.script_present and link.age(1.0) == pytest.approx(0.0)
    peer.conn.mav.system_time_send(0, 2500)  # 1.5 s later, nothing in between: a gap
    settle(link, peer)
    assert link.resumed_at == pytest.approx(2.5)
    assert link.script_present and link.age(1.0) == pytest.approx(0.0)
    for ms in range(2550, 3551, 50):  # telemetry flows again, still no SL_STATE: now it is silent
        peer.conn.mav.system_time_send(0, ms)
    settle(link, peer)
    assert link.age(1.0) == pytest.approx(1.05)
    assert not link.script_present


def test_command_accepted_after_one_lost_try(pair):
    link, peer, clk = pair
    found(link, peer)
    h = link.command(mavlink.MAV_CMD_USER_1, 1, 0, 500, retries=2, timeout_s=0.5)
    got = [m for m in settle(link, peer) if m.get_type() == "COMMAND_LONG" and m.command == 31010]
    assert len(got) == 1 and got[0].param3 == 500 and not h.done
    clk.advance(0.6)  # the first try is ignored; the link re-sends
    got = [m for m in settle(link, peer) if m.get_type() == "COMMAND_LONG" and m.command == 31010]
    assert len(got) == 1 and got[0].confirmation == 1
    peer.conn.mav.command_ack_send(31010, mavlink.MAV_RESULT_ACCEPTED)
    settle(link, peer)
    assert h.ok and h.tries == 2


def test_command_rejected_and_timeout(pair):
    link, peer, clk = pair
    found(link, peer)
    h = link.command(mavlink.MAV_CMD_USER_2, 1, 0.3, 20, 60, 300, 1000)
    peer.conn.mav.command_ack_send(31011, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
    settle(link, peer)
    assert h.state == "rejected" and h.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    h2 = link.command(mavlink.MAV_CMD_USER_1, 0, retries=1, timeout_s=0.2)
    for _ in range(3):
        clk.advance(0.25)
        settle(link, peer, 2)
    assert h2.state == "timeout" and h2.tries == 2


def test_a_late_ack_of_a_timed_out_command_does_not_confirm_the_next_of_its_id(pair):
    """ArduPilot's COMMAND_ACK names only the command id: the answer to a request given up on could
    confirm the next request of that id. The id is held back for a second after a timeout: the
    new request is sent after it, and the late ACK arriving meanwhile is dropped."""
    from slopelander.controller.link.commands import QUARANTINE_S

    link, peer, clk = pair
    found(link, peer)
    old = link.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 5, retries=0, timeout_s=0.2)
    clk.advance(0.25)
    settle(link, peer, 2)
    assert old.state == "timeout"
    new = link.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4, retries=2, timeout_s=0.5)
    sent = [m for m in settle(link, peer, 2) if m.get_type() == "COMMAND_LONG" and m.command == 176]
    assert sent == [] and new.tries == 0  # held back
    peer.conn.mav.command_ack_send(176, mavlink.MAV_RESULT_ACCEPTED)  # the old one's late answer
    settle(link, peer, 2)
    assert not new.done
    clk.advance(QUARANTINE_S)
    sent = [m for m in settle(link, peer, 2) if m.get_type() == "COMMAND_LONG" and m.command == 176]
    assert [m.param2 for m in sent] == [4] and not new.done
    peer.conn.mav.command_ack_send(176, mavlink.MAV_RESULT_ACCEPTED)  # its own answer
    settle(link, peer, 2)
    assert new.ok


def test_link_loss_on_local_clock_and_clock_from_vehicle_stamps(pair):
    link, peer, clk = pair
    assert link.lost  # nothing heard yet
    found(link, peer)
    assert not link.lost
    peer.conn.mav.raw_imu_send(2_000_000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer)
    assert link.clock.now() == pytest.approx(2.0)
    clk.advance(1.4)
    link.poll()
    assert not link.lost and link.lost_why is None
    clk.advance(0.2)
    assert not link.lost  # nobody looked in those 0.2 s
    link.poll()
    assert link.lost  # nothing at all for 1.6 s of local time, read after it
    assert link.lost_why == "nothing heard for 1.60 s of local time"


def test_a_companion_that_stalls_does_not_take_its_pause_for_the_autopilots_silence(pair):
    """The companion stops for 2 s between its read and its landing step (a long garbage
    collection in a big process, a starved CPU): what the autopilot sent meanwhile is waiting
    in the socket, so the link is not lost, before the next read or after it."""
    link, peer, clk = pair
    found(link, peer)
    peer.conn.mav.raw_imu_send(2_000_000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer)
    clk.advance(2.0)  # the stall, after a read that drained the link
    peer.conn.mav.raw_imu_send(2_010_000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    time.sleep(0.05)
    assert not link.lost, link.lost_why
    link.poll()
    assert not link.lost and link.clock.now() == pytest.approx(2.01)
    # the same pause with nothing sent in it: silent for as long as the reads show
    clk.advance(2.0)
    assert not link.lost
    link.poll()
    assert link.lost_why == "nothing heard for 2.00 s of local time"


def test_a_slow_vehicle_is_not_lost_but_one_without_heartbeats_is(pair):
    link, peer, clk = pair
    peer.conn.mav.system_time_send(0, 1000)
    found(link, peer)
    # a vehicle running at a quarter of real time: its messages keep coming, 4 local s = 1 vehicle s
    for i in range(1, 21):
        clk.advance(0.2)
        peer.conn.mav.raw_imu_send(1_000_000 + i * 50_000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
        if i == 10:
            peer.heartbeat()
        settle(link, peer, 1)
        assert not link.lost, i
    # its clock moves on 3.1 s past the last HEARTBEAT (at 1.5 s) with no new one: three missed
    for us in range(2_050_000, 4_650_001, 50_000):
        peer.conn.mav.raw_imu_send(us, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer, 1)
    assert link.lost
    assert link.lost_why.startswith("no HEARTBEAT for 3.1") and "vehicle time" in link.lost_why


def test_one_lost_heartbeat_is_not_link_loss_but_the_configured_count_is(pair):
    """A dropped 1 Hz HEARTBEAT on a noisy link left 1.5 s without one: that was link loss."""
    link, peer, _ = pair
    peer.conn.mav.system_time_send(0, 1000)
    found(link, peer)  # its HEARTBEAT at 1.0 s of vehicle time
    ms = 1000
    for beat in range(1, 4):  # the ones at 2 s and 3 s are lost
        for _ in range(21):
            ms += 50
            peer.conn.mav.raw_imu_send(ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
        settle(link, peer, 1)
        assert link.lost == (beat == 3), beat  # 1.05, 2.1 s after it: not lost; 3.15 s: lost
    peer.heartbeat()
    settle(link, peer, 1)
    assert not link.lost
    link.heartbeats_missed = 1  # the setting (link.heartbeats_missed) says how many
    for _ in range(22):
        ms += 50
        peer.conn.mav.raw_imu_send(ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer, 1)
    assert link.lost


def _acks_for(peer: Peer, got: list, answer) -> None:
    for m in got:
        is_request = m.get_type() == "COMMAND_LONG" and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
        if is_request and answer(m):
            peer.conn.mav.command_ack_send(m.command, mavlink.MAV_RESULT_ACCEPTED)


def test_five_stream_requests_are_each_tracked_until_each_is_answered(pair):
    """A newer SET_MESSAGE_INTERVAL used to supersede the pending one: of five, only the last was
    re-sent. Here the autopilot ignores every first try: each request is re-sent and answered."""
    link, peer, clk = pair
    found(link, peer)
    ids = [27, 132, 65, 32, 30]
    handles = [link.request_stream(i, 10) for i in ids]
    tries: dict[int, int] = {}

    def second_try_only(m) -> bool:
        tries[int(m.param1)] = tries.get(int(m.param1), 0) + 1
        return tries[int(m.param1)] >= 2

    for _ in range(40):
        _acks_for(peer, settle(link, peer, 2), second_try_only)
        if all(h.done for h in handles):
            break
        clk.advance(0.3)
    assert [h.state for h in handles] == ["accepted"] * 5
    assert tries == dict.fromkeys(ids, 2)  # each re-sent once, none sent again once answered


def ack2(peer: Peer, command: int, result: int, request: int) -> None:
    """A MAVLink 2 COMMAND_ACK carrying ``request`` in result_param2 (MAVLink 1 has no such field)."""
    enc = mav2.MAVLink(None, srcSystem=7, srcComponent=1)
    peer.conn.write(mav2.MAVLink_command_ack_message(command, result, 0, request, 0, 0).pack(enc))


def test_an_ack_answers_the_request_it_carries_the_number_of(pair):
    """With a request number (echoed in COMMAND_ACK.result_param2) two commands of one id are in
    flight at once, and each ACK answers its own, whatever order they come in."""
    link, peer, _ = pair
    found(link, peer)
    a = link.command(mavlink.MAV_CMD_USER_1, 1, 0, 500, request=41)
    b = link.command(mavlink.MAV_CMD_USER_1, 0, 0, 500, request=42)
    sent = [m for m in settle(link, peer) if m.get_type() == "COMMAND_LONG" and m.command == 31010]
    assert len(sent) == 2  # sent at once, not queued
    ack2(peer, 31010, mavlink.MAV_RESULT_ACCEPTED, 99)  # nobody's
    ack2(peer, 31010, mavlink.MAV_RESULT_DENIED, 42)
    settle(link, peer)
    assert b.state == "rejected" and not a.done
    ack2(peer, 31010, mavlink.MAV_RESULT_ACCEPTED, 41)
    settle(link, peer)
    assert a.ok
    with pytest.raises(LinkError, match="request number"):
        link.command(mavlink.MAV_CMD_USER_1, 1, request=1.5)


def test_without_a_request_number_one_command_of_an_id_is_in_flight_at_a_time(pair):
    """An ACK without a request number says only its command id: the second command waits, so
    the first ACK cannot be taken for the second's answer."""
    link, peer, _ = pair
    found(link, peer)
    a = link.command(mavlink.MAV_CMD_USER_2, 1)
    b = link.command(mavlink.MAV_CMD_USER_2, 0)
    sent = [m for m in settle(link, peer) if m.get_type() == "COMMAND_LONG" and m.command == 31011]
    assert [m.param1 for m in sent] == [1] and b.tries == 0
    peer.conn.mav.command_ack_send(31011, mavlink.MAV_RESULT_ACCEPTED)
    sent = [m for m in settle(link, peer) if m.get_type() == "COMMAND_LONG" and m.command == 31011]
    assert a.ok and not b.done and [m.param1 for m in sent] == [0]
    peer.conn.mav.command_ack_send(31011, mavlink.MAV_RESULT_FAILED)
    settle(link, peer)
    assert b.state == "rejected"


def _imu(peer: Peer, us: int) -> None:
    peer.conn.mav.raw_imu_send(us, 0, 0, -1000, 0, 0, 0, 0, 0, 0)


def test_no_timesync_to_an_autopilot_unless_the_caller_asks_for_the_echo(pair):
    """ArduPilot drops TIMESYNC answers it did not ask for: a link not told it flies a lock-stepped
    simulator sends none at all (there were 50 a second of vehicle time, and a probe)."""
    link, peer, clk = pair
    found(link, peer)
    for i in range(60):  # 1.2 s of a free-running vehicle's 50 Hz stream
        _imu(peer, 1_000_000 + i * 20_000)
        clk.advance(0.02)
        settle(link, peer, 1)
    assert link.lockstep is None
    assert [m for m in peer.received if m.get_type() == "TIMESYNC"] == []


def test_a_lockstep_link_echoes_the_newest_vehicle_time_every_20_ms(pair):
    """Asked for (a simulator that waits), the echo follows the vehicle's time: ts1 is the newest
    vehicle time read, in ns, once per 20 ms of it."""
    from slopelander.controller.link.lockstep import LockstepEcho

    link, peer, clk = pair
    link.lockstep = LockstepEcho(link.conn, link.clock, link.monotonic)
    found(link, peer)
    for i in range(11):
        _imu(peer, 1_000_000 + i * 10_000)  # 10 ms apart: an echo every second sample
        clk.advance(0.01)
        settle(link, peer, 1)
    ts = [m.ts1 for m in peer.received if m.get_type() == "TIMESYNC"]
    assert ts == [(1_000_000 + k * 20_000) * 1000 for k in range(6)], ts
    assert all(m.tc1 != 0 for m in peer.received if m.get_type() == "TIMESYNC")  # answers, not requests


def test_an_autopilot_reboot_is_link_loss_though_heartbeats_go_on(pair):
    """After a reboot its clock starts again from zero: the link's clock stood still while
    HEARTBEATs kept the link 'up', and the machine was no longer stepped."""
    link, peer, _ = pair
    found(link, peer)
    for ms in range(9000, 10_001, 100):
        peer.conn.mav.system_time_send(0, ms)
    settle(link, peer)
    peer.conn.mav.system_time_send(0, 7000)  # one late frame is not a reboot
    peer.conn.mav.system_time_send(0, 10_100)
    settle(link, peer)
    assert not link.rebooted and not link.lost
    for ms in range(2000, 2500, 100):  # booted again: heartbeats and a clock from 2 s
        peer.heartbeat()
        peer.conn.mav.system_time_send(0, ms)
        settle(link, peer, 1)
    assert link.rebooted and link.lost
    assert "from 10.1 s to 2.4 s" in link.reboot_note


def test_the_landing_takes_a_reboot_for_link_loss(pair):
    from slopelander.controller.config import load_config
    from slopelander.controller.machine import Machine
    from slopelander.controller.runner import Lander

    link, peer, _ = pair
    found(link, peer)
    lander = Lander(link, load_config(), (0.8, 1.5), legs=None)
    lander.machine = Machine(lander.ctx, None, "TAKEOFF")  # link loss is all its row acts on
    for ms in range(9000, 10_001, 100):
        peer.conn.mav.system_time_send(0, ms)
    settle(link, peer)
    lander.poll()
    assert lander.machine.name == "TAKEOFF"
    for ms in range(2000, 2500, 100):
        peer.heartbeat()
        peer.conn.mav.system_time_send(0, ms)
        time.sleep(0.01)
        lander.poll()
    assert lander.machine.name == "LINK_LOST"


def _stream_at(peer: Peer, link: Link, hz: float, t0_s: float, span_s: float) -> None:
    n = round(hz * span_s)
    for i in range(1, n + 1):
        _imu(peer, int((t0_s + i / hz) * 1e6))
        if i % 20 == 0:
            settle(link, peer, 1)
    settle(link, peer)


def test_a_stream_delivering_less_than_its_share_is_refused_with_its_rates(pair):
    from slopelander.controller.link import stream_refusal

    link, peer, _ = pair
    found(link, peer)
    _imu(peer, 1_000_000)
    settle(link, peer)
    h = link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 100)
    settle(link, peer)
    peer.conn.mav.command_ack_send(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_ACCEPTED)
    _stream_at(peer, link, 40, 1.0, 0.2)
    assert h.ok
    assert "not measured yet" in stream_refusal(link, 0.5)  # 0.2 s of vehicle time is too little
    _stream_at(peer, link, 40, 1.2, 1.0)
    why = stream_refusal(link, 0.5)
    assert why == "stream RAW_IMU delivers 40.0 Hz of 100 Hz requested (less than 50%)"
    assert stream_refusal(link, 0.3) is None
    _stream_at(peer, link, 100, 2.2, 2.0)
    assert link.delivered_hz("RAW_IMU") == pytest.approx(100.0)
    assert stream_refusal(link, 0.5) is None
    assert stream_refusal(None, 0.5) is None


def test_checks_refuse_a_short_stream(pair):
    """CHECKS reads link.min_delivered_fraction: everything else fine, a stream at 40 % aborts."""
    from slopelander.controller.config import load_config
    from slopelander.controller.machine import Machine
    from slopelander.controller.runner import Lander
    from slopelander.controller.states.base import Inputs

    link, peer, _ = pair
    found(link, peer)
    _imu(peer, 1_000_000)
    settle(link, peer)
    link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 100)
    _stream_at(peer, link, 40, 1.0, 1.0)
    lander = Lander(link, load_config(), (0.8, 1.5), legs=None)
    lander.machine = Machine(lander.ctx, None, "CHECKS")
    lander.machine.step(Inputs(t=2.0, range_m=5.0, range_ok=True, legs_ready=True))
    assert lander.machine.name == "ABORTED"
    assert "stream RAW_IMU delivers 40.0 Hz of 100 Hz" in lander.machine.history[-1]["reason"]


def test_stream_rate_measured(pair):
    link, peer, _ = pair
    found(link, peer)
    h = link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 100)
    req = [
        m
        for m in settle(link, peer)
        if m.get_type() == "COMMAND_LONG" and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
    ]
    assert req and req[-1].param1 == mavlink.MAVLINK_MSG_ID_RAW_IMU and req[-1].param2 == 10000
    assert not h.done
    for i in range(40):
        peer.conn.mav.raw_imu_send(1000 + i * 10000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer)
    assert link.rate_hz("RAW_IMU", window=2.0) == pytest.approx(20.0)


def test_bad_input_errors():
    with pytest.raises(LinkError, match="empty"):
        Link("")
    with pytest.raises(LinkError, match="link_loss_s"):
        Link("udpin:127.0.0.1:0", link_loss_s=-1)
    link = Link(f"udpin:127.0.0.1:{free_port()}")
    try:
        with pytest.raises(LinkError, match="no autopilot"):
            link.command(400, 1)
        with pytest.raises(LinkError, match="200"):
            link.info = None
            link.request_stream(27, 500)
    finally:
        link.close()


def test_actions_send_the_contracts_commands(pair):
    from slopelander.controller.actions import MavActions
    from slopelander.controller.config import load_config

    link, peer, clk = pair
    found(link, peer)
    act = MavActions(link, load_config())
    act.reflex_arm()
    act.descend(0.5)
    act.descend(0.5)  # within the re-send period: not sent twice
    act.set_mode("LOITER")
    got = settle(link, peer)
    reflex = [m for m in got if m.get_type() == "COMMAND_LONG" and m.command == 31011]
    assert [m.param1 for m in reflex] == [3, 1]  # the landing's SETUP first, then ARM (contract 4)
    a = reflex[1]
    assert (a.param1, a.param2, a.param4, a.param6) == (1, pytest.approx(0.3), 100, 1000)
    assert (reflex[0].param7, a.param7) == (1, 2)  # each request numbered
    sp = [m for m in got if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    assert len(sp) == 1 and sp[0].type_mask == 0x0DC7 and sp[0].vz == 0.5 and sp[0].target_system == 7
    mode = [m for m in got if m.get_type() == "COMMAND_LONG" and m.command == mavlink.MAV_CMD_DO_SET_MODE]
    assert mode and mode[0].param2 == 5
    clk.advance(0.11)
    act.descend(0.5)
    assert [m for m in settle(link, peer) if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]


def test_lander_over_the_link_aborts_without_a_leg_board(pair, tmp_path):
    """Everything else healthy (GUIDED, armed, script, range): no leg board means no descent."""
    from slopelander.controller.config import load_config
    from slopelander.controller.runner import Lander

    link, peer, _ = pair
    rec = (tmp_path / "t.jsonl").open("w")
    lander = Lander(link, load_config(), (0.8, 1.5), legs=None, record=rec)
    for i in range(5):
        peer.conn.mav.heartbeat_send(
            mavlink.MAV_TYPE_QUADROTOR,
            mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
            mavlink.MAV_MODE_FLAG_SAFETY_ARMED | 1,
            4,
            mavlink.MAV_STATE_ACTIVE,
        )
        peer.conn.mav.named_value_float_send(1000 + i * 20, b"SL_STATE", 0)
        peer.conn.mav.distance_sensor_send(1000 + i * 20, 20, 1000, 500, 10, 1, 25, 100)
        time.sleep(0.01)
        lander.poll()
        peer.drain(0.01)
    rec.close()
    assert lander.machine.name == "ABORTED"
    assert "no leg board" in lander.machine.history[-1]["reason"]
    got = settle(link, peer)
    aborts = [m for m in peer.received if m.get_type() == "COMMAND_LONG" and m.command == 31011]
    assert aborts and aborts[-1].param1 == 0
    setpoints = [m for m in got + peer.received if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    assert setpoints and all(m.vz < 0 for m in setpoints)  # the abort's climb, never a descent
    assert (tmp_path / "t.jsonl").read_text().count("\n") == len(lander.machine.history)
    assert any("SL ABORTED" in m.text for m in peer.received if m.get_type() == "STATUSTEXT")


def test_every_imu_sample_is_kept_for_a_reader_that_polls_seldom(pair):
    from slopelander.controller.link import RECENT_LEN

    link, peer, _ = pair
    found(link, peer)
    seen = link.received.get("RAW_IMU", 0)
    for i in range(7):
        peer.conn.mav.raw_imu_send(1_000_000 + i * 5000, i, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer)
    msgs, seen = link.since("RAW_IMU", seen)
    assert [m.xacc for m in msgs] == list(range(7))
    assert link.since("RAW_IMU", seen) == ([], seen)
    for i in range(RECENT_LEN + 10):  # more than the link keeps: the newest, in order
        peer.conn.mav.raw_imu_send(2_000_000 + i * 5000, i, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer)
    msgs, seen2 = link.since("RAW_IMU", seen)
    assert seen2 - seen == RECENT_LEN + 10
    assert [m.xacc for m in msgs] == list(range(10, RECENT_LEN + 10))


def test_an_impact_between_two_wakes_of_the_loop_is_detected(pair):
    """The spike is neither the first nor the last sample read in one poll: the detector still
    gets it (it was given only the newest sample once, and a loop waking every 10 ms missed it)."""
    from slopelander.controller.config import load_config
    from slopelander.controller.runner import Lander

    link, peer, _ = pair
    found(link, peer)
    lander = Lander(link, load_config(), (0.8, 1.5), legs=None)
    lander.detector.arm_after_cut(0.5)
    for i in range(6):  # free fall, one contact of 4 g up the body, then free fall again, all in one batch
        peer.conn.mav.raw_imu_send(1_000_000 + i * 5000, 0, 0, -4000 if i == 2 else -50, 0, 0, 0, 0, 0, 0)
    time.sleep(0.05)
    lander.poll()
    assert lander.detector.impact is not None
    assert lander.detector.impact.t == pytest.approx(1.010)


def _range(peer: Peer, ms: int, cm: int) -> None:
    peer.conn.mav.distance_sensor_send(ms, 10, 800, cm, 0, 0, mavlink.MAV_SENSOR_ROTATION_PITCH_270, 0)


def test_a_late_older_message_does_not_replace_a_newer_one(pair):
    """Found by the soak under link noise: a reordered range reading from before became 'the
    newest', and a script state from before could undo a newer one."""
    link, peer, _ = pair
    found(link, peer)
    _range(peer, 2000, 120)
    peer.conn.mav.named_value_float_send(2000, b"SL_STATE", 12)
    settle(link, peer)
    _range(peer, 1900, 80)  # the older ones arrive last
    peer.conn.mav.named_value_float_send(1900, b"SL_STATE", 11)
    settle(link, peer)
    assert link.received["DISTANCE_SENSOR"] == 2
    assert link.last["DISTANCE_SENSOR"].current_distance == 120
    assert link.script_state == 12
    _range(peer, 2100, 110)  # a newer one still replaces it
    settle(link, peer)
    assert link.last["DISTANCE_SENSOR"].current_distance == 110


@pytest.mark.parametrize(
    "sent, want",
    [
        ([(990, 0.35), (1200, 0.0)], 20.05),  # tilted then, level by the time the range arrives
        ([(1000, 0.0), (1300, 0.35)], 0.0),  # level then: a later swing is not this reading's
        ([(1090, 0.1), (950, 0.35)], 20.05),  # every attitude near it counts, in any order
        ([(1300, 0.0)], None),  # none near it: not level
    ],
)
def test_a_range_reading_is_judged_by_the_attitude_of_its_own_moment(pair, sent, want):
    """The rangefinder looks along the body; a level attitude from after a tilted reading must not
    make that reading a height (it loosened the legs 0.6-0.7 m above the roof under link noise)."""
    from slopelander.controller.config import load_config
    from slopelander.controller.runner import Lander

    link, peer, _ = pair
    found(link, peer)
    from slopelander.controller.machine import Machine

    lander = Lander(link, load_config(), (0.8, 1.5), legs=None)
    _range(peer, 1000, 90)
    for ms, roll in sent:
        peer.conn.mav.attitude_send(ms, roll, 0.0, 0.0, 0.0, 0.0, 0.0)
    settle(link, peer)
    for state in ("TAKEOFF", "SETTLED"):  # the take-off's clear height, SETTLED's "in the air"
        lander.machine = Machine(lander.ctx, None, state)
        tilt = lander.inputs().tilt_deg
        assert tilt == (None if want is None else pytest.approx(want, abs=0.05)), state


def test_a_streams_rate_counts_from_when_the_autopilot_took_the_request(pair):
    """A request answered late (queued behind another, or its ACK lost once) holds from its ACK:
    the time before it says nothing about the rate asked for."""
    from slopelander.controller.link import stream_refusal

    link, peer, _ = pair
    found(link, peer)
    _imu(peer, 1_000_000)
    settle(link, peer)
    h = link.request_stream(mavlink.MAVLINK_MSG_ID_RAW_IMU, 100)
    peer.conn.mav.system_time_send(0, 2000)  # a second of vehicle time before the answer
    settle(link, peer)
    peer.conn.mav.command_ack_send(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_ACCEPTED)
    settle(link, peer)
    assert h.ok
    _stream_at(peer, link, 100, 2.0, 1.0)
    assert link.delivered_hz("RAW_IMU") == pytest.approx(100.0)
    assert stream_refusal(link, 0.9) is None
