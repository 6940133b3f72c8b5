"""The firmware twin: the release ELF of the sleeve firmware on an emulated STM32F405.

The CPU is unicorn's Cortex-M4 (QEMU's instruction set model). Everything around it
is modelled here, register by register, from the STM32F405 reference manual (RM0090)
and the ARMv7-M architecture reference manual (exception entry and return, NVIC):
RCC/PWR/FLASH ready bits, TIM2-TIM7, IWDG, GPIO, EXTI + SYSCFG, the NVIC and the
SCB. What is and is not modelled is in README.md.

Time is counted in units of 1/336 MHz (so that the 16 MHz HSI, the 168 MHz core,
the 84 MHz timer clock and the 32 kHz LSI are all whole numbers of units). The CPU
runs in quanta of `QUANTUM` instructions, one core cycle each; peripherals are
advanced between quanta, interrupts are taken between quanta. `wfe`/`wfi` end a
quantum and the clock jumps to the next event that can wake the core.
"""

import struct

from unicorn import (
    UC_ARCH_ARM,
    UC_HOOK_CODE,
    UC_HOOK_INTR,
    UC_HOOK_MEM_WRITE,
    UC_MODE_MCLASS,
    UC_MODE_THUMB,
    Uc,
    UcError,
)
from unicorn import arm_const as A

T_HZ = 336_000_000
"""Time units per second."""
HSI_HZ = 16_000_000
LSI_HZ = 32_000
QUANTUM = 2000
"""Instructions per run of the CPU between two peripheral updates (12 us at 168 MHz)."""

FLASH_BASE, FLASH_SIZE = 0x0800_0000, 1024 * 1024
BANK_BASE, BANK_SIZE = 0x080C_0000, 256 * 1024
SRAM_BASE, SRAM_SIZE = 0x2000_0000, 128 * 1024
CCM_BASE, CCM_SIZE = 0x1000_0000, 64 * 1024

# IRQ numbers (RM0090 table 61, "Vector table for STM32F405xx/07xx").
IRQ = {"EXTI0": 6, "EXTI1": 7, "EXTI2": 8, "EXTI3": 9, "EXTI4": 10, "EXTI9_5": 23,
       "TIM2": 28, "TIM3": 29, "TIM4": 30, "EXTI15_10": 40, "TIM5": 50, "TIM6_DAC": 54,
       "TIM7": 55, "FLASH": 4, "USART1": 37, "USART2": 38, "USART3": 39}
HARDFAULT = 3


class NotModelled(Exception):
    """The firmware did something this twin does not model: the test fails loudly."""


class Fault(Exception):
    """A bus fault the harness injected (see `Board.fault_on`)."""


# ---------------------------------------------------------------------------- ELF


def load_elf(path):
    """(segments [(paddr, bytes)], symbols {name: addr}) of a 32-bit little-endian ELF."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise ValueError(f"{path}: not a 32-bit little-endian ELF")
    (phoff, shoff, _flags, _ehsize, phentsize, phnum, shentsize, shnum, _shstrndx) = struct.unpack_from(
        "<IIIHHHHHH", data, 0x1C)
    segments = []
    for i in range(phnum):
        p_type, off, _vaddr, paddr, filesz, _memsz, _flags, _align = struct.unpack_from(
            "<IIIIIIII", data, phoff + i * phentsize)
        if p_type == 1 and filesz:
            segments.append((paddr, data[off:off + filesz]))
    sections = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    symbols = {}
    for sh in sections:
        if sh[1] != 2:  # SHT_SYMTAB
            continue
        strtab = sections[sh[6]]
        for j in range(sh[5] // 16):
            name, value, _size, _info, _other, _shndx = struct.unpack_from("<IIIBBH", data, sh[4] + j * 16)
            s = data[strtab[4] + name:data.index(b"\0", strtab[4] + name)].decode()
            if s:
                symbols[s] = value
    return segments, symbols


# ------------------------------------------------------------------- peripherals


class Regs:
    """A plain register file: what is written reads back (unmodelled registers)."""

    def __init__(self):
        self.r = {}

    def read(self, off):
        return self.r.get(off, 0)

    def write(self, off, v):
        self.r[off] = v


class Rcc(Regs):
    """RCC (RM0090 section 7.3): every oscillator and the PLL are ready as soon as
    they are switched on; SWS follows SW; the clock tree gives SYSCLK and the timer
    clocks; the enable and reset bits gate and reset the peripherals."""

    CR, PLLCFGR, CFGR, AHB1RSTR, APB1RSTR, APB2RSTR = 0x00, 0x04, 0x08, 0x10, 0x20, 0x24
    AHB1ENR, APB1ENR, APB2ENR, BDCR, CSR = 0x30, 0x40, 0x44, 0x70, 0x74

    def __init__(self, board, csr=0x0E00_0000):
        super().__init__()
        self.board = board
        self.r = {self.CR: 0x83, self.PLLCFGR: 0x2400_3010, self.CSR: csr}
        self.cache = {}

    def read(self, off):
        v = self.r.get(off, 0)
        if off == self.CR:  # HSIRDY, HSERDY, PLLRDY, PLLI2SRDY follow their ON bits
            for on in (0, 16, 24, 26):
                v = (v & ~(2 << on)) | ((v >> on & 1) << (on + 1))
        elif off == self.CFGR:
            v = (v & ~0xC) | ((v & 3) << 2)
        elif off in (self.BDCR, self.CSR):  # LSERDY, LSIRDY
            v = (v & ~2) | ((v & 1) << 1)
        return v

    def write(self, off, v):
        self.cache = {}
        for t in getattr(self.board, "timers", {}).values():
            t._next = False
        if off == self.CSR and v & (1 << 24):  # RMVF clears the reset flags
            v &= 0x00FF_FFFF
        self.r[off] = v
        if off == self.APB1RSTR:
            for t in self.board.timers.values():
                if v >> t.en_bit & 1:
                    t.reset()
        if off in (self.APB1RSTR, self.APB2RSTR):
            for u in self.board.usarts.values():
                if (off == self.APB1RSTR) == (u.apb == 1) and v >> u.en_bit & 1:
                    u.reset()

    def sysclk(self):
        sw = self.r.get(self.CFGR, 0) & 3
        if sw == 0:
            return HSI_HZ
        if sw != 2:
            raise NotModelled(f"SYSCLK source SW={sw} (only HSI and PLL are modelled)")
        cfg = self.r[self.PLLCFGR]
        if cfg >> 22 & 1:
            raise NotModelled("PLL from HSE (no crystal is modelled)")
        m, n, p = cfg & 0x3F, cfg >> 6 & 0x1FF, (2 + 2 * (cfg >> 16 & 3))
        return HSI_HZ // m * n // p

    def hclk(self):
        hpre = self.r.get(self.CFGR, 0) >> 4 & 0xF
        div = 1 if hpre < 8 else [2, 4, 8, 16, 64, 128, 256, 512][hpre - 8]
        return self.sysclk() // div

    def apb1_timer_clk(self):
        """TIM2-7 kernel clock: PCLK1, doubled when APB1 is divided (RM0090 7.2)."""
        if "tim" not in self.cache:
            self.cache["tim"] = self._apb1_timer_clk()
        return self.cache["tim"]

    def _apb1_timer_clk(self):
        ppre1 = self.r.get(self.CFGR, 0) >> 10 & 7
        div = 1 if ppre1 < 4 else 2 << (ppre1 - 4)
        return self.hclk() // div * (1 if div == 1 else 2)

    def enabled(self, reg, bit):
        return self.r.get(reg, 0) >> bit & 1


class Pwr(Regs):
    """PWR (RM0090 5.4): CR reads back; CSR.VOSRDY (bit 14) always set."""

    def read(self, off):
        return self.r.get(off, 0) | ((1 << 14) if off == 0x04 else 0)


class Timer:
    """TIM2-TIM5 (RM0090 section 18) and TIM6/TIM7 (section 20), up-counting only:
    prescaler and auto-reload with preload, update events, compare matches with
    CCxIF, compare preload (OCxPE), UG, interrupts (DIER), master mode "enable" as
    TRGO and slave trigger mode (a slave starts when its master is enabled)."""

    CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR = (
        0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18, 0x1C, 0x20, 0x24, 0x28, 0x2C)
    CCR = (0x34, 0x38, 0x3C, 0x40)
    # Internal trigger inputs ITR0-3 of each slave (RM0090 table 94).
    ITR = {"TIM2": ("TIM1", "TIM8", "TIM3", "TIM4"), "TIM3": ("TIM1", "TIM2", "TIM5", "TIM4"),
           "TIM4": ("TIM1", "TIM2", "TIM3", "TIM8"), "TIM5": ("TIM2", "TIM3", "TIM4", "TIM8")}

    def __init__(self, board, name, en_bit, irq, bits, basic):
        self.board, self.name, self.en_bit, self.irq = board, name, en_bit, irq
        self.max = (1 << bits) - 1
        self.basic = basic
        self.reset()

    def reset(self):
        self.cr1 = self.cr2 = self.smcr = self.dier = self.sr = 0
        self.ccmr = [0, 0]
        self.ccer = 0
        self.psc = self.psc_a = 0
        self.arr = self.arr_a = self.max
        self.ccr = [0] * 4
        self.ccr_a = [0] * 4
        self.cnt, self.t_ref = 0, self.board.t
        self.started_at = None
        self._cc_key = None
        self._next = False  # cached next_event(); False = stale

    # -- state
    def running(self):
        return self.cr1 & 1

    def unit(self):
        """Time units per count."""
        clk = self.board.rcc.apb1_timer_clk()
        if T_HZ % clk:
            raise NotModelled(f"{self.name} clock {clk} Hz is not a divisor of {T_HZ}")
        return T_HZ // clk * (self.psc_a + 1)

    def ocpe(self, k):
        return self.ccmr[k // 2] >> (3 + 8 * (k % 2)) & 1

    def compare_channels(self):
        """Channels whose compare match sets CCxIF: configured as outputs (CCxS = 00)."""
        if self.basic:
            return ()
        key = (self.ccmr[0], self.ccmr[1])
        if self._cc_key != key:
            self._cc_key = key
            self._cc = tuple(k for k in range(4) if self.ccmr[k // 2] >> (8 * (k % 2)) & 3 == 0)
        return self._cc

    def cnt_now(self):
        if not self.running():
            return self.cnt
        return self.cnt + (self.board.t - self.t_ref) // self.unit()

    def next_event(self):
        """(time, kind) of the next update or compare match, or None if stopped."""
        if self._next is False:
            self._next = self._next_event()
        return self._next

    def _next_event(self):
        if not self.running():
            return None
        u = self.unit()
        top = self.arr_a if self.cnt <= self.arr_a else self.max
        best = (self.t_ref + (top - self.cnt + 1) * u, "update")
        for k in self.compare_channels():
            c = self.ccr_a[k]
            if self.cnt < c <= top and self.t_ref + (c - self.cnt) * u < best[0]:
                best = (self.t_ref + (c - self.cnt) * u, k)
        return best

    def preload_pending(self):
        return (self.psc != self.psc_a or self.arr != self.arr_a
                or any(self.ccr[k] != self.ccr_a[k] for k in range(4)))

    def load_preloads(self):
        self.psc_a, self.arr_a = self.psc, self.arr
        for k in range(4):
            self.ccr_a[k] = self.ccr[k]

    def advance(self, t):
        """Applies every event up to time `t`."""
        while True:
            ev = self.next_event()
            if ev is None or ev[0] > t:
                return
            self._next = False
            when, kind = ev
            if kind == "update":
                self.sr |= 1
                self.load_preloads()
                self.cnt, self.t_ref = 0, when
                for k in self.compare_channels():
                    if self.ccr_a[k] == 0:
                        self.sr |= 2 << k
                if self.cr1 & 8:  # one-pulse mode: the counter stops at the update
                    self.cr1 &= ~1
                    return
                if not self.preload_pending():
                    # Nothing changes from period to period: skip whole periods.
                    period = (self.arr_a + 1) * self.unit()
                    n = (t - when) // period
                    if n:
                        self.t_ref += n * period
                        for k in self.compare_channels():
                            if self.ccr_a[k] <= self.arr_a:
                                self.sr |= 2 << k
            else:
                self.sr |= 2 << kind
                self.cnt, self.t_ref = self.ccr_a[kind], when

    def irq_line(self):
        return bool(self.sr & self.dier & 0x5F)

    # -- bus
    def clocked(self):
        return self.board.rcc.enabled(Rcc.APB1ENR, self.en_bit)

    def read(self, off):
        if not self.clocked():
            return 0
        regs = {self.CR1: self.cr1, self.CR2: self.cr2, self.SMCR: self.smcr,
                self.DIER: self.dier, self.SR: self.sr, self.CCMR1: self.ccmr[0],
                self.CCMR2: self.ccmr[1], self.CCER: self.ccer, self.CNT: self.cnt_now(),
                self.PSC: self.psc, self.ARR: self.arr}
        if off in regs:
            return regs[off]
        if off in self.CCR:
            return self.ccr[self.CCR.index(off)]
        return 0

    def write(self, off, v):
        if not self.clocked():
            self.board.note(f"{self.name} written with its clock off (ignored)")
            return
        b = self.board
        self._next = False
        if off == self.CR1:
            if v & 0x70:
                raise NotModelled(f"{self.name}: only up-counting edge-aligned mode is modelled")
            was = self.running()
            if was and not v & 1:
                self.cnt = self.cnt_now()
            self.cr1 = v & 0x3FF
            if not was and v & 1:
                self.start()
        elif off == self.CR2:
            self.cr2 = v
        elif off == self.SMCR:
            self.smcr = v
        elif off == self.DIER:
            self.dier = v
        elif off == self.SR:
            self.sr &= v  # rc_w0
        elif off == self.EGR:
            if v & 1:  # UG: reinitialise the counter, load the preloads
                self.load_preloads()
                self.cnt, self.t_ref = 0, b.t
                if not self.cr1 & 4:  # URS = 0: UG sets UIF
                    self.sr |= 1
            self.sr |= v & 0x1E
        elif off == self.CCMR1:
            self.ccmr[0] = v
        elif off == self.CCMR2:
            self.ccmr[1] = v
        elif off == self.CCER:
            self.ccer = v
        elif off == self.CNT:
            self.cnt, self.t_ref = v & self.max, b.t
        elif off == self.PSC:
            self.psc = v & 0xFFFF
        elif off == self.ARR:
            self.arr = v & self.max
            if not self.cr1 & 0x80:  # ARPE off: takes effect now
                self.arr_a = self.arr
        elif off in self.CCR:
            k = self.CCR.index(off)
            self.ccr[k] = v & self.max
            if not self.ocpe(k):
                self.ccr_a[k] = self.ccr[k]
        b.trace(self.name, off, v)

    def start(self):
        self.t_ref = self.board.t
        self.started_at = self.board.t
        if self.cr2 >> 4 & 7 == 1:  # MMS = enable: CEN is TRGO
            for slave in self.board.timers.values():
                ts, sms = slave.smcr >> 4 & 7, slave.smcr & 7
                itr = self.ITR.get(slave.name, ())
                if sms == 6 and ts < 4 and ts < len(itr) and itr[ts] == self.name and not slave.running():
                    slave._next = False
                    slave.cr1 |= 1
                    slave.start()


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
            self.ipr[n:n + size] = v.to_bytes(size, "little")
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


# ------------------------------------------------------------------------- board


class Board:
    """An STM32F405RG running an ELF: memory, peripherals, the run loop."""

    def __init__(self, elf, bank=None, quantum=QUANTUM, flash_timing="typ"):
        """`elf` is the path of the firmware, or a list of (address, bytes) segments
        (the model tests' hand-assembled programs)."""
        self.segments, self.symbols = (elf, {}) if isinstance(elf, list) else load_elf(elf)
        self.quantum = quantum
        self.flash_timing = flash_timing
        self.erases = []  # (start, end, sector) of every sector erase
        self.programs = 0  # flash writes programmed
        self.dirty_writes = []  # (t, addr, old, value): programs over bits not erased
        # A test's look at each flash operation as it starts: on_flash("erase", sector)
        # or on_flash("program", address); it may cut the power there (`power_cut`).
        self.on_flash = None
        self.tick_instructions = None  # [(t, instructions)] per TIM7 handler, when counted
        self.counting = False
        self._count_hook = None
        self._polls = None  # (reads, fed) of a wait on a busy flash
        self._flash_writes = []
        # The host's end of each USART: the wire outlives the chip's resets.
        self.usarts = {
            "USART1": Usart(self, "USART1", IRQ["USART1"], Rcc.APB2ENR, 4, 2),
            "USART2": Usart(self, "USART2", IRQ["USART2"], Rcc.APB1ENR, 17, 1),
            "USART3": Usart(self, "USART3", IRQ["USART3"], Rcc.APB1ENR, 18, 1),
        }
        self.usart2 = self.usarts["USART2"]
        self.t = 0
        self.events = []  # scheduled harness actions [(t, seq, fn)]
        self.seq = 0
        self.log = []  # (t, periph, offset, value) of traced writes
        self.notes = []
        self.unmodelled = set()
        self.resets = []  # (t, cause)
        self.all_feeds = []  # every watchdog start and reload, across resets
        self.frames = []  # (t, ccr[8] preload, ccr[8] active) after each TIM7 handler
        self.led = []  # (t, level) of PC12
        self.pin_modes = []  # (t, pin, mode, af, {timer: (running, ccr, ccr active)})
        self.taken = []  # (t, exception number) entries, for the tests
        self.tick_irq_blocked = False
        self.fault_addr = None
        self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self.uc.ctl_set_cpu_model(A.UC_CPU_ARM_CORTEX_M4)
        uc = self.uc
        uc.mem_map(FLASH_BASE, FLASH_SIZE)
        uc.mem_map(SRAM_BASE, SRAM_SIZE)
        uc.mem_map(CCM_BASE, CCM_SIZE)
        uc.mem_map(0x1FFF_0000, 0x10000)  # system memory, OTP, option bytes
        uc.mem_map(0xE000_0000, 0xE000)  # ITM, DWT, FPB: read back
        uc.mem_map(0xE000_F000, 0xF1000)  # rest of the PPB, DBGMCU
        uc.mem_map(0xFFFF_F000, 0x1000)  # EXC_RETURN values land here
        uc.mmio_map(0x4000_0000, 0x8_0000, self._pread, None, self._pwrite, None)
        uc.mmio_map(0xE000_E000, 0x1000, self._sread, None, self._swrite, None)
        uc.mem_write(FLASH_BASE, b"\xff" * FLASH_SIZE)
        for addr, data in self.segments:
            if not (FLASH_BASE <= addr and addr + len(data) <= FLASH_BASE + FLASH_SIZE):
                raise ValueError(f"segment at {addr:#x} is not in flash")
            uc.mem_write(addr, data)
        if bank is not None:
            self.set_bank(bank)
        self._hook_sleep_instructions()
        uc.hook_add(UC_HOOK_INTR, self._intr)
        uc.hook_add(UC_HOOK_MEM_WRITE, self._flash_write, None, FLASH_BASE, FLASH_BASE + FLASH_SIZE - 1)
        self.csr_flags = 0x0E00_0000  # power-on reset flags
        self.devices = []  # models outside the APB/AHB1 map (otg_fs.OtgFs), see `attach`
        self._power_on()

    def attach(self, dev):
        """Maps a model at `dev.BASE`: its registers, IRQ line, wake-ups and reset."""
        rd = lambda uc, o, size, _: dev.read(o & ~3) >> 8 * (o & 3) & ((1 << 8 * size) - 1)  # noqa: E731
        self.uc.mmio_map(dev.BASE, dev.SIZE, rd, None, lambda uc, o, size, v, _: dev.write(o & ~3, v), None)
        self.devices.append(dev)
        return dev

    # -- memory
    def set_bank(self, image):
        """The bank region as flashed: `image` then erased bytes."""
        if len(image) > BANK_SIZE:
            raise ValueError("bank larger than its region")
        self.uc.mem_write(BANK_BASE, bytes(image) + b"\xff" * (BANK_SIZE - len(image)))

    def read32(self, addr):
        return struct.unpack("<I", self.uc.mem_read(addr, 4))[0]

    def _hook_sleep_instructions(self):
        text = [(a, d) for a, d in self.segments]
        for addr, data in text:
            for i in range(0, len(data) - 1, 2):
                hw = data[i] | data[i + 1] << 8
                if hw in (0xBF20, 0xBF30, 0xBF40):
                    self.uc.hook_add(UC_HOOK_CODE, self._sleep_hook, hw, addr + i, addr + i)

    def _sleep_hook(self, uc, address, size, kind):
        if kind == 0xBF40:  # SEV
            self.event_reg = True
            return
        self.stop = ("wfe" if kind == 0xBF20 else "wfi", address)
        uc.emu_stop()

    def _intr(self, uc, intno, _):
        self.stop = ("intr", intno)
        uc.emu_stop()

    def _flash_write(self, uc, _access, addr, size, value, _):
        """A CPU store into flash: once the quantum ends, the flash interface
        decides what the cells hold (`Flash.program`). (Not stopped here: unicorn
        would run the store again.)"""
        old = int.from_bytes(uc.mem_read(addr, size), "little")
        self._flash_writes.append((addr, self.flash.program(addr, size, value, old).to_bytes(size, "little")))

    def flash_busy_changed(self):
        """A flash operation started or ended. (The quantum is not cut short here:
        stopping inside a bus access makes unicorn run that instruction again.)"""

    def _poll(self, kind):
        """Watches for a wait on a busy flash: FLASH_SR read again and again with
        nothing but watchdog reloads between (`kind` is "sr", "feed" or anything
        else). Such a loop, in RAM, would spin for the whole erase; the board skips
        to its end instead, reloading the watchdog as the loop did (or not). (A
        loop that also counts its rounds to give up early is not told apart.)"""
        if kind == "sr" and self.flash.busy():
            n, fed = self._polls if self._polls else (0, False)
            self._polls = (n + 1, fed)
            if n + 1 >= 32:
                self.stop = ("flash-wait", fed)
                self.uc.emu_stop()
        elif kind == "feed" and self._polls:
            self._polls = (self._polls[0], True)
        else:
            self._polls = None

    def _skip_flash_wait(self, end, fed):
        """Runs the clock to the end of the flash operation (or `end`, or an
        interrupt that would preempt the loop), reloading the watchdog every
        millisecond if the loop did."""
        target = min(self.flash.busy_until or self.t, end)
        self._polls = None
        while self.t < target:
            if fed:
                self.iwdg.write(0x00, 0xAAAA)
            if self._advance_to(min(target, self.t + T_HZ // 1000)):
                return True
            if self._next_exception() is not None:
                break
        return False

    def count_tick_instructions(self, on=True):
        """From now on (until called with `on` false), appends (time, instructions)
        of each TIM7 handler (its own and anything nested in it) to
        `tick_instructions`."""
        self.counting = on
        if on and self.tick_instructions is None:
            self.tick_instructions = []

    def _count(self, uc, address, size, _):
        self._icount += 1
    # -- reset
    def _power_on(self):
        self.rcc = Rcc(self, self.csr_flags)
        self.pwr = Pwr()
        self.flash = Flash(self, self.flash_timing)
        for u in self.usarts.values():
            u.reset()
        self.timers = {}
        for i, name in enumerate(["TIM2", "TIM3", "TIM4", "TIM5", "TIM6", "TIM7"]):
            bits = 32 if name in ("TIM2", "TIM5") else 16
            irq = IRQ["TIM6_DAC" if name == "TIM6" else name]
            self.timers[name] = Timer(self, name, i, irq, bits, name in ("TIM6", "TIM7"))
        self.iwdg = Iwdg(self)
        self.gpio = [Gpio(self, "GPIO" + "ABCDEFGHI"[i], i) for i in range(9)]
        self.syscfg = Regs()
        self.exti = Exti(self)
        self.nvic = Nvic(self)
        self.other = Regs()
        for dev in getattr(self, "devices", []):
            dev.chip_reset()
        self.active = []  # exception numbers, innermost last
        self.saved = []  # per active exception: EXC_RETURN used
        self.event_reg = False
        self.sleeping = None
        self.stop = None
        self.boot_at = self.t
        uc = self.uc
        for r in range(13):
            uc.reg_write(A.UC_ARM_REG_R0 + r, 0)
        uc.reg_write(A.UC_ARM_REG_PRIMASK, 0)
        uc.reg_write(A.UC_ARM_REG_BASEPRI, 0)
        uc.reg_write(A.UC_ARM_REG_CONTROL, 0)
        uc.reg_write(A.UC_ARM_REG_SP, self.read32(FLASH_BASE))
        uc.reg_write(A.UC_ARM_REG_LR, 0xFFFF_FFFF)
        self.pc = self.read32(FLASH_BASE + 4) & ~1

    def request_reset(self, cause):
        """A reset asked for by the running code: it takes effect once the CPU has
        stopped (a reset from inside a bus access would be undone by the rest of
        the quantum)."""
        self.stop = ("reset", cause)
        self.uc.emu_stop()

    def power_cut(self):
        """The supply cut and back at once, from a peripheral's model in the middle
        of a quantum: the chip restarts as from a reset once the CPU has stopped."""
        self.request_reset("power")

    def reset(self, cause):
        """A system reset: peripherals and core to their reset state, RAM kept."""
        self.resets.append((self.t, cause))
        self.tick_irq_blocked = False
        self.flash.abort(self.t)
        if self._count_hook is not None:
            self.uc.hook_del(self._count_hook)
            self._count_hook = None
        flag = {"IWDG": 1 << 29, "SYSRESETREQ": 1 << 28}.get(cause, 0)
        self.csr_flags = self.rcc.r.get(Rcc.CSR, 0) & 0xFF00_0000 | flag | (1 << 26)
        self._power_on()
        self.reset_pending = True

    # -- bus
    def note(self, text):
        if text not in self.notes:
            self.notes.append(text)

    def trace(self, periph, off, v):
        self.log.append((self.t, periph, off, v))

    def _periph(self, addr):
        if self.fault_addr is not None and addr == self.fault_addr:
            self.fault_addr = None
            self.stop = ("fault", addr)
            self.uc.emu_stop()
        if 0x4000_0000 <= addr < 0x4000_1800:
            name = ["TIM2", "TIM3", "TIM4", "TIM5", "TIM6", "TIM7"][(addr - 0x4000_0000) // 0x400]
            return self.timers[name], addr & 0x3FF
        if 0x4000_3000 <= addr < 0x4000_3400:
            return self.iwdg, addr & 0x3FF
        if 0x4000_4400 <= addr < 0x4000_4C00:
            return self.usarts["USART2" if addr < 0x4000_4800 else "USART3"], addr & 0x3FF
        if 0x4001_1000 <= addr < 0x4001_1400:
            return self.usarts["USART1"], addr & 0x3FF
        if 0x4000_7000 <= addr < 0x4000_7400:
            return self.pwr, addr & 0x3FF
        if 0x4001_3800 <= addr < 0x4001_3C00:
            return self.syscfg, addr & 0x3FF
        if 0x4001_3C00 <= addr < 0x4001_4000:
            return self.exti, addr & 0x3FF
        if 0x4002_0000 <= addr < 0x4002_2400:
            return self.gpio[(addr - 0x4002_0000) // 0x400], addr & 0x3FF
        if 0x4002_3800 <= addr < 0x4002_3C00:
            return self.rcc, addr & 0x3FF
        if 0x4002_3C00 <= addr < 0x4002_4000:
            return self.flash, addr & 0x3FF
        self.unmodelled.add(addr)
        return self.other, addr

    def _pread(self, uc, off, size, _):
        p, o = self._periph(0x4000_0000 + off)
        self._poll("sr" if p is self.flash and o & ~3 == Flash.SR else "other")
        v = p.read(o & ~3) >> (8 * (o & 3))
        return v & ((1 << (8 * size)) - 1)

    def _pwrite(self, uc, off, size, value, _):
        p, o = self._periph(0x4000_0000 + off)
        self._poll("feed" if p is self.iwdg and o == 0 and value & 0xFFFF == 0xAAAA else "other")
        if size != 4:
            shift = 8 * (o & 3)
            mask = ((1 << (8 * size)) - 1) << shift
            value = (p.read(o & ~3) & ~mask) | ((value << shift) & mask)
        p.write(o & ~3, value & 0xFFFF_FFFF)

    def _sread(self, uc, off, size, _):
        return self.nvic.read(off, size) & ((1 << (8 * size)) - 1)

    def _swrite(self, uc, off, size, value, _):
        self.nvic.write(off, value, size)

    def pins_changed(self, port, before):
        after = port.levels()
        for pin in range(16):
            if before[pin] != after[pin]:
                sel = self.syscfg.read(0x08 + 4 * (pin // 4)) >> (4 * (pin % 4)) & 0xF
                if sel == port.index:
                    self.exti.edge(pin, after[pin] == 1)
                if port.name == "GPIOC" and pin == 12:
                    self.led.append((self.t, after[pin]))

    def mode_changed(self, port, pin):
        """Records a pin's new mode with the state of the PWM timers at that moment."""
        timers = {n: (t.running(), tuple(t.ccr), tuple(t.ccr_a)) for n, t in self.timers.items()
                  if n in ("TIM3", "TIM4")}
        self.pin_modes.append((self.t, f"P{port.name[-1]}{pin}", port.mode(pin), port.af(pin), timers))

    # -- harness controls
    def at(self, t_s, fn):
        """Runs `fn(board)` at time `t_s` seconds."""
        self.events.append((round(t_s * T_HZ), self.seq, fn))
        self.seq += 1
        self.events.sort()

    def press(self, t_s, hold_s, port=0, pin=0):
        """Drives the button pin high at `t_s` for `hold_s` seconds."""
        self.at(t_s, lambda b: b.gpio[port].drive(pin, 1))
        self.at(t_s + hold_s, lambda b: b.gpio[port].drive(pin, 0))

    def now(self):
        return self.t / T_HZ

    # -- exceptions
    def _irq_lines(self):
        lines = 0
        for t in self.timers.values():
            if t.irq_line():
                lines |= 1 << (16 + t.irq)
        ex = self.exti.lines()
        for line in range(16):
            if ex >> line & 1:
                n = IRQ["EXTI%d" % line] if line < 5 else IRQ["EXTI9_5" if line < 10 else "EXTI15_10"]
                lines |= 1 << (16 + n)
        for u in self.usarts.values():
            if u.irq_line():
                lines |= 1 << (16 + u.irq)
        f = self.flash
        if (f.cr & f.EOPIE and f.sr & f.EOP) or (f.cr & f.ERRIE and f.sr & f.OPERR):
            lines |= 1 << (16 + IRQ["FLASH"])
        lines |= sum(1 << (16 + d.IRQ) for d in self.devices if d.irq_line())
        if self.tick_irq_blocked:
            lines &= ~(1 << (16 + IRQ["TIM7"]))
        return lines

    def _exec_prio(self, with_primask=True):
        p = 256
        for n in self.active:
            p = min(p, self.nvic.prio(n))
        uc = self.uc
        bp = uc.reg_read(A.UC_ARM_REG_BASEPRI) & 0xF0
        if bp:
            p = min(p, bp)
        if with_primask and uc.reg_read(A.UC_ARM_REG_PRIMASK) & 1:
            p = min(p, 0)
        return p

    def _next_exception(self, with_primask=True):
        nv = self.nvic
        nv.pending |= self._irq_lines() & ~sum(1 << n for n in self.active)
        best = None
        cand = nv.pending & ((nv.enabled << 16) | 0xFFFC)
        while cand:
            n = (cand & -cand).bit_length() - 1
            cand &= cand - 1
            if best is None or nv.prio(n) < nv.prio(best):
                best = n
        if best is not None and nv.prio(best) < self._exec_prio(with_primask):
            return best
        return None

    def _enter(self, n):
        uc = self.uc
        if uc.reg_read(A.UC_ARM_REG_CONTROL) & 2:
            raise NotModelled("thread mode on the process stack (CONTROL.SPSEL)")
        sp = uc.reg_read(A.UC_ARM_REG_SP)
        align = (sp >> 2) & 1
        frame = (sp - 32) & ~(align << 2)
        xpsr = uc.reg_read(A.UC_ARM_REG_XPSR)
        if xpsr & 0x0600_FC00:
            raise NotModelled("exception inside an IT block")
        regs = [uc.reg_read(r) for r in (A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2,
                                         A.UC_ARM_REG_R3, A.UC_ARM_REG_R12, A.UC_ARM_REG_LR)]
        regs += [self.pc, (xpsr & 0xF80F_0000) | (1 << 24) | (align << 9) | (self.active[-1] if self.active else 0)]
        uc.mem_write(frame, struct.pack("<8I", *regs))
        uc.reg_write(A.UC_ARM_REG_SP, frame)
        exc_return = 0xFFFF_FFF1 if self.active else 0xFFFF_FFF9
        uc.reg_write(A.UC_ARM_REG_LR, exc_return)
        self.nvic.pending &= ~(1 << n)
        self.active.append(n)
        self.saved.append(exc_return)
        vtor = self.nvic.vtor or FLASH_BASE
        self.pc = self.read32(vtor + 4 * n) & ~1
        self.sleeping = None
        self.event_reg = True
        self.taken.append((self.t, n))
        if n == 16 + IRQ["TIM7"] and self.counting and self._count_hook is None:
            self._icount = 0
            self._count_hook = uc.hook_add(UC_HOOK_CODE, self._count)

    def _exit(self, exc_return):
        uc = self.uc
        if not self.active or exc_return != self.saved[-1]:
            raise NotModelled(f"exception return {exc_return:#x} with active {self.active}")
        n = self.active.pop()
        self.saved.pop()
        frame = uc.reg_read(A.UC_ARM_REG_SP)
        r0, r1, r2, r3, r12, lr, pc, xpsr = struct.unpack("<8I", uc.mem_read(frame, 32))
        for reg, v in zip((A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2, A.UC_ARM_REG_R3,
                           A.UC_ARM_REG_R12, A.UC_ARM_REG_LR), (r0, r1, r2, r3, r12, lr)):
            uc.reg_write(reg, v)
        uc.reg_write(A.UC_ARM_REG_APSR, xpsr & 0xF80F_0000)
        uc.reg_write(A.UC_ARM_REG_SP, frame + 32 + (4 if xpsr >> 9 & 1 else 0))
        self.pc = pc & ~1
        self.event_reg = True
        if n == 16 + IRQ["TIM7"]:
            if self._count_hook is not None:
                uc.hook_del(self._count_hook)
                self._count_hook = None
                self.tick_instructions.append((self.t, self._icount))
            t3, t4 = self.timers["TIM3"], self.timers["TIM4"]
            self.frames.append((self.t, tuple(t3.ccr + t4.ccr), tuple(t3.ccr_a + t4.ccr_a)))

    # -- the run loop
    def _advance_to(self, t):
        """Moves time to `t`: timers, watchdog, harness events in order."""
        while True:
            nxt = t
            if self.events and self.events[0][0] < nxt:
                nxt = self.events[0][0]
            exp = self.iwdg.expires()
            if exp is not None and exp < nxt:
                nxt = exp
            for tim in self.timers.values():
                tim.advance(nxt)
            for u in self.usarts.values():
                u.advance(nxt)
            self.t = max(self.t, nxt)
            self.flash.finish(self.t)
            if exp is not None and exp <= self.t and self.iwdg.expires() == exp:
                self.reset("IWDG")
                return True
            if self.events and self.events[0][0] <= self.t:
                _, _, fn = self.events.pop(0)
                fn(self)
                continue
            if nxt == t:
                return False

    def _wake_time(self, limit):
        """Earliest time something can wake a sleeping core, at most `limit`."""
        cands = [limit]
        if self.events:
            cands.append(self.events[0][0])
        exp = self.iwdg.expires()
        if exp is not None:
            cands.append(exp)
        for tim in self.timers.values():
            ev = tim.next_event()
            if ev is not None and tim.dier & 0x5F:
                cands.append(ev[0])
        for u in self.usarts.values():
            ev = u.next_event()
            if ev is not None and u.can_wake():
                cands.append(ev)
        if self.flash.busy_until is not None:
            cands.append(self.flash.busy_until)
        cands += [e for e in (d.next_event() for d in self.devices) if e is not None]
        return max(self.t, min(cands))

    def _stalled(self, exception=None):
        """Whether the CPU waits for a busy flash: it executes from flash, or is about
        to take an exception whose vector or handler is in flash."""
        if not self.flash.busy():
            return False
        in_flash = lambda a: FLASH_BASE <= a < FLASH_BASE + FLASH_SIZE  # noqa: E731
        if exception is not None:
            vtor = self.nvic.vtor or FLASH_BASE
            return in_flash(vtor) or in_flash(self.read32(vtor + 4 * exception) & ~1)
        return self.sleeping is None and in_flash(self.pc)

    def run(self, seconds):
        """Runs until `seconds` of emulated time have passed since now."""
        end = self.t + round(seconds * T_HZ)
        self.reset_pending = False
        while self.t < end:
            if self.reset_pending:
                self.reset_pending = False
                continue
            wake_any = self.sleeping == "wfi"
            n = self._next_exception(with_primask=not wake_any) if self.sleeping else self._next_exception()
            if n is not None and self.sleeping and wake_any and self.uc.reg_read(A.UC_ARM_REG_PRIMASK) & 1:
                self.sleeping = None  # WFI wakes on a masked interrupt without taking it
                continue
            if n is not None and self._stalled(n):
                self._advance_to(min(self.flash.busy_until, end))
                continue
            if n is not None:
                self._enter(n)
                continue
            if self.sleeping:
                if self._advance_to(self._wake_time(end)):
                    continue
                if self.t >= end:
                    break
                continue
            if self._stalled():
                self._advance_to(min(self.flash.busy_until, end))
                continue
            self._step(end)

    def _step(self, end):
        uc = self.uc
        self.stop = None
        units = T_HZ // self.rcc.hclk()
        count = self.quantum
        # A USART event inside the quantum: stop there, so that its interrupt is
        # taken between two bytes as on the chip, not after several.
        for u in self.usarts.values():
            ev = u.next_event()
            if ev is not None and u.can_wake() and ev > self.t:
                count = min(count, max(1, -(-(ev - self.t) // units)))
        try:
            uc.emu_start(self.pc | 1, 0, 0, count)
            error = None
        except UcError as e:
            error = e
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        stop = self.stop
        executed = count if stop is None and error is None else max(1, count // 2)
        writes, self._flash_writes = self._flash_writes, []
        for addr, cells in writes:
            uc.mem_write(addr, cells)
        if stop and stop[0] == "reset":
            self.reset(stop[1])
            return
        if stop and stop[0] in ("wfe", "wfi"):
            self.pc = stop[1] + 2
            if stop[0] == "wfe" and self.event_reg:
                self.event_reg = False
            else:
                self.sleeping = stop[0]
        elif pc >= 0xFFFF_FF00:
            self._exit(pc | 1)
        elif stop and stop[0] == "flash":
            self.pc = pc
        elif stop and stop[0] == "flash-wait":
            self.pc = pc
            if self._advance_to(min(end, self.t + executed * units)):
                return
            self._skip_flash_wait(end, stop[1])
            return
        elif stop and stop[0] == "fault":
            self.pc = pc
            self._enter(HARDFAULT)
        elif error is not None or (stop and stop[0] == "intr"):
            raise NotModelled(f"CPU stopped at {pc:#010x}: {error or stop}")
        else:
            self.pc = pc
        if self._advance_to(min(end, self.t + executed * units)):
            return

    # -- views for the tests
    def poke(self, addr, value):
        """A 32-bit write on the bus, as the CPU would make it (peripherals, SCS)."""
        if addr >= 0xE000_E000:
            self._swrite(self.uc, addr - 0xE000_E000, 4, value, None)
        else:
            self._pwrite(self.uc, addr - 0x4000_0000, 4, value, None)

    def peek(self, addr):
        """A 32-bit read on the bus (with its side effects: reading a USART's DR
        clears RXNE)."""
        if addr >= 0xE000_E000:
            return self._sread(self.uc, addr - 0xE000_E000, 4, None)
        return self._pread(self.uc, addr - 0x4000_0000, 4, None)

    def pin(self, name):
        """(mode, af, pupd) of a pin named like "PA6"."""
        port = self.gpio["ABCDEFGHI".index(name[1])]
        pin = int(name[2:])
        pupd = port.r.get(Gpio.PUPDR, 0) >> (2 * pin) & 3
        return port.mode(pin), port.af(pin), pupd


# ------------------------------------------------------------------ serving


def serve(board, link_path, usart="USART2", seconds=None, speed=1.0, stop=None):
    """Runs `board` in step with the wall clock (`speed` emulated seconds per
    second, at most) with a USART's wire on a pseudo-terminal, whose path is linked
    at `link_path`: `touchc sleeve --port LINK_PATH ...` then talks to the twin as
    to a sleeve on a USB-serial adapter. Stops after `seconds` (emulated), when
    `stop` (a threading.Event) is set, or when interrupted."""
    import os
    import select
    import time
    import tty

    port = board.usarts[usart]
    master, slave = os.openpty()
    tty.setraw(slave)
    if os.path.lexists(link_path):
        os.unlink(link_path)
    os.symlink(os.ttyname(slave), link_path)
    step = 0.001
    try:
        start, t0 = time.monotonic(), board.t
        while (seconds is None or board.t - t0 < seconds * T_HZ) and not (stop and stop.is_set()):
            ready, _, _ = select.select([master], [], [], 0)
            if ready:
                try:
                    port.send(os.read(master, 4096))
                except OSError:
                    pass  # no process has the port open
            board.run(step)
            out = port.take()
            if out:
                os.write(master, out)
            ahead = (board.t - t0) / T_HZ / speed - (time.monotonic() - start)
            if ahead > 0:
                select.select([master], [], [], ahead)
    finally:
        os.unlink(link_path)
        os.close(master)
        os.close(slave)
    return board


if __name__ == "__main__":
    import argparse
    import os
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
    try:
        serve(b, a.link, a.usart, a.seconds, a.speed)
    except KeyboardInterrupt:
        pass
