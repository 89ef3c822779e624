"""The PIO program that counts a motor encoder, in rp2's assembler (names the decorator injects)."""

# ruff: noqa: F821

import rp2


@rp2.asm_pio()
def quadrature_x1():
    # x1 decoding: on every rising edge of A, count up if B is low, down if it is high; the
    # count is in X, and the CPU reads it by executing "mov isr, x; push" (Rp2040Hal.encoder)
    wrap_target()
    wait(0, pin, 0)
    wait(1, pin, 0)
    jmp(pin, "down")
    mov(x, invert(x))  # x + 1 is ~(~x - 1)
    jmp(x_dec, "up")
    label("up")
    mov(x, invert(x))
    jmp("end")
    label("down")
    jmp(x_dec, "end")
    label("end")
    wrap()
