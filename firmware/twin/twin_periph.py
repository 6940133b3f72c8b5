"""The twin's watchdog, GPIO, EXTI and NVIC (RM0090 sections 8, 12, 21; ARMv7-M
B3.4). `twin.py` gathers the modules."""


from twin_core import HARDFAULT, LSI_HZ, T_HZ, NotModelled, Rcc


class Iwdg:
    """IWDG (RM0090 section 21): key register (0x5555 unlock, 0xAAAA reload, 0xCCCC
    start), prescaler and reload; the LSI at 32 kHz; the counter reaching zero resets
    the chip. PR/RLR updates are immediate (SR always reads 0)."""

    def __init__(self, board):
        self.board = board
        self.running = False
        self.unlocked = False
        self.pr, self.rlr = 0, 0xFFF
        self.fed_at = 0
        self.started_at = None
        self.feeds = []

    def timeout_units(self):
        return (self.rlr + 1) * (4 << self.pr) * (T_HZ // LSI_HZ)

    def expires(self):
        return self.fed_at + self.timeout_units() if self.running else None

    def read(self, off):
        return {0x04: self.pr, 0x08: self.rlr}.get(off, 0)

    def write(self, off, v):
        b = self.board
        if off == 0x00:
            v &= 0xFFFF
            self.unlocked = v == 0x5555
            if v == 0xAAAA:
                self.fed_at = b.t
                if self.running:
                    self.feeds.append(b.t)
                    b.all_feeds.append(b.t)
            elif v == 0xCCCC and not self.running:
                self.running, self.fed_at, self.started_at = True, b.t, b.t
                self.feeds.append(b.t)
                b.all_feeds.append(b.t)
        elif off == 0x04 and self.unlocked:
            self.pr = v & 7
        elif off == 0x08 and self.unlocked:
            self.rlr = v & 0xFFF
        b.trace("IWDG", off, v)


class Gpio:
    """GPIO port (RM0090 section 8.4): mode, pulls, output data and BSRR, alternate
    functions. A pin's input level is what the harness drives on it (a button), else
    its pull, else the output data for an output."""

    MODER, PUPDR, IDR, ODR, BSRR, AFRL, AFRH = 0x00, 0x0C, 0x10, 0x14, 0x18, 0x20, 0x24

    # Reset values that are not zero (RM0090 8.4): the debug pins PA13-15, PB3-4.
    RESET = {0: {0x00: 0xA800_0000, 0x0C: 0x6400_0000},
             1: {0x00: 0x0000_0280, 0x08: 0x0000_00C0, 0x0C: 0x0000_0100}}

    def __init__(self, board, name, index):
        self.board, self.name, self.index = board, name, index
        self.r = dict(self.RESET.get(index, {}))
        self.external = {}

    def level(self, pin):
        mode = self.r.get(self.MODER, 0) >> (2 * pin) & 3
        if mode == 1:
            return self.r.get(self.ODR, 0) >> pin & 1
        if pin in self.external:
            return self.external[pin]
        return 1 if self.r.get(self.PUPDR, 0) >> (2 * pin) & 3 == 1 else 0

    def levels(self):
        return [self.level(p) for p in range(16)]

    def mode(self, pin):
        return self.r.get(self.MODER, 0) >> (2 * pin) & 3

    def af(self, pin):
        return self.r.get(self.AFRL if pin < 8 else self.AFRH, 0) >> (4 * (pin % 8)) & 0xF

    def clocked(self):
        return self.board.rcc.enabled(Rcc.AHB1ENR, self.index)

    def read(self, off):
        if not self.clocked():
            return 0
        if off == self.IDR:
            return sum(lv << p for p, lv in enumerate(self.levels()))
        return self.r.get(off, 0)

    def write(self, off, v):
        if not self.clocked():
            self.board.note(f"{self.name} written with its clock off (ignored)")
            return
        before = self.levels()
        modes = [self.mode(p) for p in range(16)]
        if off == self.BSRR:
            odr = self.r.get(self.ODR, 0)
            odr = (odr | (v & 0xFFFF)) & ~(v >> 16)
            self.r[self.ODR] = odr
        else:
            self.r[off] = v
        self.board.trace(self.name, off, v)
        self.board.pins_changed(self, before)
        for p in range(16):
            if self.mode(p) != modes[p]:
                self.board.mode_changed(self, p)

    def drive(self, pin, level):
        before = self.levels()
        self.external[pin] = level
        self.board.pins_changed(self, before)


class Exti:
    """EXTI (RM0090 section 12.3) with SYSCFG_EXTICR routing (section 9.2): an edge
    on the routed pin sets PR if its trigger (RTSR/FTSR) is on; PR & IMR is the
    interrupt request. Lines 0-15 only (no events, no wakeup lines)."""

    IMR, EMR, RTSR, FTSR, SWIER, PR = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14

    def __init__(self, board):
        self.board = board
        self.r = {}

    def edge(self, line, rising):
        if self.r.get(self.RTSR if rising else self.FTSR, 0) >> line & 1:
            self.r[self.PR] = self.r.get(self.PR, 0) | (1 << line)

    def read(self, off):
        return self.r.get(off, 0)

    def write(self, off, v):
        if off == self.PR:
            self.r[self.PR] = self.r.get(self.PR, 0) & ~v
        elif off == self.SWIER:
            self.r[self.PR] = self.r.get(self.PR, 0) | (v & self.r.get(self.IMR, 0))
        else:
            self.r[off] = v
        self.board.trace("EXTI", off, v)

    def lines(self):
        return self.r.get(self.PR, 0) & self.r.get(self.IMR, 0)


class Nvic:
    """NVIC and SCB (ARMv7-M B3.4, B3.2): enable, pending, active, priorities (4
    bits, as on the STM32F4), PRIGROUP, VTOR, SHPR, ICSR (VECTACTIVE, PendSV),
    AIRCR.SYSRESETREQ, STIR. The rest of the system control space reads back."""

    def __init__(self, board):
        self.board = board
        self.enabled = 0
        self.pending = 0  # bit n = exception n (IRQ k is 16 + k)
        self.ipr = bytearray(256)  # priority per exception number
        self.r = {}
        self.vtor = 0
        self.prigroup = 0

    def prio(self, n):
        if n == HARDFAULT:
            return -1
        if n == 2:
            return -2
        p = self.ipr[n] & 0xF0
        return p & ~((2 << self.prigroup) - 1) & 0xFF

    def read(self, off, size):
        if 0x100 <= off < 0x120:
            return self.enabled >> (32 * ((off - 0x100) // 4)) & 0xFFFF_FFFF
        if 0x180 <= off < 0x1A0:
            return self.enabled >> (32 * ((off - 0x180) // 4)) & 0xFFFF_FFFF
        if 0x200 <= off < 0x220 or 0x280 <= off < 0x2A0:
            base = 0x200 if off < 0x280 else 0x280
            return (self.pending >> 16) >> (32 * ((off - base) // 4)) & 0xFFFF_FFFF
        if 0x300 <= off < 0x320:
            act = sum(1 << (n - 16) for n in self.board.active if n >= 16)
            return act >> (32 * ((off - 0x300) // 4)) & 0xFFFF_FFFF
        if 0x400 <= off < 0x4F0:
            return int.from_bytes(self.ipr[16 + off - 0x400:16 + off - 0x400 + size], "little")
        if 0xD18 <= off < 0xD24:
            return int.from_bytes(self.ipr[4 + off - 0xD18:4 + off - 0xD18 + size], "little")
        if off == 0xD04:
            act = self.board.active[-1] if self.board.active else 0
            pend = [n for n in range(256) if self.pending >> n & 1]
            return act | ((pend[0] if pend else 0) << 12) | ((self.pending >> 14 & 1) << 28)
        if off == 0xD08:
            return self.vtor
        if off == 0xD0C:
            return 0xFA05_0000 | (self.prigroup << 8)
        return self.r.get(off, 0)

    def write(self, off, v, size):
        b = self.board
        if 0x100 <= off < 0x120:
            self.enabled |= v << (32 * ((off - 0x100) // 4))
        elif 0x180 <= off < 0x1A0:
            self.enabled &= ~(v << (32 * ((off - 0x180) // 4)))
        elif 0x200 <= off < 0x220:
            self.pending |= (v << (32 * ((off - 0x200) // 4))) << 16
        elif 0x280 <= off < 0x2A0:
            self.pending &= ~((v << (32 * ((off - 0x280) // 4))) << 16)
        elif 0x400 <= off < 0x4F0:
            n = 16 + off - 0x400
            old = bytes(self.ipr[n:n + size])
            self.ipr[n:n + size] = v.to_bytes(size, "little")
            if old != bytes(self.ipr[n:n + size]):
                b.priority_changed(range(n, n + size))
        elif 0xD18 <= off < 0xD24:
            n = 4 + off - 0xD18
            self.ipr[n:n + size] = v.to_bytes(size, "little")
        elif off == 0xD04:
            if v >> 28 & 1:
                self.pending |= 1 << 14
            if v >> 27 & 1:
                self.pending &= ~(1 << 14)
            if v >> 26 & 1:
                self.pending |= 1 << 15
        elif off == 0xD08:
            self.vtor = v & ~0x7F
        elif off == 0xD0C:
            if v >> 16 == 0x05FA:
                self.prigroup = v >> 8 & 7
                if v & 4:
                    b.request_reset("SYSRESETREQ")
        elif off == 0xF00:
            self.pending |= 1 << (16 + (v & 0x1FF))
        else:
            if off == 0xD88 or 0x010 <= off < 0x020:
                pass
            self.r[off] = v
        if off == 0x010 and v & 3 == 3:
            raise NotModelled("SysTick interrupts are not modelled")

    def irq_enabled(self, n):
        return n < 16 or self.enabled >> (n - 16) & 1
