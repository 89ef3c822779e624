"""The vehicle's MAVLink endpoints: one pymavlink connection per --endpoint string (a channel,
numbered in order), a message sent to all of them or to one, messages received from any of them
(with the channel number). Each channel numbers its own frames, as each of ArduPilot's
GCS_MAVLINK channels does: a message sent on one link leaves no gap in another's sequence."""

from __future__ import annotations

import os
import struct
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "ardupilotmega")

import contextlib

from pymavlink import mavutil

mavlink = mavutil.mavlink


class EndpointError(RuntimeError):
    """An endpoint string that cannot be opened."""


class Endpoints:
    def __init__(self, urls: list[str], sysid: int = 1, compid: int = 1, tlog: Path | None = None) -> None:
        if not urls:
            raise EndpointError("at least one --endpoint is needed (e.g. tcpin:127.0.0.1:5760)")
        self.conns = []
        for url in urls:
            try:
                c = mavutil.mavlink_connection(
                    url,
                    source_system=sysid,
                    source_component=compid,
                    dialect="ardupilotmega",
                    autoreconnect=True,
                )
            except Exception as exc:  # pymavlink raises many kinds for a bad address
                self.close()
                raise EndpointError(f"cannot open endpoint {url!r}: {exc}") from None
            c.mav.srcSystem, c.mav.srcComponent = sysid, compid
            self.conns.append(c)
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.sysid, self.compid = sysid, compid
        self.seqs = [0] * len(self.conns)
        self._tlog = open(tlog, "ab") if tlog else None  # noqa: SIM115 - open for the process's life

    def _targets(self, chan: int | None) -> range | list[int]:
        """Every channel for None (or a channel this vehicle does not have), else that one."""
        return range(len(self.conns)) if chan is None or not 0 <= chan < len(self.conns) else [chan]

    def send(self, msg: mavlink.MAVLink_message, chan: int | None = None) -> None:
        """Pack with each channel's own sequence number and write to every endpoint, or to
        channel ``chan`` only."""
        for n, i in enumerate(self._targets(chan)):
            self.mav.seq = self.seqs[i]
            buf = msg.pack(self.mav)
            self.seqs[i] = (self.seqs[i] + 1) % 256
            self._write(i, buf, log=n == 0)

    def send_payload(self, chan: int, msgid: int, payload: bytes) -> bool:
        """Frame a payload in wire order as a MAVLink 2 message (what ``mavlink:send_chan`` does)."""
        cls = mavlink.mavlink_map.get(msgid)
        if cls is None:
            return False
        size = cls.unpacker.size
        body = bytes(payload[:size]).ljust(size, b"\0").rstrip(b"\0") or b"\0"
        for n, i in enumerate(self._targets(chan)):
            hdr = struct.pack(
                "<BBBBBBBHB",
                0xFD,
                len(body),
                0,
                0,
                self.seqs[i],
                self.sysid,
                self.compid,
                msgid & 0xFFFF,
                msgid >> 16,
            )
            crc = mavutil.x25crc(hdr[1:] + body)
            crc.accumulate(struct.pack("B", cls.crc_extra))
            self.seqs[i] = (self.seqs[i] + 1) % 256
            self._write(i, hdr + body + struct.pack("<H", crc.crc), log=n == 0)
        return True

    def _write(self, chan: int, buf: bytes, log: bool = True) -> None:
        c = self.conns[chan]
        try:
            if getattr(c, "port", True) is not None:
                c.write(buf)
        except OSError:
            pass  # a client went away: tcpin waits for the next one
        if self._tlog and log:  # a message sent on several links is logged once
            self._tlog.write(struct.pack(">Q", int(time.time() * 1e6)) + buf)

    def receive(self) -> list[tuple[int, mavlink.MAVLink_message]]:
        out = []
        for i, c in enumerate(self.conns):
            for _ in range(64):
                try:
                    m = c.recv_msg()
                except (OSError, mavlink.MAVError):
                    m = None
                if m is None:
                    break
                if m.get_type() != "BAD_DATA":
                    out.append((i, m))
        return out

    def close(self) -> None:
        if self._tlog:
            self._tlog.close()
            self._tlog = None
        for c in self.conns:
            with contextlib.suppress(OSError):
                c.close()
