"""docs/commands.md's "Using it" section, followed as a new user would: its code blocks, taken from
the page (so the page cannot drift from what lands), run in order with real processes: the
simulated leg board, the simulated ArduCopter, a real MAVProxy typed into at its prompt, and
`slopelander land`. The vehicle must end on the roof, landed and disarmed.

The page's commands use fixed places (`/tmp/legboard`, TCP ports 5760 and 5762), as a user's
would. So that two runs, or anything else on the machine, cannot collide with them, every command
runs inside one sandbox of Linux namespaces: its own `/tmp` (a tmpfs, showing of the machine's
only what holds this checkout or its Python, when they live there), its own network
holding only loopback, and its own process tree, which the kernel ends whole when the test ends
(even when the test is killed). The commands are otherwise run verbatim by bash from the
repository's root, `python3` and `slopelander` being this checkout's."""

from __future__ import annotations

import math
import os
import re
import shlex
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "commands.md"
HEADING = "## Using it"
#: what a long-running terminal prints once it is up; a block whose command is not here runs to its end
READY = {
    "slopelander_sitl.legboard": "legboard ready",
    "slopelander_sitl.vehicle": "vehicle ready",
    "mavproxy.py": "Detected vehicle",
}
#: a new user (mapped to root in it, so no privilege is needed), network, mount and process namespace
UNSHARE = ["unshare", "--user", "--map-root-user", "--net", "--mount", "--pid", "--fork", "--kill-child"]
PROMPT = re.compile(r"^[A-Z_]+> ")


@dataclass
class Block:
    kind: str  # "sh": a terminal's commands; "text": lines typed at MAVProxy's prompt
    text: str

    @property
    def typed(self) -> list[str]:
        return [PROMPT.sub("", ln).strip() for ln in self.text.splitlines() if ln.strip()]


def walkthrough(page: str) -> list[Block]:
    """The section's code blocks, in order."""
    section = page.split(f"\n{HEADING}", 1)[1].split("\n## ", 1)[0]
    blocks = []
    for m in re.finditer(r"^```(\w*)\n(.*?)^```", section, re.S | re.M):
        if m.group(1) not in ("sh", "text"):
            raise ValueError(f"a ```{m.group(1)} block in {HEADING}: sh (a terminal) or text (MAVProxy)")
        blocks.append(Block(m.group(1), m.group(2)))
    return blocks


def _argv(block: Block, program: str) -> list[str]:
    """The words of the command in a terminal block that runs ``program``."""
    for line in block.text.replace("\\\n", " ").splitlines():
        for part in re.split(r"&&|;", line):
            words = shlex.split(part)
            if program in words:
                return words
    return []


def test_the_walkthrough_starts_the_board_vehicle_mavproxy_then_lands_on_a_matching_roof():
    """What the flight below relies on, and what issue 23 asked of the page: the leg board is on
    the vehicle's legs, the roof is the slope `land` is told, MAVProxy flies it over the roof."""
    blocks = walkthrough(PAGE.read_text())
    assert [b.kind for b in blocks] == ["sh", "sh", "sh", "text", "sh"]
    board, vehicle, mavproxy, console, land = blocks
    assert "slopelander_sitl.legboard" in board.text and "slopelander_sitl.vehicle" in vehicle.text
    assert "mavproxy.py" in mavproxy.text and land.text.startswith("slopelander land ")
    v, b = _argv(vehicle, "slopelander_sitl.vehicle"), _argv(board, "slopelander_sitl.legboard")
    assert v[v.index("--legboard-control") + 1] == b[b.index("--link") + 1] + ".ctl"
    assert "--lockstep" in v and "--lockstep" in _argv(land, "land")  # the companion echoes its time
    scenario = re.search(r"slope_deg: (\d+)", vehicle.text)
    assert scenario is not None and _argv(land, "land")[-1] == scenario.group(1)
    assert [c.split()[0] for c in console.typed] == ["mode", "arm", "takeoff", "position"]


def test_a_block_of_another_kind_is_refused():
    with pytest.raises(ValueError, match="```python"):
        walkthrough(f"x\n{HEADING}\n\n```python\nprint()\n```\n")


def kept_under_tmp() -> list[str]:
    """The entries of the machine's /tmp that hold this checkout, this Python (a venv) or a folder
    on its path: each name right under /tmp, which the sandbox's own /tmp must show too."""
    places = [ROOT, Path(sys.executable), Path(sys.prefix), Path(sys.base_prefix), *map(Path, sys.path)]
    names = set()
    for place in places:
        for path in {place.absolute(), place.resolve()}:
            if (
                len(path.parts) > 2
                and path.parts[:2] == ("/", "tmp")
                and Path("/tmp", path.parts[2]).is_dir()
            ):
                names.add(path.parts[2])
    return sorted(names)


class Sandbox:
    """A private /tmp, loopback-only network and process tree (``unshare``); :meth:`run` starts a
    shell command inside it. Its first process (the namespace's init) reads the test's pipe: when
    the test closes it, or dies, init ends and the kernel ends every process in the sandbox."""

    def __init__(self) -> None:
        up_code = "from slopelander_sitl.netns import bring_loopback_up as f; f()"
        up = f"{shlex.quote(sys.executable)} -c '{up_code}'"
        # what lives under the machine's /tmp and the commands need (a checkout or a venv cloned
        # there) is bound back into the private one, reached through a descriptor of the old /tmp
        # opened before it was covered (not canonicalized: that path would resolve into the new one)
        names = [shlex.quote(name) for name in kept_under_tmp()]
        keep = " && ".join(
            f"mkdir /tmp/{n} && mount --no-canonicalize --bind /proc/self/fd/3/{n} /tmp/{n}" for n in names
        )
        script = (
            f"exec 3</tmp && mount -t tmpfs walkthrough /tmp && {keep or 'true'} && exec 3<&- && {up} "
            "&& echo ready && exec cat >/dev/null"
        )
        self.env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
        self.holder = subprocess.Popen(
            [*UNSHARE, "sh", "-c", script],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=self.env,
            cwd=ROOT,
        )
        if self.holder.stdout.readline().strip() != "ready":
            self.close()
            raise RuntimeError("the sandbox did not start")
        children = Path(f"/proc/{self.holder.pid}/task/{self.holder.pid}/children").read_text().split()
        self.init = int(children[0])
        # this checkout's python3 and slopelander, first on PATH inside the sandbox (in its /tmp)
        bin_dir = Path(f"/proc/{self.init}/root/tmp/.walkthrough-bin")
        bin_dir.mkdir()
        (bin_dir / "python3").symlink_to(sys.executable)
        cli = bin_dir / "slopelander"
        cli.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m slopelander.cli "$@"\n')
        cli.chmod(0o755)
        self.env["PATH"] = f"/tmp/.walkthrough-bin{os.pathsep}{os.environ['PATH']}"

    def run(self, command: str) -> Terminal:
        enter = ["nsenter", "-t", str(self.init), "--user", "--net", "--mount", "--pid"]
        proc = subprocess.Popen(
            [*enter, "--preserve-credentials", "--", "bash", "-c", command],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=self.env,
            cwd=ROOT,
        )
        return Terminal(proc)

    def close(self) -> None:
        self.holder.stdin.close()
        try:
            self.holder.wait(10)
        except subprocess.TimeoutExpired:
            self.holder.kill()
            self.holder.wait()


class Terminal:
    """One terminal's process: its output lines as they come (read on a thread), what is typed."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self.times: list[float] = []  # when each line came (monotonic)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.times.append(time.monotonic())
            self.lines.append(line.rstrip("\n"))

    def type(self, line: str) -> None:
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def wait_for(self, text: str, timeout: float, start: int = 0) -> int:
        """The index of the first line from ``start`` on that holds ``text`` (looked for at least
        once, until ``timeout`` s have passed or the process has ended)."""
        end = time.monotonic() + timeout
        while True:
            ended = self.proc.poll() is not None
            if ended:
                time.sleep(0.5)  # the reader's last lines
            for n in range(start, len(self.lines)):
                if text in self.lines[n]:
                    return n
            if ended or time.monotonic() > end:
                break
            time.sleep(0.1)
        raise AssertionError(f"no {text!r} within {timeout:g} s:\n" + "\n".join(self.lines[-40:]))

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


def local_position(mavproxy: Terminal) -> dict[str, float]:
    """The vehicle's LOCAL_POSITION_NED, asked of MAVProxy (`status LOCAL_POSITION_NED`)."""
    start = len(mavproxy.lines)
    mavproxy.type("status LOCAL_POSITION_NED")
    n = mavproxy.wait_for("LOCAL_POSITION_NED {", 20, start)
    return {k: float(v) for k, v in re.findall(r"(\w+) : ([-+.\deE]+)", mavproxy.lines[n])}


def fly_to(mavproxy: Terminal, north: float, down: float, timeout: float = 120.0) -> dict[str, float]:
    """Wait, as the user does, until the vehicle hovers at (north, down) from home."""
    end = time.monotonic() + timeout
    p: dict[str, float] = {}
    while time.monotonic() < end:
        p = local_position(mavproxy)
        if math.hypot(p["x"] - north, p["z"] - down) < 0.25 and math.hypot(p["vx"], p["vz"]) < 0.1:
            return p
        time.sleep(0.5)
    raise AssertionError(f"not at ({north}, {down}) within {timeout:g} s: {p}")


def test_the_walkthrough_lands_on_the_roof_and_disarms():
    if shutil.which("mavproxy.py") is None or shutil.which("unshare") is None:
        if os.environ.get("CI") == "true":
            pytest.fail("MAVProxy (.[test]) and unshare (util-linux) are needed")
        pytest.skip("MAVProxy or unshare is not installed")
    blocks = walkthrough(PAGE.read_text())
    wall0 = time.monotonic()
    sandbox = Sandbox()
    terminals: list[Terminal] = []
    try:
        mavproxy = land = None
        for block in blocks:
            if block.kind == "text":  # typed at MAVProxy's prompt, each awaited as a user would
                assert mavproxy is not None
                north, down = 0.0, 0.0
                for line in block.typed:
                    start = len(mavproxy.lines)
                    mavproxy.type(line)
                    words = line.split()
                    if words[0] == "position":
                        north, down = north + float(words[1]), down + float(words[3])
                        fly_to(mavproxy, north, down)
                    else:
                        mavproxy.wait_for("ACCEPTED", 30, start)  # COMMAND_ACK
                    if words[0] == "takeoff":
                        down = -float(words[1])
                        fly_to(mavproxy, north, down)
                continue
            term = sandbox.run(block.text)
            terminals.append(term)
            ready = next((text for program, text in READY.items() if program in block.text), None)
            if ready is not None:
                term.wait_for(ready, 600)  # a first start compiles the model
                mavproxy = term if "mavproxy.py" in block.text else mavproxy
            else:
                land = term
                assert term.proc.wait(600) == 0, term.text
        assert mavproxy is not None and land is not None
        verdict = mavproxy.wait_for("Landing: ", 30)
        mavproxy.wait_for("DISARMED", 30, verdict)
        rest = local_position(mavproxy)
    finally:
        sandbox.close()
    wall = time.monotonic() - wall0
    print(f"walkthrough: {wall:.0f} s wall\n{land.text}")
    vehicle = terminals[1].text
    assert "outcome: LANDED" in land.text, land.text
    # the vehicle's own verdict (the model's classes): it stayed on the roof, neither slid off nor
    # flipped. Mostly "ideal"; 2 runs of 15 on 2026-11-26 ended in another class, the one whose
    # verdict was kept "joint_touch" (a joint touched the roof, a failure in the paper's terms; its
    # reverse thrust ran 0.99 s instead of about 0.5 s): printed here, not hidden
    verdict_line = mavproxy.lines[verdict]
    print(verdict_line)
    outcome = re.search(r"Landing: (\w+)", verdict_line).group(1)
    assert outcome not in ("slid", "flip", "damaged"), f"{verdict_line}\n{land.text}"
    # at rest on the roof past its edge, as high over the roof's surface as it sat over the pad
    # at home (NED from home: the body over the roof is as far above the roof as home was above
    # the pad, within the legs' compression and the slope's lean)
    slope = math.radians(float(re.search(r"slope_deg=([\d.]+)", vehicle).group(1)))
    roof_x, roof_z = 3.0, 0.5  # the scenario's defaults (docs/simulated-vehicle.md)
    assert rest["x"] > roof_x + 0.5, rest
    surface_down = -(roof_z - (rest["x"] - roof_x) * math.tan(slope))
    assert abs(rest["z"] - surface_down) < 0.15, (rest, surface_down)
    # MAVProxy's first minute with this vehicle: no false fence breach, parameters without FTP time-outs
    assert "fence breach" not in mavproxy.text.lower(), mavproxy.text
    assert "FTP: request timed out" not in mavproxy.text, mavproxy.text
    detected, params = mavproxy.wait_for("Detected vehicle", 0), mavproxy.wait_for(" parameters", 0)
    assert mavproxy.times[params] - mavproxy.times[detected] < 5.0, mavproxy.text  # one FTP time-out: 2 s
