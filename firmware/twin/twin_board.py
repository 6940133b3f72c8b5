"""The board: an STM32F405RG running an ELF on unicorn's Cortex-M4, its memory,
the peripheral models around it and the run loop. The CPU runs in quanta of
`QUANTUM` instructions, one core cycle each; peripherals are advanced between
quanta, interrupts are taken between quanta. `wfe`/`wfi` end a quantum and the
clock jumps to the next event that can wake the core. `twin.py` gathers the
modules; exception entry and return are `twin_exceptions.py`'s."""

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

from twin_core import (BANK_BASE, BANK_SIZE, CCM_BASE, CCM_SIZE, ENTRY_CYCLES, FLASH_BASE, FLASH_SIZE, HARDFAULT,
                       IRQ, MASKED_PRECISE, MASKED_STEP, QUANTUM, SRAM_BASE, SRAM_SIZE, T_HZ, NotModelled, Pwr, Rcc,
                       Regs, Timer, load_elf)
from twin_exceptions import Exceptions
from twin_periph import Exti, Gpio, Iwdg, Nvic
from twin_usart_flash import Flash, Usart


class Board(Exceptions):
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
        self.tick_lowered = None  # [(t, instructions)] of the handlers that lowered their priority: that part
        self._icount_top = None
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
        `tick_instructions`; of one that lowers its priority, those up to there,
        and the rest to `tick_lowered`."""
        self.counting = on
        if on and self.tick_instructions is None:
            self.tick_instructions = []
            self.tick_lowered = []

    def whole_tick_instructions(self):
        """(time, instructions) of each counted TIM7 handler whole: its part at the
        top priority and, of one that lowered its priority, the rest (anything nested
        in it included)."""
        lowered = dict(self.tick_lowered or [])
        return [(t, n + lowered.get(t, 0)) for t, n in self.tick_instructions or []]

    def _count(self, uc, address, size, _):
        self._icount += 1

    def priority_changed(self, exceptions):
        """A write changed the priority of `exceptions`. For an active one, what it
        lets in changes at once: the quantum ends after this store (a store the
        CPU then runs again writes the same value, which changes nothing). A TIM7
        handler that lowers its own priority ends its part at the top there: its
        instructions so far are what `tick_instructions` counts."""
        tim7 = 16 + IRQ["TIM7"]
        if tim7 in exceptions and tim7 in self.active and self._count_hook is not None:
            if self.nvic.prio(tim7) > 0 and self._icount_top is None:
                self._icount_top = self._icount
        if any(n in self.active for n in exceptions):
            self.stop = ("priority", None)
            self.uc.emu_stop()
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
        self._masked_for = 0  # instructions run so far while an interrupt waits on a mask
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
                self._masked_for = 0
                # Stacking and the vector fetch: the handler starts this much later.
                self._advance_to(min(end, self.t + ENTRY_CYCLES * (T_HZ // self.rcc.hclk())))
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
        # The same for a timer's interrupt (the tick): taken at its time, not at the
        # end of the quantum it falls in.
        for tim in self.timers.values():
            ev = tim.next_interrupt()
            if ev is not None and ev > self.t:
                count = min(count, max(1, -(-(ev - self.t) // units)))
        # An interrupt held out by PRIMASK or BASEPRI is taken within a few
        # instructions of the code letting it in, as on the chip.
        if not self._masked():
            self._masked_for = 0
        elif self._masked_for < MASKED_PRECISE:
            count = min(count, MASKED_STEP)
            self._masked_for += count
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
        elif stop and stop[0] in ("flash", "priority"):
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
