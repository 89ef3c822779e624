"""What must hold between the board, its calibration and the lookup table before a flight.

``slopelander legs status --calibration FILE`` runs these without flying; opening the board
has already refused a board of another protocol version or leg count and a calibration made
on another board (:meth:`slopelander.legs.driver.LegBoard.connect`).
"""

from __future__ import annotations

from pathlib import Path

from slopelander.legs.driver import BoardStatus, LegBoard
from slopelander.legs.errors import LegBoardError
from slopelander.legs.messages import FAULT_TEXT, LegState


def preflight(board: LegBoard, status: BoardStatus, table: str | Path | None = None) -> list[str]:
    """Every reason the legs are not ready to fly (empty if they are)."""
    from slopelander.controller.table import DEFAULT_TABLE, LookupTable

    cal = board.calibration
    info = board.info
    problems = []
    for s in status.legs:
        if s.state is LegState.FAULT:
            problems.append(f"leg {s.leg} faulted: {FAULT_TEXT[s.fault]} (loosen it after the repair)")
    if info is not None and not info.simulated and cal.provenance != "measured":
        problems.append(
            f"a real leg board flies only with a measured calibration; {cal.source} is {cal.provenance} "
            "(slopelander legs calibrate)"
        )
    if info is not None and not info.simulated and cal.provenance == "measured" and cal.board_id is None:
        problems.append(f"{cal.source} names no board_id: it cannot be checked against this board")
    path = table or DEFAULT_TABLE
    lookup = LookupTable.load(path)
    for pair in ("tau_up", "tau_down"):
        wanted = sorted({float(v) for v in lookup.cells[pair].ravel()})
        for leg in range(len(cal.legs)):
            bad = []
            for tau in wanted:
                if tau == 0:
                    continue
                try:
                    cal.current_for(leg, tau)
                except LegBoardError:
                    bad.append(tau)
            if bad:
                curve = cal.legs[leg]
                problems.append(
                    f"leg {leg} cannot take the table's {pair} of {', '.join(f'{t:g}' for t in bad)} N·m: "
                    f"{cal.source} covers {curve.min_torque_nm:g}–{curve.max_torque_nm:g} N·m ({path})"
                )
    angles = sorted({float(v) for v in lookup.cells["angle_up_deg"].ravel()})
    lo, hi = cal.angle_range_deg
    outside = [a for a in angles if not lo <= a <= hi]
    if outside:
        problems.append(
            f"the table's uphill angles {', '.join(f'{a:g}' for a in outside)} deg are outside the "
            f"legs' range {lo:g}–{hi:g} deg ({cal.source})"
        )
    return problems
