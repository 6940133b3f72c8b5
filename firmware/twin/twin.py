"""The firmware twin: the release ELF of the sleeve firmware on an emulated STM32F405.

The CPU is unicorn's Cortex-M4 (QEMU's instruction set model). Everything around it
is modelled, register by register, from the STM32F405 reference manual (RM0090)
and the ARMv7-M architecture reference manual (exception entry and return, NVIC),
in modules of their own: `twin_core` (time base, constants, ELF, RCC, PWR,
TIM2-TIM7), `twin_usart_flash` (USARTs, the flash interface), `twin_periph` (IWDG,
GPIO, EXTI, NVIC), `twin_exceptions` (exception entry and return) and `twin_board`
(memory, the run loop). This module gathers what the tests and tools use, and
serves a board on a pseudo-terminal.
What is and is not modelled is in README.md.
"""

from unicorn import UC_HOOK_CODE
from unicorn import arm_const as A

from twin_board import Board
from twin_core import (BANK_BASE, ENTRY_CYCLES, FLASH_BASE, HARDFAULT, IRQ, MASKED_STEP, T_HZ, NotModelled,
                       load_elf)
from twin_usart_flash import Flash

__all__ = ["A", "BANK_BASE", "Board", "ENTRY_CYCLES", "FLASH_BASE", "Flash", "HARDFAULT", "IRQ", "MASKED_STEP",
           "NotModelled", "T_HZ", "UC_HOOK_CODE", "load_elf", "serve", "serve_pty"]


def serve_pty(board, link_path, send, take, ready=lambda: True, seconds=None, speed=1.0, stop=None):
    """Runs `board` in step with the wall clock (`speed` emulated seconds per
    second, at most) with a wire on a pseudo-terminal, whose path is linked at
    `link_path`: what a program writes to the port goes to `send(bytes)` while
    `ready()` (else it waits, as a program's writes wait on a port that is not
    there yet), and what `take()` gives back is written to the port. Stops after
    `seconds` (emulated), when `stop` (a threading.Event) is set, or when
    interrupted."""
    import os
    import select
    import time
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    # The link, and beside it the process that serves it: `touchc sleeve` takes the
    # link for a sleeve only while this process lives (a killed twin leaves the link).
    pid_path = os.path.splitext(link_path)[0] + ".pid"
    for path in (link_path, pid_path):
        if os.path.lexists(path):
            os.unlink(path)
    os.symlink(os.ttyname(slave), link_path)
    with open(pid_path, "w") as f:
        f.write(f"{os.getpid()}\n")
    step = 0.001
    try:
        start, t0 = time.monotonic(), board.t
        while (seconds is None or board.t - t0 < seconds * T_HZ) and not (stop and stop.is_set()):
            if ready():
                waiting, _, _ = select.select([master], [], [], 0)
                if waiting:
                    try:
                        send(os.read(master, 4096))
                    except OSError:
                        pass  # no process has the port open
            board.run(step)
            out = take()
            if out:
                os.write(master, out)
            ahead = (board.t - t0) / T_HZ / speed - (time.monotonic() - start)
            if ahead > 0:
                select.select([master], [], [], ahead)
    finally:
        for path in (link_path, pid_path):
            if os.path.lexists(path):
                os.unlink(path)
        os.close(master)
        os.close(slave)
    return board


def serve(board, link_path, usart="USART2", seconds=None, speed=1.0, stop=None):
    """`board` served with a USART's wire on a pseudo-terminal linked at
    `link_path` (see `serve_pty`): `touchc sleeve --port LINK_PATH ...` then talks
    to the twin as to a sleeve on a USB-serial adapter."""
    port = board.usarts[usart]
    return serve_pty(board, link_path, port.send, port.take, seconds=seconds, speed=speed, stop=stop)


if __name__ == "__main__":
    import argparse
    import os
    import signal
    import sys
    import tempfile

    ap = argparse.ArgumentParser(description="The sleeve firmware on the twin, its USART on a pseudo-terminal.")
    ap.add_argument("elf")
    default_link = os.path.join(tempfile.gettempdir(), "touchc-sleeve-twin")
    ap.add_argument("--link", default=default_link,
                    help="path of a symlink to the pseudo-terminal (the --port for touchc; by default the one "
                         "`touchc sleeve` finds by itself: %(default)s)")
    ap.add_argument("--bank", help="a bank image in the bank region (default: erased)")
    ap.add_argument("--usart", default="USART2")
    ap.add_argument("--seconds", type=float, help="stop after this many emulated seconds")
    ap.add_argument("--speed", type=float, default=1.0, help="emulated seconds per wall-clock second, at most")
    a = ap.parse_args()
    b = Board(a.elf)
    if a.bank:
        with open(a.bank, "rb") as f:
            b.set_bank(f.read())
    # A terminated twin (kill, a closed terminal) removes its link too.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        serve(b, a.link, a.usart, a.seconds, a.speed)
    except KeyboardInterrupt:
        pass
