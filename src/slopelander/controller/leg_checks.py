"""What must hold between the board, its calibration and the lookup table before a flight (here,
beside the table: the leg package knows nothing of it).

``slopelander legs status --calibration FILE`` runs these without flying; opening the board
has already refused a board of another protocol version or leg count and a calibration made
on another board (:meth:`slopelander.legs.driver.LegBoard.connect`).
"""

from __future__ import annotations

from pathlib import Path

from slopelander.controller.table import DEFAULT_TABLE, LookupTable
from slopelander.legs.calibration import Calibration
from slopelander.legs.driver import BoardInfo, BoardStatus, LegBoard
from slopelander.legs.errors import LegBoardError
from slopelander.legs.messages import FAULT_TEXT, LegState


def _fault_problems(status: BoardStatus) -> list[str]:
    """Each faulted leg, with its fault: a leg is loosened only after the repair."""
    return [
        f"leg {s.leg} faulted: {FAULT_TEXT[s.fault]} (loosen it after the repair)"
        for s in status.legs
        if s.state is LegState.FAULT
    ]


def calibration_problems(info: BoardInfo | None, cal: Calibration, given: bool = True) -> list[str]:
    """A real board flies only with a measured calibration that names the board it was measured on:
    the one rule ``land`` and ``legs status`` apply (``given``: whether the pilot named a file)."""
    if info is None or info.simulated:
        return []
    if cal.provenance != "measured":
        why = f"{cal.source} is {cal.provenance}" if given else "no --calibration given"
        return [
            f"a real leg board flies only with a measured calibration ({why}): measure the "
            "current-to-torque curve (slopelander legs calibrate) and pass it with --calibration FILE"
        ]
    if cal.board_id is None:
        return [f"{cal.source} names no board_id: it cannot be checked against this board"]
    return []


def _torques_beyond(cal: Calibration, leg: int, wanted: list[float]) -> list[float]:
    """The torques (N·m, other than none) that leg's calibration cannot set a current for."""
    bad = []
    for tau in wanted:
        if tau == 0:
            continue
        try:
            cal.current_for(leg, tau)
        except LegBoardError:
            bad.append(tau)
    return bad


def _torque_problems(cal: Calibration, lookup: LookupTable, path: str | Path) -> list[str]:
    """Each leg and torque pair whose table torques lie beyond the leg's calibrated curve."""
    problems = []
    for pair in ("tau_up", "tau_down"):
        wanted = sorted({float(v) for v in lookup.cells[pair].ravel()})
        for leg in range(len(cal.legs)):
            bad = _torques_beyond(cal, leg, wanted)
            if bad:
                curve = cal.legs[leg]
                problems.append(
                    f"leg {leg} cannot take the table's {pair} of {', '.join(f'{t:g}' for t in bad)} N·m: "
                    f"{cal.source} covers {curve.min_torque_nm:g}–{curve.max_torque_nm:g} N·m ({path})"
                )
    return problems


def _angle_problems(cal: Calibration, lookup: LookupTable) -> list[str]:
    """The table's uphill angles outside the range the calibration holds for."""
    angles = sorted({float(v) for v in lookup.cells["angle_up_deg"].ravel()})
    lo, hi = cal.angle_range_deg
    outside = [a for a in angles if not lo <= a <= hi]
    if not outside:
        return []
    return [
        f"the table's uphill angles {', '.join(f'{a:g}' for a in outside)} deg are outside the "
        f"legs' range {lo:g}–{hi:g} deg ({cal.source})"
    ]


def preflight(board: LegBoard, status: BoardStatus, table: str | Path | None = None) -> list[str]:
    """Every reason the legs are not ready to fly (empty if they are)."""
    cal = board.calibration
    problems = _fault_problems(status) + calibration_problems(board.info, cal)
    path = table or DEFAULT_TABLE
    lookup = LookupTable.load(path)
    return problems + _torque_problems(cal, lookup, path) + _angle_problems(cal, lookup)
