"""The companion link against a small autopilot peer over real UDP sockets."""

from __future__ import annotations

import socket
import time

import pytest
from pymavlink import mavutil

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
    assert "QUADROTOR" in link.info.describe() and "script absent" in link.info.describe()


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


def test_link_loss_on_local_clock_and_clock_from_vehicle_stamps(pair):
    link, peer, clk = pair
    assert link.lost  # nothing heard yet
    found(link, peer)
    assert not link.lost
    peer.conn.mav.raw_imu_send(2_000_000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer)
    assert link.clock.now() == pytest.approx(2.0)
    ts = [m for m in peer.received if m.get_type() == "TIMESYNC"]
    # an answer (tc1 != 0: ArduPilot takes tc1 == 0 as a request for its own time) echoing the
    # newest vehicle time, the lock-step echo a simulated vehicle waits on
    assert ts and ts[-1].tc1 != 0 and ts[-1].ts1 == 2_000_000_000
    clk.advance(1.4)
    assert not link.lost
    clk.advance(0.2)
    assert link.lost  # nothing at all for 1.6 s of local time


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
    # its clock moves on 1.6 s past the last HEARTBEAT (at 1.5 s) with no new one: lost
    for us in range(2_050_000, 3_150_001, 50_000):
        peer.conn.mav.raw_imu_send(us, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    settle(link, peer, 1)
    assert link.lost


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
    assert not [m for m in got + peer.received if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
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
    for i in range(6):  # free fall, one spike of 4 g, then free fall again, all in one batch
        peer.conn.mav.raw_imu_send(1_000_000 + i * 5000, 0, 0, 4000 if i == 2 else 50, 0, 0, 0, 0, 0, 0)
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
def test_the_take_off_judges_a_range_reading_by_the_attitude_of_its_own_moment(pair, sent, want):
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
    assert lander.inputs().tilt_deg is None  # read in TAKEOFF only: not looked up before
    lander.machine = Machine(lander.ctx, None, "TAKEOFF")
    tilt = lander.inputs().tilt_deg
    assert tilt == (None if want is None else pytest.approx(want, abs=0.05))
