"""A scripted full-speed USB host for the twin: one root port, one device (`otg_fs`).

It does what a computer does when a sleeve is plugged in (USB 2.0 chapter 9, and the
order Linux's hub driver uses): waits 100 ms after the device pulls D+ up, resets the
bus, reads the device descriptor at address 0, resets again, sets an address, reads
the device, configuration and string descriptors, sets the configuration, then opens
the CDC-ACM port (SET_LINE_CODING, SET_CONTROL_LINE_STATE with DTR) and keeps a read
pending on its bulk IN endpoint, as a serial driver does. Bytes written to the port
go out on the bulk OUT endpoint in 64-byte packets.

The bus is full speed (12 Mbit/s): every transaction takes its bits' time (token,
data with its CRC, handshake, turnarounds; no bit stuffing) out of a budget that
grows with the board's clock, so the host never moves more than the wire could. The
host runs every `STEP_S` of emulated time (an event on the board); a pipe the device
NAKs is retried at the next step, 50 us later (about one 64-byte transaction's time:
a host retries a NAKed bulk pipe back to back). Data toggles are the host's own: it keeps one per
pipe, resets them to DATA0 after SET_CONFIGURATION and CLEAR_FEATURE(ENDPOINT_HALT)
(USB 2.0 9.1.1.5, 9.4.5), drops a data packet whose PID is not the expected one, and
a device that did not reset its own loses that packet (see test_usb.py).
"""

import struct

import twin

STEP_S = 1 / 20000
BIT_S = 1 / 12_000_000
STEP_BITS = round(STEP_S / BIT_S)
TOKEN, HANDSHAKE, GAP = 35, 19, 8  # bits: SYNC PID ADDR ENDP CRC5 EOP; SYNC PID EOP; turnaround
MPS = 64
# Standard requests (USB 2.0 table 9-4) and CDC PSTN ones (PSTN 1.2 table 13).
CLEAR_FEATURE, SET_ADDRESS, GET_DESCRIPTOR, SET_CONFIGURATION = 1, 5, 6, 9
SET_LINE_CODING, SET_CONTROL_LINE_STATE = 0x20, 0x22
DEVICE, CONFIGURATION, STRING = 1, 2, 3
LANG_EN_US = 0x0409


def data_bits(n):
    return TOKEN + GAP + TOKEN + 8 * n + GAP + HANDSHAKE


class UsbError(Exception):
    """The device did not do what the host asked in time, or stalled."""


class UsbHost:
    """The host port, stepped by the board. `port_*` is the CDC-ACM serial port's
    view: `send` queues bytes for the device, `take` returns what it sent."""

    def __init__(self, board, otg, address=5, line=(460_800, 0, 0, 8)):
        self.b, self.otg = board, otg
        self.address, self.line = address, line
        self.addr = 0  # the address the device answers on, as far as the host knows
        self.state = "detached"  # attached, configured, failed
        self.script = None  # the control pipe's work: a generator, stepped
        self.queue = []  # control scripts waiting for the pipe
        self.budget = 0
        self.tx, self.rx = bytearray(), bytearray()
        self.toggle = {}  # endpoint address -> the PID the host sends or expects next
        self.bulk_out, self.bulk_in = None, None
        self.log = []  # (t, text)
        self.in_packets = []  # (t, length) of every bulk IN data packet taken
        self.dropped = []  # (t, endpoint, length): data packets dropped for their PID
        self.descriptors = {}
        self.strings = {}
        self.attached_at = self.configured_at = None
        self.sent_at = None  # when the device took the last OUT packet
        self.error = None
        self._next = board.t
        board.at(board.now(), self._step)

    # -- the port, as a program sees it
    def send(self, data):
        """Queues bytes for the device (a write to the serial port)."""
        if self.state == "configured":
            self.tx += data

    def take(self):
        """The bytes the device sent since the last call."""
        out, self.rx = bytes(self.rx), bytearray()
        return out

    def plug(self, on=True):
        """Plugs the cable in (VBUS on) or pulls it out."""
        self.otg.set_vbus(on)
        self.log.append((self.b.t, "plug" if on else "unplug"))

    def control(self, gen):
        """Runs a control script (e.g. `self.set_configuration()`) once the pipe is
        free; returns a list that gets its result (or the exception) when done."""
        box = []
        self.queue.append((gen, box))
        return box

    # -- stepping
    def _step(self, b):
        self.budget = min(self.budget + STEP_BITS, 2 * STEP_BITS)
        connected = self.otg.connected()
        if self.state != "detached" and not connected:
            self._detach()
        elif self.state == "detached" and connected:
            self.state = "attached"
            self.attached_at = b.t
            self.log.append((b.t, "attach"))
            self.queue.insert(0, (self._enumerate(), []))
        if self.state != "detached":
            self._run_control()
            if self.state == "configured":
                self._bulk()
        # Nothing on the bus while detached: look for an attach once a millisecond.
        self._next += round((STEP_S if self.state != "detached" else 0.001) * twin.T_HZ)
        b.events.append((self._next, -1, self._step))
        b.events.sort(key=lambda e: (e[0], e[1]))

    def _detach(self):
        self.log.append((self.b.t, "detach"))
        self.state, self.addr = "detached", 0
        self.script, self.queue = None, []
        self.tx = bytearray()

    def _run_control(self):
        if self.script is None and self.queue:
            self.script = self.queue.pop(0)
        if self.script is None:
            return
        gen, box = self.script
        try:
            next(gen)
        except StopIteration as done:
            box.append(done.value)
            self.script = None
        except UsbError as e:
            self.log.append((self.b.t, f"error: {e}"))
            box.append(e)
            self.script = None
            if self.state == "attached":
                self.state, self.error = "failed", e

    def _spend(self, bits):
        """Waits (yields) until the bus has room for `bits`, then takes them."""
        while self.budget < bits:
            yield
        self.budget -= bits

    # -- bulk pipes
    def _bulk(self):
        out_ep, in_ep = self.bulk_out, self.bulk_in
        while self.tx:
            n = min(MPS, len(self.tx))
            if self.budget < data_bits(n):
                break
            self.budget -= data_bits(n)
            r = self.otg.out(self.addr, out_ep, bytes(self.tx[:n]), self.toggle[out_ep])
            if r != "ACK":
                break
            self.toggle[out_ep] ^= 1
            del self.tx[:n]
            self.sent_at = self.b.t
        while self.budget >= data_bits(MPS):
            r = self.otg.in_(self.addr, in_ep & 0x7F)
            if not isinstance(r, tuple):
                self.budget -= TOKEN + GAP + HANDSHAKE
                break
            _, pid, data = r
            self.budget -= data_bits(len(data))
            if pid != self.toggle[in_ep]:
                self.dropped.append((self.b.t, in_ep, len(data)))
                continue
            self.toggle[in_ep] ^= 1
            self.rx += data
            self.in_packets.append((self.b.t, len(data)))

    # -- control transfers (generators: `yield` waits for the next step)
    def _deadline(self, timeout):
        return self.b.t + round(timeout * twin.T_HZ)

    def _late(self, deadline, what):
        if self.b.t > deadline:
            raise UsbError(f"{what}: no answer")

    def transfer(self, bm, req, value, index, length=0, data=b"", timeout=0.5):
        """One control transfer: SETUP, data stage, status stage. Returns the IN
        data (or b""); raises UsbError on a STALL or a timeout."""
        deadline = self._deadline(timeout)
        what = f"request {bm:#04x} {req} {value:#06x}"
        setup = struct.pack("<BBHHH", bm, req, value, index, length if bm & 0x80 else len(data))
        while True:
            yield from self._spend(data_bits(8))
            if self.otg.setup(self.addr, setup) == "ACK":
                break
            self._late(deadline, what)
            yield
        got, pid = bytearray(), 1
        chunks = [data[i:i + MPS] for i in range(0, len(data), MPS)] if not bm & 0x80 else []
        while bm & 0x80 or chunks:
            yield from self._spend(data_bits(MPS))
            if bm & 0x80:
                r = self.otg.in_(self.addr, 0)
            else:
                r = self.otg.out(self.addr, 0, chunks[0], pid)
            if r == "STALL":
                raise UsbError(f"{what}: STALL")
            if r == "ACK" or isinstance(r, tuple):
                if isinstance(r, tuple) and r[1] == pid:
                    got += r[2]
                pid ^= 1
                if not bm & 0x80:
                    chunks.pop(0)
                elif len(r[2]) < MPS or len(got) >= length:
                    break
                continue
            self._late(deadline, what)
            yield
        # Status stage: the other direction, DATA1, zero length.
        while True:
            yield from self._spend(data_bits(0))
            r = self.otg.out(self.addr, 0, b"", 1) if bm & 0x80 else self.otg.in_(self.addr, 0)
            if r == "STALL":
                raise UsbError(f"{what}: STALL in the status stage")
            if r == "ACK" or (isinstance(r, tuple) and not r[2]):
                return bytes(got)
            self._late(deadline, what)
            yield

    def wait(self, seconds):
        end = self._deadline(seconds)
        while self.b.t < end:
            yield

    def reset(self):
        """SE0 for 20 ms (USBRST at its start, ENUMDNE at its end), 10 ms recovery."""
        self.otg.bus_reset()
        self.addr = 0
        yield from self.wait(0.020)
        self.otg.reset_done()
        yield from self.wait(0.010)

    def descriptor(self, kind, index=0, length=255, lang=0):
        return (yield from self.transfer(0x80, GET_DESCRIPTOR, kind << 8 | index, lang, length))

    def _enumerate(self):
        yield from self.wait(0.100)  # attach debounce (USB 2.0 7.1.7.3)
        yield from self.reset()
        self.descriptors["device0"] = yield from self.descriptor(DEVICE, length=64)
        yield from self.reset()
        yield from self.transfer(0x00, SET_ADDRESS, self.address, 0)
        self.addr = self.address
        yield from self.wait(0.002)  # SET_ADDRESS recovery (USB 2.0 9.2.6.3)
        dev = yield from self.descriptor(DEVICE, length=18)
        self.descriptors["device"] = dev
        head = yield from self.descriptor(CONFIGURATION, length=9)
        total = struct.unpack_from("<H", head, 2)[0]
        self.descriptors["configuration"] = yield from self.descriptor(CONFIGURATION, length=total)
        langs = yield from self.descriptor(STRING, 0)
        self.strings[0] = langs
        for i in (dev[14], dev[15], dev[16]):
            if i:
                raw = yield from self.descriptor(STRING, i, lang=LANG_EN_US)
                self.strings[i] = raw[2:raw[0]].decode("utf-16-le")
        yield from self.set_configuration()
        yield from self.open_port()
        self.state = "configured"
        self.configured_at = self.b.t
        self.log.append((self.b.t, "configured"))

    def endpoints(self):
        """(address, attributes, max packet size) of every endpoint descriptor."""
        cfg, out, i = self.descriptors.get("configuration", b""), [], 0
        while i + 1 < len(cfg):
            if cfg[i + 1] == 5:
                out.append((cfg[i + 2], cfg[i + 3], struct.unpack_from("<H", cfg, i + 4)[0]))
            i += cfg[i]
        return out

    def set_configuration(self, value=1):
        """SET_CONFIGURATION; every pipe's toggle back to DATA0."""
        yield from self.transfer(0x00, SET_CONFIGURATION, value, 0)
        for ep, attrs, _ in self.endpoints():
            self.toggle[ep] = 0
            if attrs & 3 == 2:
                if ep & 0x80:
                    self.bulk_in = ep
                else:
                    self.bulk_out = ep

    def clear_halt(self, ep):
        """CLEAR_FEATURE(ENDPOINT_HALT) on `ep`; its toggle back to DATA0."""
        yield from self.transfer(0x02, CLEAR_FEATURE, 0, ep)
        self.toggle[ep] = 0

    def open_port(self):
        """What a serial driver does when a program opens the port."""
        baud, stop, parity, bits = self.line
        coding = struct.pack("<IBBB", baud, stop, parity, bits)
        yield from self.transfer(0x21, SET_LINE_CODING, 0, 0, data=coding)
        yield from self.transfer(0x21, SET_CONTROL_LINE_STATE, 0x3, 0)  # DTR, RTS

    # -- the CDC-ACM port as test_twin.Host's transport
    def port_ready(self, timeout=2.0):
        """Runs the board until the port is configured (or raises UsbError)."""
        end = self._deadline(timeout)
        while self.state != "configured" and self.b.t < end:
            if self.state == "failed":
                raise UsbError(f"enumeration failed: {self.error}")
            self.b.run(0.001)
        if self.state != "configured":
            raise UsbError(f"not configured after {timeout} s (state {self.state}, log {self.log[-4:]})")


# ------------------------------------------------------------------ serving


def serve(board, host, link_path, seconds=None, speed=1.0, stop=None):
    """Runs `board` in step with the wall clock with the host's CDC-ACM port on a
    pseudo-terminal linked at `link_path` (`twin.serve_pty`), as the port a
    computer shows for the sleeve (/dev/ttyACM0, COM3): `touchc sleeve --port
    LINK_PATH ...` talks to the twin over USB. While the device is not configured
    (before its enumeration, or while it restarts after an upload) the port's
    bytes wait, as a program's writes wait on a port that reappears. Stops after
    `seconds` (emulated), when `stop` is set, or when interrupted."""
    return twin.serve_pty(board, link_path, host.send, host.take,
                          ready=lambda: host.state == "configured" and not host.tx,
                          seconds=seconds, speed=speed, stop=stop)


if __name__ == "__main__":
    import argparse
    import signal
    import sys

    import otg_fs

    ap = argparse.ArgumentParser(description="The sleeve firmware on the twin, its USB port on a pseudo-terminal.")
    ap.add_argument("elf")
    ap.add_argument("--link", required=True, help="path of a symlink to the pseudo-terminal (the --port for touchc)")
    ap.add_argument("--bank", help="a bank image in the bank region (default: erased)")
    ap.add_argument("--uid", default="303132333435363738393a3b", help="the chip's 96-bit unique ID, hexadecimal")
    ap.add_argument("--seconds", type=float, help="stop after this many emulated seconds")
    ap.add_argument("--speed", type=float, default=1.0, help="emulated seconds per wall-clock second, at most")
    a = ap.parse_args()
    b = twin.Board(a.elf)
    if a.bank:
        with open(a.bank, "rb") as f:
            b.set_bank(f.read())
    otg_fs.write_uid(b, bytes.fromhex(a.uid))
    h = UsbHost(b, b.attach(otg_fs.OtgFs(b)))
    h.plug(True)
    # A terminated twin (kill, a closed terminal) removes its link too.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        serve(b, h, a.link, a.seconds, a.speed)
    except KeyboardInterrupt:
        pass
