"""The board's exceptions, as the Cortex-M4 takes them (PM0214): which interrupt
lines are up, the execution priority with PRIMASK and BASEPRI, the next exception
to take, entry (the stacked frame, EXC_RETURN) and return. A mixin of `Board`,
whose run loop calls these between quanta; it reads the board's peripherals, NVIC,
active stack and instruction counters."""

import struct

from unicorn import UC_HOOK_CODE
from unicorn import arm_const as A

from twin_core import FLASH_BASE, IRQ, NotModelled


class Exceptions:
    """Exception entry and return for `Board` (see the module's documentation)."""

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

    def _masked(self):
        """Whether an interrupt is pending that PRIMASK or BASEPRI keeps out (the
        active handlers' priorities alone would let it in)."""
        nv = self.nvic
        cand = nv.pending & ((nv.enabled << 16) | 0xFFFC)
        if not cand:
            return False
        best = min(nv.prio(n) for n in range(cand.bit_length()) if cand >> n & 1)
        active = min((nv.prio(n) for n in self.active), default=256)
        return best < active

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
            self._icount_top = None
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
                top = self._icount if self._icount_top is None else self._icount_top
                self.tick_instructions.append((self.t, top))
                if self._icount_top is not None:
                    self.tick_lowered.append((self.t, self._icount - top))
            t3, t4 = self.timers["TIM3"], self.timers["TIM4"]
            self.frames.append((self.t, tuple(t3.ccr + t4.ccr), tuple(t3.ccr_a + t4.ccr_a)))
