"""ArduPilot's Lua compiles with limits stock Lua 5.3 does not have: a script the stand-in's
Lua (lupa, stock) accepts can fail to load on the autopilot. The rules mirrored, each from
ArduPilot's copy of Lua 5.3:

- ``MAXVARS 100`` (libraries/AP_Scripting/lua/src/lparser.c, stock: 200): at most 100 local
  variables declared at once in one function, the main chunk included; past it the load fails
  with "too many local variables (limit is 100) in main function" (``new_localvar``).

The count comes from the compiled chunk's own debug information (``string.dump``: each local's
first and last instruction), so it is the compiler's count, not a reading of the source text.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from lupa import lua53

MAXVARS = 100  # libraries/AP_Scripting/lua/src/lparser.c


@dataclass(frozen=True)
class FunctionLocals:
    line: int  # 0: the main chunk
    most_at_once: int

    @property
    def where(self) -> str:
        """As lparser.c's ``errorlimit`` names a function."""
        return "main function" if self.line == 0 else f"function at line {self.line}"


class _Reader:
    """Lua 5.3's ``string.dump`` format (lundump.c), with the sizes its header gives."""

    def __init__(self, data: bytes) -> None:
        self.b, self.i = data, 0
        if data[:5] != b"\x1bLua\x53" or data[5] != 0:
            raise ValueError("not a Lua 5.3 chunk")
        self.i = 12
        self.int_size, self.size_t, self.instr, self.integer, self.number = data[12:17]
        self.i = 17 + self.integer + self.number

    def byte(self) -> int:
        self.i += 1
        return self.b[self.i - 1]

    def int(self) -> int:
        (v,) = struct.unpack_from({4: "<i", 8: "<q"}[self.int_size], self.b, self.i)
        self.i += self.int_size
        return v

    def skip(self, n: int) -> None:
        self.i += n

    def string(self) -> None:
        size = self.byte()
        if size == 0xFF:
            size = int.from_bytes(self.b[self.i : self.i + self.size_t], "little")
            self.i += self.size_t
        if size:
            self.skip(size - 1)

    def function(self, out: list[FunctionLocals]) -> None:
        self.string()  # source
        line = self.int()
        self.int()  # last line
        self.skip(3)  # numparams, is_vararg, maxstacksize
        ncode = self.int()
        self.skip(ncode * self.instr)
        for _ in range(self.int()):  # constants
            tag = self.byte()
            if tag == 1:
                self.skip(1)
            elif tag == 3:
                self.skip(self.number)
            elif tag == 19:
                self.skip(self.integer)
            elif tag in (4, 20):
                self.string()
        self.skip(2 * self.int())  # upvalues: instack, idx
        for _ in range(self.int()):  # nested functions
            self.function(out)
        self.skip(self.int() * self.int_size)  # line info
        spans = []
        for _ in range(self.int()):  # locals: name, first and last instruction
            self.string()
            spans.append((self.int(), self.int()))
        for _ in range(self.int()):  # upvalue names
            self.string()
        most = max((sum(1 for a, b in spans if a <= pc < b) for pc in range(ncode + 1)), default=0)
        out.append(FunctionLocals(line, most))


def locals_per_function(source: str) -> list[FunctionLocals]:
    """Each function's (and the main chunk's) most locals alive at once, compiled by stock Lua
    5.3. A syntax error raises ``lupa.lua53.LuaSyntaxError``."""
    lua = lua53.LuaRuntime(register_eval=False, encoding=None)  # the dump as bytes
    compiled = lua.compile(source)
    dump = lua.eval("string.dump")(compiled)
    data = dump if isinstance(dump, bytes) else dump.encode("latin-1")
    reader = _Reader(data)
    reader.byte()  # the main chunk's upvalue count
    out: list[FunctionLocals] = []
    reader.function(out)
    return out


def ardupilot_load_error(source: str) -> str | None:
    """The message ArduPilot's Lua would refuse the script with for a limit it has and stock Lua
    has not, or None."""
    for f in locals_per_function(source):
        if f.most_at_once > MAXVARS:
            return f"too many local variables (limit is {MAXVARS}) in {f.where}"
    return None
