"""A stand-in for MicroPython's ``rp2`` (tests only: there is no Pico here). ``asm_pio`` runs the
program's function with the PIO assembler's names in its globals, as MicroPython's does, and
records the instructions; ``StateMachine`` executes them on its two input pins (``machine.LEVEL``)
whenever :func:`settle` is called, so the encoder's PIO program itself is what counts."""

import machine

_MASK = 0xFFFFFFFF
MACHINES = []


class _Invert:
    def __init__(self, src):
        self.src = src


def asm_pio(**kw):
    def assemble(f):
        program = []
        names = {
            "pin": "pin",
            "x": "x",
            "isr": "isr",
            "x_dec": "x_dec",
            "invert": _Invert,
            "wrap_target": lambda: program.append(("wrap_target",)),
            "wrap": lambda: program.append(("wrap",)),
            "label": lambda name: program.append(("label", name)),
            "wait": lambda pol, src, index: program.append(("wait", pol, src, index)),
            "jmp": lambda a, b=None: program.append(("jmp", None, a) if b is None else ("jmp", a, b)),
            "mov": lambda dst, src: program.append(("mov", dst, src)),
        }
        g = f.__globals__
        saved = {k: g[k] for k in names if k in g}
        g.update(names)
        try:
            f()
        finally:
            for k in names:
                del g[k]
            g.update(saved)
        return program

    return assemble


class StateMachine:
    def __init__(self, id, program, in_base=None, jmp_pin=None):
        self.program = program
        self.a = in_base.id
        self.b = jmp_pin.id
        self.x = 0
        self.isr = 0
        self.fifo = []
        self.pc = 0
        self.running = False
        self.labels = {ins[1]: i for i, ins in enumerate(program) if ins[0] == "label"}
        MACHINES.append(self)

    def active(self, on):
        self.running = bool(on)
        settle()

    def exec(self, text):
        if text == "set(x, 0)":
            self.x = 0
        elif text == "mov(isr, x)":
            self.isr = self.x
        elif text == "push()":
            self.fifo.append(self.isr)
        else:
            raise ValueError(text)

    def get(self):
        return self.fifo.pop(0)

    def run(self):
        """Execute until the program waits on a pin level it does not see."""
        for _ in range(1000):
            ins = self.program[self.pc]
            op = ins[0]
            if op == "wait":
                if machine.LEVEL.get(self.a + ins[3], 1) != ins[1]:
                    return
                self.pc += 1
            elif op == "jmp":
                cond, target = ins[1], ins[2]
                if cond is None:
                    take = True
                elif cond == "pin":
                    take = machine.LEVEL.get(self.b, 1) == 1
                else:  # x_dec: jump if X is not zero, decrementing it either way
                    take = self.x != 0
                    self.x = (self.x - 1) & _MASK
                self.pc = self.labels[target] if take else self.pc + 1
            elif op == "mov":
                src = ins[2]
                self.x = (~self.x) & _MASK if isinstance(src, _Invert) else self.x
                self.pc += 1
            elif op == "wrap":
                self.pc = next(i for i, s in enumerate(self.program) if s[0] == "wrap_target")
            else:
                self.pc += 1
        raise RuntimeError("PIO program ran 1000 steps without waiting")


def settle():
    """Let every running state machine catch up with the pins' levels."""
    for sm in MACHINES:
        if sm.running:
            sm.run()


def turn(pin_a, cycles):
    """Turn a motor's encoder (A on ``pin_a``, B on the next pin) ``cycles`` quadrature cycles:
    forward (> 0) A leads B, backward B leads A."""
    steps = ((1, 0), (1, 1), (0, 1), (0, 0)) if cycles > 0 else ((0, 1), (1, 1), (1, 0), (0, 0))
    for _ in range(abs(cycles)):
        for a, b in steps:
            machine.LEVEL[pin_a] = a
            machine.LEVEL[pin_a + 1] = b
            settle()
