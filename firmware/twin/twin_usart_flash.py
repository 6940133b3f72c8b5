"""The twin's USARTs and its flash interface (RM0090 sections 30 and 3.5-3.9,
DS8626's programming times). `twin.py` gathers the modules."""


from twin_core import FLASH_BASE, T_HZ, NotModelled, Rcc


class Usart:
    """USART1/2/3 (RM0090 section 30.6) as an asynchronous 8N1-style link to a host
    byte queue: SR (PE, FE, NF, ORE, IDLE, RXNE, TC, TXE), DR, BRR (OVER8 0 and 1),
    CR1 (UE, M, TE, RE, RXNEIE, TCIE, TXEIE, IDLEIE, PEIE), CR2 (STOP), CR3. The
    transmitter has a data register and a shift register; each frame takes its
    bit time at the programmed baud rate from the bus clock. The receiver takes
    the host's bytes back to back at the same rate; a byte that completes while
    RXNE is still set is lost and sets ORE. RXNE is cleared by reading DR, TC and
    RXNE by writing 0 to them; ORE, IDLE, NF, FE, PE by a read of SR then of DR.
    DMA (CR3 DMAR/DMAT), parity, LIN, smartcard and synchronous modes are not
    modelled."""

    SR, DR, BRR, CR1, CR2, CR3, GTPR = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18
    PE, FE, NF, ORE, IDLE, RXNE, TC, TXE = 1, 2, 4, 8, 16, 32, 64, 128
    UE, M, PCE, TE, RE = 1 << 13, 1 << 12, 1 << 10, 1 << 3, 1 << 2
    IE_PE, IE_TXE, IE_TC, IE_RXNE, IE_IDLE = 1 << 8, 1 << 7, 1 << 6, 1 << 5, 1 << 4

    HOST_BAUD = 460_800
    """The host's line rate (8N1) unless a test sets `host_baud`."""

    def __init__(self, board, name, irq, enr, en_bit, apb):
        self.board, self.name, self.irq = board, name, irq
        self.enr, self.en_bit, self.apb = enr, en_bit, apb
        self.host_baud = self.HOST_BAUD
        self.garbled = 0  # host bytes received at a baud rate 3 % or more off
        self.sent = []  # (t, byte) the host received from the device, in order
        self.lost = 0  # host bytes that arrived while the receiver was off
        self.overruns = 0  # host bytes lost to ORE
        self.rx = []  # (time its stop bit ends, byte) on the wire toward the device
        self.line_free = 0  # when the host's line is idle again
        self.reset()

    def reset(self):
        self.sr = self.TXE | self.TC
        self.dr_in = 0
        self.brr = self.cr1 = self.cr2 = self.cr3 = self.gtpr = 0
        self.tdr = None  # byte waiting in the data register
        self.shift = None  # (done time, byte) in the shift register
        self.idle_at = None  # when IDLE will be set (a frame of idle after a byte)
        self.seen = 0  # SR flags read, cleared by the next DR read

    # -- timing
    def pclk(self):
        rcc = self.board.rcc
        pre = rcc.r.get(Rcc.CFGR, 0) >> (10 if self.apb == 1 else 13) & 7
        return rcc.hclk() // (1 if pre < 4 else 2 << (pre - 4))

    def frame_units(self):
        """Time units of one frame (start bit, 8 or 9 data bits, stop bits)."""
        if not self.brr:
            raise NotModelled(f"{self.name}: enabled with BRR = 0")
        clk = self.pclk()
        if self.cr1 & 0x8000:  # OVER8: USARTDIV = BRR[15:4] + BRR[2:0] / 8
            div = 8 * (self.brr >> 4) + (self.brr & 7)
        else:  # USARTDIV * 16 = BRR
            div = self.brr
        stop = {0: 2, 1: 1, 2: 4, 3: 3}[self.cr2 >> 12 & 3]  # in half bits
        half_bits = 2 * (1 + (9 if self.cr1 & self.M else 8)) + stop
        return half_bits * div * T_HZ // (2 * clk)

    def baud(self):
        return T_HZ * 10 / self.frame_units() if self.brr else 0

    # -- the host's side
    def send(self, data, at_s=None):
        """The host sends `data` (8N1 at `host_baud`) from `at_s` seconds (default
        now), back to back after anything still on the line. Returns the time
        (units) the last byte's stop bit ends."""
        t = self.board.t if at_s is None else round(at_s * T_HZ)
        frame = round(10 * T_HZ / self.host_baud)
        for byte in bytes(data):
            start = max(t, self.line_free)
            self.line_free = start + frame
            self.rx.append((self.line_free, byte))
        return self.line_free

    def take(self):
        """The bytes the device sent since the last call."""
        out = bytes(b for _, b in self.sent)
        self.sent = []
        return out

    # -- events
    def enabled(self):
        return self.cr1 & self.UE and self.clocked()

    def next_event(self):
        cands = []
        if self.shift is not None:
            cands.append(self.shift[0])
        if self.rx:
            cands.append(self.rx[0][0])
        if self.idle_at is not None:
            cands.append(self.idle_at)
        return min(cands) if cands else None

    def advance(self, t):
        while True:
            nxt = self.next_event()
            if nxt is None or nxt > t:
                return
            if self.shift is not None and self.shift[0] == nxt:
                self.sent.append(self.shift)
                self.shift = None
                if self.tdr is not None:
                    self._load_shift(nxt)
                else:
                    self.sr |= self.TC
            elif self.rx and self.rx[0][0] == nxt:
                _, byte = self.rx.pop(0)
                if not (self.enabled() and self.cr1 & self.RE):
                    self.lost += 1
                    continue
                if abs(self.baud() / self.host_baud - 1) >= 0.03:
                    self.sr |= self.FE  # the receiver samples the wrong bits
                    self.garbled += 1
                    byte = 0xFF
                if self.sr & self.RXNE:
                    self.sr |= self.ORE
                    self.overruns += 1
                else:
                    self.dr_in = byte
                    self.sr |= self.RXNE
                self.idle_at = nxt + round(10 * T_HZ / self.host_baud)
            else:
                self.idle_at = None
                if not self.rx or self.rx[0][0] - round(10 * T_HZ / self.host_baud) >= nxt:
                    self.sr |= self.IDLE

    def _load_shift(self, t):
        self.shift = (t + self.frame_units(), self.tdr)
        self.tdr = None
        self.sr |= self.TXE

    def irq_line(self):
        c, s = self.cr1, self.sr
        return bool((c & self.IE_RXNE and s & (self.RXNE | self.ORE)) or (c & self.IE_TXE and s & self.TXE)
                    or (c & self.IE_TC and s & self.TC) or (c & self.IE_IDLE and s & self.IDLE)
                    or (c & self.IE_PE and s & self.PE))

    def can_wake(self):
        return bool(self.cr1 & (self.IE_RXNE | self.IE_TXE | self.IE_TC | self.IE_IDLE))

    # -- bus
    def clocked(self):
        return self.board.rcc.enabled(self.enr, self.en_bit)

    def read(self, off):
        if not self.clocked():
            return 0
        if off == self.SR:
            self.seen = self.sr & (self.PE | self.FE | self.NF | self.ORE | self.IDLE)
            return self.sr
        if off == self.DR:
            self.sr &= ~(self.RXNE | self.seen)
            self.seen = 0
            return self.dr_in
        return {self.BRR: self.brr, self.CR1: self.cr1, self.CR2: self.cr2, self.CR3: self.cr3,
                self.GTPR: self.gtpr}.get(off, 0)

    def write(self, off, v):
        if not self.clocked():
            self.board.note(f"{self.name} written with its clock off (ignored)")
            return
        b = self.board
        if off == self.SR:
            self.sr &= v | ~(self.RXNE | self.TC)  # rc_w0 on RXNE and TC only
        elif off == self.DR:
            self.sr &= ~self.TC
            if not (self.enabled() and self.cr1 & self.TE):
                b.note(f"{self.name}: DR written with the transmitter off (byte lost)")
            elif self.tdr is not None:
                b.note(f"{self.name}: DR written with TXE clear (previous byte overwritten)")
                self.tdr = v & 0xFF
            else:
                self.tdr = v & 0xFF
                self.sr &= ~self.TXE
                if self.shift is None:
                    self._load_shift(b.t)
        elif off == self.BRR:
            self.brr = v & 0xFFFF
        elif off == self.CR1:
            if v & self.PCE:
                raise NotModelled(f"{self.name}: parity")
            self.cr1 = v & 0xFFFF
        elif off == self.CR2:
            if v & (1 << 11 | 1 << 14):
                raise NotModelled(f"{self.name}: synchronous or LIN mode")
            self.cr2 = v & 0x7F7F
        elif off == self.CR3:
            if v & (3 << 6):
                raise NotModelled(f"{self.name}: DMA (CR3 DMAR/DMAT)")
            if v & (1 << 5 | 1 << 3 | 1 << 1):
                raise NotModelled(f"{self.name}: smartcard, half-duplex or IrDA mode")
            self.cr3 = v & 0xFFF
        elif off == self.GTPR:
            self.gtpr = v & 0xFFFF
        b.trace(self.name, off, v)


# Sector layout of the 1 MB bank (RM0090 table 5): (first address, size).
SECTORS = ([(FLASH_BASE + i * 0x4000, 0x4000) for i in range(4)] + [(FLASH_BASE + 0x1_0000, 0x1_0000)]
           + [(FLASH_BASE + 0x2_0000 * i, 0x2_0000) for i in range(1, 8)])
# Sector erase and word programming times, s, (typical, maximum), per parallelism
# (PSIZE x8, x16, x32) and sector size: STM32F405 datasheet (DS8626), table
# "Flash memory programming".
ERASE_S = {0x4000: ((0.4, 0.8), (0.3, 0.6), (0.25, 0.5)),
           0x1_0000: ((1.2, 2.4), (0.7, 1.4), (0.55, 1.1)),
           0x2_0000: ((2.0, 4.0), (1.3, 2.6), (1.0, 2.0))}
PROGRAM_S = (16e-6, 100e-6)


class Flash:
    """The flash interface (RM0090 section 3): ACR reads back; KEYR unlock sequence
    (a wrong key locks the control register until reset); CR with PG, SER, SNB,
    PSIZE, STRT, EOPIE, ERRIE, LOCK; SR with EOP, OPERR, WRPERR, PGAERR, PGPERR,
    PGSERR (rc_w1) and BSY. A sector erase sets the sector to 0xFF and is busy for
    its datasheet time (`timing` "typ" or "max"); a program is one write of PSIZE's
    width at an aligned address, busy for 16 or 100 us, and only clears bits (a
    write over data that is not erased is counted in `dirty_writes`). While BSY,
    an instruction fetch or a vector read from flash stalls the CPU until the
    operation ends (checked at the end of each quantum, so code in flash may run
    up to a quantum past the start of an erase); the timers and the IWDG keep counting. Code
    in RAM runs on; its data reads of flash are not stalled. A RAM loop that only
    polls FLASH_SR (and reloads the watchdog) is skipped to the operation's end. A reset during an erase leaves the part of
    the sector already erased at 0xFF and the rest as it was."""

    ACR, KEYR, OPTKEYR, SR, CR, OPTCR = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14
    KEY1, KEY2 = 0x4567_0123, 0xCDEF_89AB
    EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR, BSY = 1, 2, 16, 32, 64, 128, 1 << 16
    PG, SER, MER, STRT, EOPIE, ERRIE, LOCK = 1, 2, 4, 1 << 16, 1 << 24, 1 << 25, 1 << 31

    def __init__(self, board, timing="typ"):
        self.board = board
        self.timing = 0 if timing == "typ" else 1
        self.acr = 0
        self.sr = 0
        self.cr = self.LOCK
        self.optcr = 0x0FFF_AAED
        self.keys = 0  # how many keys of the sequence were written
        self.frozen = False  # a wrong key: locked until reset
        self.busy_until = None
        self.op = None  # ("erase", sector, start) or ("program",)

    def busy(self, t=None):
        t = self.board.t if t is None else t
        return self.busy_until is not None and t < self.busy_until

    def read(self, off):
        if off == self.ACR:
            return self.acr
        if off == self.SR:
            return self.sr | (self.BSY if self.busy() else 0)
        if off == self.CR:
            return self.cr
        if off == self.OPTCR:
            return self.optcr
        return 0

    def write(self, off, v):
        b = self.board
        b.trace("FLASH", off, v)
        if off == self.ACR:
            self.acr = v & 0x1F07
        elif off == self.KEYR:
            if self.frozen or not self.cr & self.LOCK:
                return
            want = (self.KEY1, self.KEY2)[self.keys]
            if v != want:
                self.frozen = True
                b.note("FLASH: wrong key sequence (control register locked until reset)")
                return
            self.keys += 1
            if self.keys == 2:
                self.cr &= ~self.LOCK
                self.keys = 0
        elif off == self.SR:
            self.sr &= ~(v & (self.EOP | self.OPERR | self.WRPERR | self.PGAERR | self.PGPERR | self.PGSERR))
        elif off == self.CR:
            if self.cr & self.LOCK:
                return
            if self.busy():
                b.note("FLASH: CR written while busy")
            self.cr = v & 0x8301_03FF | (v & self.LOCK)
            if v & self.MER:
                raise NotModelled("FLASH: mass erase")
            if v & self.STRT:
                self.cr &= ~self.STRT
                if v & self.SER and not v & self.PG:
                    self.erase(v >> 3 & 0xF)
                else:
                    self.sr |= self.PGSERR
        elif off == self.OPTCR:
            b.note("FLASH: option bytes written (ignored)")

    def psize(self):
        return self.cr >> 8 & 3

    def erase(self, snb):
        b = self.board
        if snb >= len(SECTORS):
            raise NotModelled(f"FLASH: sector {snb} (the F405 has 12)")
        if self.psize() == 3:
            raise NotModelled("FLASH: x64 parallelism needs an external VPP")
        start = max(b.t, self.busy_until or 0)
        size = SECTORS[snb][1]
        self.busy_until = start + round(ERASE_S[size][self.psize()][self.timing] * T_HZ)
        addr, size = SECTORS[snb]
        self.op = ("erase", snb, start, bytes(b.uc.mem_read(addr, size)))
        b.uc.mem_write(addr, b"\xff" * size)
        b.erases.append((start, self.busy_until, snb))
        b.flash_busy_changed()
        if b.on_flash:
            b.on_flash("erase", snb)

    def finish(self, t):
        """Completes the operation that ends at or before `t`."""
        if self.busy_until is None or t < self.busy_until:
            return
        if self.cr & self.EOPIE:
            self.sr |= self.EOP
        self.busy_until, self.op = None, None
        self.board.flash_busy_changed()

    def abort(self, t):
        """A reset in the middle of an operation: an erase is left partly done."""
        if self.busy_until is None or t >= self.busy_until:
            self.finish(t)
            return
        if self.op and self.op[0] == "erase":
            _, snb, start, old = self.op
            addr, size = SECTORS[snb]
            done = min(size, max(0, size * (t - start) // max(1, self.busy_until - start))) & ~3
            self.board.uc.mem_write(addr + done, old[done:])
        self.busy_until, self.op = None, None

    def program(self, addr, size, value, old):
        """A CPU write of `size` bytes at `addr` in flash, over `old`: sets the flags
        and returns what the cells hold after it (the board writes that over the
        store once the quantum ends)."""
        b = self.board
        width = 1 << self.psize()
        ok = True
        if self.cr & self.LOCK or not self.cr & self.PG or self.cr & self.SER:
            self.sr |= self.PGSERR
            ok = False
        elif size != width:
            self.sr |= self.PGPERR
            ok = False
        elif addr % width:
            self.sr |= self.PGAERR
            ok = False
        if ok and self.psize() == 3:
            raise NotModelled("FLASH: x64 parallelism needs an external VPP")
        mask = (1 << (8 * size)) - 1
        new = old & value & mask if ok else old
        if ok and value & mask & ~old:
            b.dirty_writes.append((b.t, addr, old, value & mask))
        if ok:
            start = max(b.t, self.busy_until or 0)
            self.busy_until = start + round(PROGRAM_S[self.timing] * T_HZ)
            self.op = ("program",)
            b.programs += 1
            b.flash_busy_changed()
            if b.on_flash:
                b.on_flash("program", addr)
        elif self.cr & self.ERRIE:
            self.sr |= self.OPERR
        return new
