"""The firmware on a host: the plant under the HAL, board time fed from outside.

:class:`HostBoard` is what the simulated board runs (``slopelander_sitl.legboard``), in its own CPython
process or as a MicroPython child (``micropython -X heapsize=192K host.py --fd N ...``, the
heap a Pico leaves to MicroPython). The firmware never reads a clock: board time moves only
when :meth:`HostBoard.advance` is called, one firmware tick (4 ms) at a time, so a host on the
wall clock and a host fed a vehicle's time run the same code. Requests are the control
channel's (docs/leg-protocol.md §6), one JSON object per line.
"""

import math

from legfw.board import Firmware
from legfw.compat import wire
from legfw.config import Config
from legfw.plant import Noise, Plant, PlantParams
from legfw.simhal import CAPABILITIES, Port, SimHal

STATE_NAMES = ("LOOSE", "LOOSENING", "TIGHTENING", "HOLDING", "STOPPED", "POSITIONING", "FAULT")
FAULT_NAMES = ("NONE", "OVERCURRENT", "STUCK", "TIMEOUT", "SENSE", "TRAVEL")
LEG_FAULTS = ("stuck", "slip", "overcurrent", "sense", "erratic", "grip")
IO_FAULTS = ("silent", "corrupt", "unplug")
FAULT_KINDS = LEG_FAULTS + IO_FAULTS
MAX_ADVANCE_S = 10.0  # board seconds one ``advance`` may step (a guard against a runaway time)
_PLANT_FLAG = {"stuck": "stuck", "slip": "slip", "overcurrent": "shorted", "sense": "sense_dead"}


def parse_fault(text: str) -> tuple:
    """``KIND[:ARG][@T]`` → ``(kind, arg or None, at_s)``, e.g. ``stuck:1``, ``corrupt:0.2``, ``unplug@5``."""
    spec, _, at = text.partition("@")
    kind, _, arg = spec.partition(":")
    if kind not in FAULT_KINDS:
        raise ValueError("unknown fault {!r}; one of {}".format(kind, ", ".join(FAULT_KINDS)))
    if kind in LEG_FAULTS and not arg:
        raise ValueError(f"fault {kind} needs a leg: {kind}:LEG")
    return (kind, float(arg) if arg else None, float(at) if at else 0.0)


class HostBoard:
    """The firmware, its simulated HAL and the plant; time only as :meth:`advance` feeds it."""

    def __init__(
        self,
        fd=None,
        config=None,
        plant=None,
        seed: int = 0,
        board_id: bytes = b"SIMBOARD",
        capabilities: int = CAPABILITIES,
        faults=(),
    ) -> None:
        self.cfg = Config(**(config or {}))
        params = plant if isinstance(plant, PlantParams) else PlantParams(**(plant or {}))
        self.plant = Plant(params, seed)
        self.hal = SimHal(
            self.plant, Port(fd) if fd is not None else None, board_id, capabilities, Noise(seed + 1)
        )
        self.fw = Firmware(self.hal, self.cfg)
        self.dt_s = self.cfg.tick_ms / 1000.0
        self.scheduled = sorted(faults, key=lambda f: f[2])
        self.unplugged = False
        self.clock_s = None
        # power-up: the firmware's probe finds each nut at its back stop (or not) before
        # anyone can talk to the board
        for _ in range(self.cfg.boot_probe_ms // self.cfg.tick_ms + 4):
            self._tick()

    @property
    def time_s(self) -> float:
        return self.fw.ms / 1000.0

    def _tick(self) -> None:
        self.plant.step(self.dt_s)
        self.hal.ms = self.fw.ms + self.cfg.tick_ms
        self.fw.tick()
        while self.scheduled and self.scheduled[0][2] <= self.fw.ms / 1000.0 + 1e-9:
            kind, arg, _ = self.scheduled.pop(0)
            self.inject(kind, arg)

    def serial_ready(self) -> None:
        """Bytes may have arrived: the firmware reads and answers them at the present time."""
        self.fw.poll_serial()

    def advance(self, to_s) -> float:
        """Step board time up to ``to_s`` (s) in whole ticks; a time behind the board's holds it."""
        to_s = float(to_s)
        if not math.isfinite(to_s):
            raise ValueError(f"advance: time must be a finite number of seconds, got {to_s!r}")
        ahead = to_s - self.time_s
        if ahead > MAX_ADVANCE_S:
            raise ValueError(
                f"advance: {to_s:g} s is {ahead:g} s ahead of board time {self.time_s:g} s "
                f"(at most {MAX_ADVANCE_S:g} s per request)"
            )
        if self.clock_s is None or to_s > self.clock_s:
            self.clock_s = to_s
        self.fw.status_due()
        to_ms = math.floor(to_s * 1000.0 + 1e-6)
        tick = self.cfg.tick_ms
        while self.fw.ms + tick <= to_ms:
            self._tick()
        return self.time_s

    # ---- faults and the bench ---------------------------------------------------------
    def inject(self, kind: str, arg=None) -> None:
        if kind in LEG_FAULTS:
            if arg is None or not 0 <= int(arg) < wire.N_LEGS:
                raise ValueError(f"fault {kind} needs a leg 0..3")
            setattr(self.plant.legs[int(arg)], _PLANT_FLAG.get(kind, kind), True)
        elif kind == "silent":
            self.hal.silent = True
        elif kind == "corrupt":
            self.hal.corrupt_rate = 1.0 if arg is None else float(arg)
        elif kind == "unplug":
            self.unplugged = True
            self.hal.unplug()
        else:
            raise ValueError(f"unknown fault {kind!r}")

    def clear_faults(self) -> None:
        for lg in self.plant.legs:
            lg.stuck = lg.slip = lg.shorted = lg.sense_dead = lg.erratic = lg.grip = False
            lg.grip_factor = 1.0
        self.hal.silent = False
        self.hal.corrupt_rate = 0.0

    def bench(self, req: dict) -> None:
        """The calibration bench on one leg: ``load_nm`` (a mass on a lever), ``peg`` (the lever
        held at its mark), ``spring`` (the reset spring hooked), ``catch_deg`` (where a falling
        lever is caught), ``angle_deg`` (the lever put at its mark)."""
        lg = self.plant.legs[int(req["leg"])]
        if "load_nm" in req:
            lg.load_nm = float(req["load_nm"])
        if "peg" in req:
            lg.peg = bool(req["peg"])
        if "spring" in req:
            lg.spring = bool(req["spring"])
        if "catch_deg" in req:
            lg.catch_deg = float(req["catch_deg"])
        if "angle_deg" in req:
            lg.angle_deg = min(max(float(req["angle_deg"]), 0.0), lg.stop_deg)

    # ---- the control channel ----------------------------------------------------------
    def control(self, req: dict) -> dict:
        """One control request (a decoded JSON object) → its reply."""
        op = req["op"]
        if op == "state":
            return self.state()
        if op == "advance":
            self.advance(req["to_s"])
            if req.get("reply", "state") == "state":
                return self.state()
            return {"ok": True, "time_s": self.time_s, "unplugged": self.unplugged}
        if op == "set_angles":
            for i, deg in enumerate(req["deg"]):
                if deg is not None:
                    lg = self.plant.legs[i]
                    lg.angle_deg = min(max(float(deg), 0.0), lg.stop_deg)
            return {"ok": True, "time_s": self.time_s}
        if op == "fault":
            self.inject(req["kind"], req.get("leg", req.get("rate")))
            return {"ok": True, "time_s": self.time_s}
        if op == "clear":
            self.clear_faults()
            return {"ok": True}
        if op == "bench":
            self.bench(req)
            return {"ok": True, "time_s": self.time_s}
        if op == "serial":
            self.serial_ready()
            return {"ok": True}
        raise ValueError(f"unknown op {op!r}")

    def state(self) -> dict:
        legs = []
        for i, lg in enumerate(self.plant.legs):
            fl = self.fw.legs[i]
            legs.append(
                {
                    "state": STATE_NAMES[fl.state],
                    "fault": FAULT_NAMES[fl.fault],
                    "angle_deg": lg.angle_deg,
                    "stop_deg": lg.stop_deg,
                    "torque_nm": lg.friction_torque(),
                    "current_ma": lg.current * 1000.0,
                    "target_ma": fl.target_ua / 1000.0,
                    "travel_mm": lg.travel * 1000.0,
                }
            )
        return {
            "ok": True,
            "time_s": self.time_s,
            "clock_s": self.clock_s,
            "silent": self.hal.silent,
            "corrupt_rate": self.hal.corrupt_rate,
            "unplugged": self.unplugged,
            "dropped_bytes": 0 if self.hal.port is None else self.hal.port.dropped,
            "legs": legs,
        }


def _args(argv: list) -> dict:
    """``--fd N --seed S --board-id HEX --caps C --config JSON --plant JSON --fault SPEC ...``"""
    import json

    out = {"fd": None, "seed": 0, "board_id": b"SIMBOARD", "caps": CAPABILITIES, "config": {}, "plant": {}}
    faults = []
    i = 0
    while i < len(argv):
        key, value = argv[i], argv[i + 1]
        i += 2
        if key == "--fd":
            out["fd"] = int(value)
        elif key == "--seed":
            out["seed"] = int(value)
        elif key == "--board-id":
            out["board_id"] = bytes.fromhex(value)
        elif key == "--caps":
            out["caps"] = int(value)
        elif key == "--config":
            out["config"] = json.loads(value)
        elif key == "--plant":
            out["plant"] = json.loads(value)
        elif key == "--fault":
            faults.append(parse_fault(value))
        else:
            raise ValueError(f"unknown argument {key!r}")
    out["faults"] = faults
    return out


def main(argv: list) -> None:
    """The host's loop as a child process: serial bytes from the descriptor, requests on stdin,
    replies on stdout, until stdin closes (the launcher has gone) or ``quit``."""
    import json
    import select
    import sys

    a = _args(argv)
    plant = a["plant"]
    if "mu" in plant:
        plant["mu"] = tuple(plant["mu"])
    board = HostBoard(a["fd"], a["config"], plant, a["seed"], a["board_id"], a["caps"], a["faults"])
    poll = select.poll()
    port = board.hal.port
    poll.register(sys.stdin, select.POLLIN)
    if port is not None:
        poll.register(port.fileno(), select.POLLIN)
    out = sys.stdout
    out.write(json.dumps({"ok": True, "ready": True, "time_s": board.time_s}) + "\n")
    while True:
        for obj, _event in poll.poll(-1):
            if obj is sys.stdin or obj == 0 or (hasattr(obj, "fileno") and obj.fileno() == 0):
                line = sys.stdin.readline()
                if not line:
                    return  # the launcher has gone
                try:
                    req = json.loads(line)
                    if req.get("op") == "quit":
                        out.write('{"ok": true}\n')
                        return
                    had_port = board.hal.port is not None
                    reply = board.control(req)
                    if had_port and board.hal.port is None:
                        poll.unregister(port.fileno())
                except (ValueError, KeyError, TypeError, IndexError) as exc:
                    reply = {"ok": False, "error": str(exc)}
                out.write(json.dumps(reply) + "\n")
            elif board.hal.port is not None:
                board.serial_ready()
