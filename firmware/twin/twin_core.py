"""The twin's time base, chip constants, the ELF loader and the clock and timer
models: RCC, PWR, TIM2-TIM7 (RM0090 sections 5, 6, 18, 20). `twin.py` gathers
the modules; README.md says what is and is not modelled.

Time is counted in units of 1/336 MHz (so that the 16 MHz HSI, the 168 MHz core,
the 84 MHz timer clock and the 32 kHz LSI are all whole numbers of units)."""

import struct


T_HZ = 336_000_000
"""Time units per second."""
HSI_HZ = 16_000_000
LSI_HZ = 32_000
QUANTUM = 2000
"""Instructions per run of the CPU between two peripheral updates (12 us at 168 MHz);
a run also ends at the next USART or timer event that raises an interrupt."""
ENTRY_CYCLES = 12
"""Core cycles from an interrupt's acceptance to its handler's first instruction
(PM0214 and the Cortex-M4 TRM: 12 cycles, stacking in parallel with the vector fetch,
with zero-wait-state memory)."""
MASKED_STEP = 4
"""Instructions per run while an interrupt waits for PRIMASK or BASEPRI to let it in:
it is taken within this many instructions of the unmasking."""
MASKED_PRECISE = 20_000
"""Instructions of one masked stretch stepped at `MASKED_STEP`; a longer one (a wait
for a flash operation) goes on in whole quanta."""

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

    def next_interrupt(self):
        """Time of the next event whose interrupt is enabled in DIER, or None."""
        ev = self.next_event()
        if ev is None:
            return None
        flag = 1 if ev[1] == "update" else 2 << ev[1]
        return ev[0] if self.dier & flag else None

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
