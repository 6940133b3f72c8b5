"""Prints the USB figures of docs/hardware.md, measured in the twin in one run: the
time from VBUS to a configured port, and a 1 KB and a 200 KB bank uploaded over USB
and over USART2 (BankBegin to the commit's answer) beside the flash's own erase and
program time for the same bank.

    TWIN_ELF=... TWIN_CODES=... python3 usb_figures.py     (run.sh sets up the venv:
    bash firmware/twin/run.sh figures)

The USART2 upload of 200 KB is the slow part (about 3 minutes of wall clock).
"""

import subprocess

import link
import test_twin
import test_usb
import twin
from test_twin import CODES, SCRATCH


def upload_over(kind, image):
    """(seconds, the flash's own seconds) for `image` over `kind` ("USB", "USART2")."""
    if kind == "USB":
        b, _, usb = test_usb.usb_board(erase=True)
        usb.port_ready(timeout=1.0)
        host = test_usb.UsbLink(b, usb)
    else:
        b = test_twin.boot(erase=True)
        host = test_twin.Host(b)
        b.run(0.3)
    host.ok(link.hello)
    return test_usb.timed_upload(host, image)


def main():
    SCRATCH.mkdir(parents=True, exist_ok=True)
    b, _, usb = test_usb.usb_board()
    usb.port_ready(timeout=1.0)
    enum_ms = (usb.configured_at - round(0.05 * twin.T_HZ)) * 1000 / twin.T_HZ
    print(f"| from VBUS on to the port configured | {enum_ms:.0f} ms |")
    for size in (1024, 200 * 1024):
        path = SCRATCH / f"figures-{size}.bank"
        subprocess.run([str(CODES), "big", str(size), str(path)], check=True)
        image = path.read_bytes()
        times = {kind: upload_over(kind, image) for kind in ("USB", "USART2")}
        own = times["USB"][1]
        print(f"| upload of a {len(image):,} B bank (erase, chunks, commit) | USB {times['USB'][0]:.2f} s, "
              f"USART2 {times['USART2'][0]:.2f} s; the flash's own erase + program {own:.2f} s "
              f"(USB {times['USB'][0] / own:.2f}x, USART2 {times['USART2'][0] / own:.2f}x) |")


if __name__ == "__main__":
    main()
