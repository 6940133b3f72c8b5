"""The STM32F405's USB OTG FS core in device mode (RM0090 chapter 34), for the twin.

Written from RM0090's register descriptions (34.16, "OTG_FS registers") and its
programming model (34.17, "OTG_FS programming model"): the core and device registers,
the shared receive FIFO with its status entries (GRXSTSR/GRXSTSP), one transmit FIFO
per IN endpoint (DIEPTXF0, DIEPTXFx, DTXFSTSx), endpoint 0's SETUP, OUT and IN
stages, bulk and interrupt IN/OUT with their data toggles (DPID, SD0PID/SD1PID), the
interrupts and their masks (GINTSTS/GINTMSK, DAINT/DAINTMSK, DIEPINT/DIEPMSK,
DOEPINT/DOEPMSK, DIEPEMPMSK), B-session VBUS sensing on PA9 (GCCFG.VBUSBSEN,
SRQINT, GOTGINT.SEDET), soft disconnect (DCTL.SDIS), and the bus's reset, suspend
and resume as the host drives them.

The host's side is a method per transaction (`setup`, `out`, `in_`): each returns
the handshake the device gives, as the wire would. `usb_host.py` is a host that
uses them. What is and is not modelled is in README.md ("USB").
"""

import twin

BASE, SIZE = 0x5000_0000, 0x4_0000
IRQ = 67  # OTG_FS global interrupt (RM0090 table 61)
EPS = 4  # bidirectional endpoints 0-3 (RM0090 34.2)
FIFO_WORDS = 320  # 1.25 KB of FIFO RAM (RM0090 34.2)
SESSION_S = 0.0005
"""B-session valid follows VBUS this long after the comparator is enabled or VBUS
changes (the comparator's settling; RM0090 gives no figure: a modelled choice)."""

# Core global registers (RM0090 34.16.2).
GOTGCTL, GOTGINT, GAHBCFG, GUSBCFG, GRSTCTL, GINTSTS, GINTMSK = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18
GRXSTSR, GRXSTSP, GRXFSIZ, DIEPTXF0, GCCFG, CID = 0x1C, 0x20, 0x24, 0x28, 0x38, 0x3C
# Device registers (RM0090 34.16.4).
DCFG, DCTL, DSTS, DIEPMSK, DOEPMSK, DAINT, DAINTMSK, DIEPEMPMSK = 0x800, 0x804, 0x808, 0x810, 0x814, 0x818, 0x81C, 0x834
PCGCCTL = 0xE00

# GINTSTS bits.
CMOD, OTGINT, SOF, RXFLVL, NPTXFE = 1 << 0, 1 << 2, 1 << 3, 1 << 4, 1 << 5
ESUSP, USBSUSP, USBRST, ENUMDNE, EOPF = 1 << 10, 1 << 11, 1 << 12, 1 << 13, 1 << 15
IEPINT, OEPINT, PTXFE, SRQINT, WKUPINT = 1 << 18, 1 << 19, 1 << 26, 1 << 30, 1 << 31
# The bits software clears by writing 1 (rc_w1): MMIS, SOF, ESUSP, USBSUSP, USBRST,
# ENUMDNE, ISOODRP, EOPF, IISOIXFR, IPXFR, CIDSCHG, DISCINT, SRQINT, WKUPINT.
GINTSTS_W1C = 0xF030_FC0A
# Endpoint control bits (DIEPCTLx/DOEPCTLx).
USBAEP, DPID, NAKSTS, STALL = 1 << 15, 1 << 16, 1 << 17, 1 << 21
CNAK, SNAK, SD0PID, SD1PID, EPDIS, EPENA = 1 << 26, 1 << 27, 1 << 28, 1 << 29, 1 << 30, 1 << 31
# Endpoint interrupt bits.
XFRC, EPDISD, STUP, TXFE = 1 << 0, 1 << 1, 1 << 3, 1 << 7
# Receive status PKTSTS values in device mode (RM0090 34.16.2, OTG_FS_GRXSTSR).
OUT_DATA, OUT_DONE, SETUP_DONE, SETUP_DATA = 2, 3, 4, 6


class Ep:
    """One endpoint direction's registers and state."""

    def __init__(self, n, is_in):
        self.n, self.is_in = n, is_in
        self.ctl = USBAEP if n == 0 else 0
        self.ctl |= NAKSTS if not is_in else 0
        self.int = 0
        self.tsiz = 0
        self.fifo = []  # IN: the words of its transmit FIFO


class OtgFs:
    """USB OTG FS in device mode, mapped at `BASE`; the bus side is driven by a host."""

    BASE, SIZE, IRQ = BASE, SIZE, IRQ

    def __init__(self, board):
        self.board = board
        self.vbus = False  # the cable: 5 V on VBUS (and on PA9)
        self.errors = []  # (t, text): what RM0090 says software must not do
        self.chip_reset()

    # -- the chip's side
    def chip_reset(self):
        """A system reset: every register to its reset value (RM0090 34.16), the
        pull-up off (PWRDWN clear). The cable keeps VBUS on PA9."""
        self.r = {GOTGCTL: 0x0000_0800, GUSBCFG: 0x0000_0A00, GRXFSIZ: 0x0000_0200,
                  DIEPTXF0: 0x0200_0200, CID: 0x0000_1200, DCFG: 0x0220_0000, DSTS: 0x0000_0010}
        for i in range(1, EPS):
            self.r[0x104 + 4 * (i - 1)] = 0x0200_0400 + 0x200 * (i - 1)
        self.gintsts = 0
        self.gotgint = 0
        self.rx = []  # receive FIFO: [status, data words]
        self.rx_data = []  # words of the popped entry still to read
        self.ins = [Ep(n, True) for n in range(EPS)]
        self.outs = [Ep(n, False) for n in range(EPS)]
        self.address = 0  # the address the device answers on
        self.session = False  # B-session valid, as the core sees it
        self.session_at = None  # when it follows VBUS next
        self.suspended = False
        self.in_reset = False
        self.board.gpio[0].drive(9, 1 if self.vbus else 0)

    def clocked(self):
        return self.board.rcc.read(0x34) >> 7 & 1  # RCC_AHB2ENR.OTGFSEN

    def _valid_now(self):
        g = self.r.get(GCCFG, 0)
        return bool(g & (1 << 16)) and (bool(g & (1 << 21)) or (bool(g & (1 << 19)) and self.vbus))

    def _follow_session(self):
        """Moves the session to what VBUS and GCCFG say, once the comparator settled."""
        want = self._valid_now()
        if want == self.session:
            self.session_at = None
            return
        if self.session_at is None:
            self.session_at = self.board.t + round(SESSION_S * twin.T_HZ)
        if self.board.t >= self.session_at:
            self.session_at = None
            self.session = want
            if want:
                self.gintsts |= SRQINT
            else:
                self.gotgint |= 1 << 2  # SEDET
                self._bus_lost()

    def connected(self):
        """Whether D+ is pulled up: the PHY on, no soft disconnect, a valid session."""
        self._follow_session()
        return (self.clocked() and self.session and not self.r.get(DCTL, 0) & 2
                and bool(self.r.get(GCCFG, 0) & (1 << 16)))

    def set_vbus(self, on):
        """Plugs (5 V on VBUS and PA9) or unplugs the cable."""
        self.vbus = bool(on)
        self.board.gpio[0].drive(9, 1 if on else 0)
        self._follow_session()

    def irq_line(self):
        self._follow_session()
        return bool(self.r.get(GAHBCFG, 0) & 1) and bool(self.gintsts_now() & self.r.get(GINTMSK, 0))

    def next_event(self):
        return self.session_at

    def daint(self):
        v = 0
        mi, mo, emp = self.r.get(DIEPMSK, 0), self.r.get(DOEPMSK, 0), self.r.get(DIEPEMPMSK, 0)
        for n in range(EPS):
            if self.in_int(n) & (mi | (TXFE if emp >> n & 1 else 0)):
                v |= 1 << n
            if self.outs[n].int & mo:
                v |= 1 << (16 + n)
        return v

    def in_int(self, n):
        ep = self.ins[n]
        return ep.int | (TXFE if len(ep.fifo) <= self.tx_depth(n) // 2 else 0)

    def gintsts_now(self):
        v = self.gintsts | PTXFE | NPTXFE
        if self.gotgint:
            v |= OTGINT
        if self.rx:
            v |= RXFLVL
        d = self.daint() & self.r.get(DAINTMSK, 0)
        if d & 0xFFFF:
            v |= IEPINT
        if d >> 16:
            v |= OEPINT
        return v

    def tx_depth(self, n):
        reg = self.r.get(DIEPTXF0 if n == 0 else 0x104 + 4 * (n - 1), 0)
        return reg >> 16

    def read(self, off):
        if not self.clocked():
            return 0
        if off >= 0x1000:
            return self._pop_word()
        if 0x900 <= off < 0x900 + 0x20 * EPS or 0xB00 <= off < 0xB00 + 0x20 * EPS:
            return self._ep_read(off)
        if off == GOTGCTL:
            self._follow_session()
            return (self.r[GOTGCTL] & ~0x000F_0000) | (1 << 16) | (self.session << 19)
        if off == GOTGINT:
            return self.gotgint
        if off == GRSTCTL:
            return (self.r.get(GRSTCTL, 0) & 0x7C0) | (1 << 31)  # AHB idle, resets done at once
        if off == GINTSTS:
            return self.gintsts_now()
        if off in (GRXSTSR, GRXSTSP):
            if not self.rx:
                self.errors.append((self.board.t, "GRXSTS read with the receive FIFO empty"))
                return 0
            status = self.rx[0][0]
            if off == GRXSTSP:
                self._pop_status()
            return status
        if off == DSTS:
            frame = (self.board.t // (twin.T_HZ // 1000)) & 0x3FFF
            return (3 << 1) | (frame << 8) | int(self.suspended)  # full speed
        if off == DAINT:
            return self.daint()
        return self.r.get(off, 0)

    def write(self, off, v):
        if not self.clocked():
            self.board.note("OTG_FS written with its clock off (ignored)")
            return
        if off >= 0x1000:
            self._push_word((off - 0x1000) // 0x1000, v)
        elif 0x900 <= off < 0x900 + 0x20 * EPS or 0xB00 <= off < 0xB00 + 0x20 * EPS:
            self._ep_write(off, v)
        elif off == GOTGINT:
            self.gotgint &= ~v
        elif off == GRSTCTL:
            self._grstctl(v)
        elif off == GINTSTS:
            self.gintsts &= ~(v & GINTSTS_W1C)
        elif off in (GRXSTSR, GRXSTSP, DSTS, DAINT, CID):
            pass  # read-only
        elif off == DCFG:
            self.r[DCFG] = v
        else:
            self.r[off] = v
            if off == GCCFG:
                self._follow_session()

    def _grstctl(self, v):
        if v & 1:  # CSRST: the core's registers but the clock and PHY ones to reset
            keep = {k: self.r[k] for k in (GCCFG, PCGCCTL) if k in self.r}
            vbus, session = self.vbus, self.session
            self.chip_reset()
            self.r.update(keep)
            self.vbus, self.session = vbus, session
            return
        if v & (1 << 4):  # RXFFLSH
            self.rx, self.rx_data = [], []
        if v & (1 << 5):  # TXFFLSH, TXFNUM 0x10 = all
            num = v >> 6 & 0x1F
            for ep in self.ins:
                if num == 0x10 or ep.n == num:
                    ep.fifo = []
        self.r[GRSTCTL] = v & 0x7C0

    # -- endpoint registers
    def _ep(self, off):
        is_in = off < 0xB00
        n = (off - (0x900 if is_in else 0xB00)) // 0x20
        return (self.ins if is_in else self.outs)[n], off & 0x1F

    def _ep_read(self, off):
        ep, reg = self._ep(off)
        if reg == 0x00:
            return ep.ctl
        if reg == 0x08:
            return self.in_int(ep.n) if ep.is_in else ep.int
        if reg == 0x10:
            return ep.tsiz
        if reg == 0x18 and ep.is_in:
            return self.tx_depth(ep.n) - len(ep.fifo)
        return 0

    def _ep_write(self, off, v):
        ep, reg = self._ep(off)
        if reg == 0x08:
            ep.int &= ~v
        elif reg == 0x10:
            ep.tsiz = v
        elif reg == 0x00:
            self._ctl_write(ep, v)

    def _ctl_write(self, ep, v):
        keep = DPID | NAKSTS | (USBAEP if ep.n == 0 else 0)
        ctl = (ep.ctl & keep) | (v & ~(keep | CNAK | SNAK | SD0PID | SD1PID | EPDIS))
        if ep.n == 0:
            ctl = (ctl & ~(0x3 << 18)) | USBAEP  # EP0: always active, always control
        if v & SNAK:
            ctl |= NAKSTS
        if v & CNAK:
            ctl &= ~NAKSTS
        if v & SD0PID and ep.n:
            ctl &= ~DPID
        if v & SD1PID and ep.n:
            ctl |= DPID
        if v & EPDIS and ep.ctl & EPENA:
            ctl &= ~EPENA  # disabled at once (the core needs no time here)
            ep.int |= EPDISD
        if ep.n == 0 and ep.ctl & STALL and not v & STALL:
            ctl |= STALL  # EP0's STALL: only a SETUP clears it (RM0090: rs)
        ep.ctl = ctl

    # -- FIFOs
    def _push_word(self, n, v):
        if n >= EPS:
            raise twin.NotModelled(f"OTG_FS: FIFO window {n}")
        ep = self.ins[n]
        if len(ep.fifo) >= self.tx_depth(n):
            self.errors.append((self.board.t, f"TX FIFO {n} written while full"))
            return
        ep.fifo.append(v & 0xFFFF_FFFF)

    def _pop_word(self):
        if not self.rx_data:
            self.errors.append((self.board.t, "receive FIFO read past its packet"))
            return 0
        return self.rx_data.pop(0)

    def _pop_status(self):
        status, words = self.rx.pop(0)
        if self.rx_data:
            self.errors.append((self.board.t, "receive status popped before its data was read"))
        self.rx_data = list(words)
        n, kind = status & 0xF, status >> 17 & 0xF
        if kind == SETUP_DONE:
            self.outs[0].int |= STUP
        elif kind == OUT_DONE:
            self.outs[n].int |= XFRC

    def _rx_words(self):
        return sum(1 + len(w) for _, w in self.rx) + len(self.rx_data)

    def _rx_room(self, nbytes):
        return self._rx_words() + 2 + (nbytes + 3) // 4 <= (self.r.get(GRXFSIZ, 0) & 0xFFFF)

    def _rx_push(self, n, kind, data=b"", pid=0):
        words = [int.from_bytes(bytes(data[i:i + 4]).ljust(4, b"\0"), "little") for i in range(0, len(data), 4)]
        self.rx.append((n | len(data) << 4 | pid << 15 | kind << 17, words))

    # -- the bus's side (the host calls these)
    def _bus_lost(self):
        for ep in self.ins + self.outs:
            ep.ctl &= ~EPENA

    def bus_reset(self):
        """The host starts driving SE0 (a reset): USBRST. The core deactivates every
        endpoint but 0 (RM0090, DIEPCTLx.USBAEP) and answers on address 0."""
        if not self.connected():
            return
        self.gintsts |= USBRST
        for ep in self.ins[1:] + self.outs[1:]:
            ep.ctl &= ~(USBAEP | EPENA)
        self.outs[0].ctl |= NAKSTS
        self.address = 0
        self.suspended = False
        self.in_reset = True

    def reset_done(self):
        """The reset ends: the speed is enumerated (full speed), ENUMDNE."""
        if self.in_reset and self.connected():
            self.gintsts |= ENUMDNE
        self.in_reset = False

    def suspend(self):
        """No SOF for 3 ms: ESUSP, then USBSUSP."""
        if self.connected() and not self.suspended:
            self.suspended = True
            self.gintsts |= ESUSP | USBSUSP

    def resume(self):
        """Resume signalling from the host: WKUPINT."""
        if self.suspended:
            self.suspended = False
            self.gintsts |= WKUPINT

    def _addressed(self, addr):
        return self.connected() and not self.suspended and not self.in_reset and addr == self.address

    def setup(self, addr, data):
        """A SETUP transaction to endpoint 0: "ACK" or None (no answer)."""
        if not self._addressed(addr) or len(data) != 8:
            return None
        if not self._rx_room(8):
            return None  # no room: the core cannot take it, the host times out and retries
        e0o, e0i = self.outs[0], self.ins[0]
        e0o.ctl = (e0o.ctl & ~STALL) | NAKSTS
        e0i.ctl = (e0i.ctl & ~STALL) | NAKSTS
        stup = e0o.tsiz >> 29 & 3
        e0o.tsiz = (e0o.tsiz & ~(3 << 29)) | (max(stup - 1, 0) << 29)
        e0o.dpid = e0i.dpid = 1  # the data stage starts with DATA1
        self._rx_push(0, SETUP_DATA, data, 0)
        self._rx_push(0, SETUP_DONE)
        return "ACK"

    def _toggle(self, ep):
        if ep.n == 0:
            return getattr(ep, "dpid", 1)
        return ep.ctl >> 16 & 1

    def _flip(self, ep):
        if ep.n == 0:
            ep.dpid = self._toggle(ep) ^ 1
        else:
            ep.ctl ^= DPID

    def out(self, addr, n, data, pid):
        """An OUT transaction: "ACK", "NAK", "STALL" or None. A packet whose data PID
        is not the one expected is a retransmission: acknowledged and dropped."""
        if not self._addressed(addr) or n >= EPS:
            return None
        ep = self.outs[n]
        if not ep.ctl & USBAEP:
            return None
        if ep.ctl & STALL:
            return "STALL"
        if ep.ctl & NAKSTS or not self._rx_room(len(data)):
            return "NAK"
        mps = (64 >> (ep.ctl & 3)) if n == 0 else ep.ctl & 0x7FF
        if len(data) > mps:
            self.errors.append((self.board.t, f"OUT {n}: {len(data)} bytes over its {mps}"))
            return None
        if pid != self._toggle(ep):
            return "ACK"
        self._flip(ep)
        self._rx_push(n, OUT_DATA, data, pid)
        pkt = ep.tsiz >> 19 & 0x3FF
        size = ep.tsiz & 0x7FFFF
        pkt, size = max(pkt - 1, 0), max(size - len(data), 0)
        ep.tsiz = (ep.tsiz & ~0x1FF_FFFF) | (pkt << 19) | size
        if pkt == 0 or len(data) < mps:
            # The transfer is complete: the core NAKs until the application asks for more.
            self._rx_push(n, OUT_DONE)
            ep.ctl = (ep.ctl & ~EPENA) | NAKSTS
        return "ACK"

    def in_(self, addr, n):
        """An IN transaction: ("DATA", pid, bytes), "NAK", "STALL" or None. The host
        acknowledges every data packet (it drops one with the wrong PID itself)."""
        if not self._addressed(addr) or n >= EPS:
            return None
        ep = self.ins[n]
        if not ep.ctl & USBAEP:
            return None
        if ep.ctl & STALL:
            return "STALL"
        if not ep.ctl & EPENA or ep.ctl & NAKSTS:
            return "NAK"
        pkt, size = ep.tsiz >> 19 & 0x3FF, ep.tsiz & 0x7FFFF
        mps = (64 >> (ep.ctl & 3)) if n == 0 else ep.ctl & 0x7FF
        if pkt == 0:
            return "NAK"
        length = min(size, mps)
        words = (length + 3) // 4
        if len(ep.fifo) < words:
            return "NAK"  # the packet is not all in the FIFO yet
        raw = b"".join(w.to_bytes(4, "little") for w in ep.fifo[:words])[:length]
        del ep.fifo[:words]
        pid = self._toggle(ep)
        self._flip(ep)
        pkt, size = pkt - 1, size - length
        ep.tsiz = (ep.tsiz & ~0x1FF_FFFF) | (pkt << 19) | size
        if pkt == 0:
            ep.ctl &= ~EPENA
            ep.int |= XFRC
            if n == 0:
                # A new DCFG.DAD takes effect once the control transfer that set it
                # has ended: its status stage still answers on the old address.
                self.address = self.r.get(DCFG, 0) >> 4 & 0x7F
        return ("DATA", pid, raw)


UID_ADDR = 0x1FFF_7A10
"""The 96-bit unique device ID (RM0090 39.1), in system memory."""


def write_uid(board, uid):
    """Gives the board its unique ID (12 bytes, as read from `UID_ADDR` up)."""
    if len(uid) != 12:
        raise ValueError("a unique ID is 12 bytes")
    board.uc.mem_write(UID_ADDR, bytes(uid))
