"""Firmware in the loop: the release image on the emulated STM32F405 prints a job that
`dollop send` uploads over the emulated UART4, and its pins are compared with
`dollop simulate --model-only` of the same job and config.

What the harness adds to emulate.py's register model (see the README section "Running the
firmware in an emulator"):
  * UART4 (QEMU's stm32f2xx-usart, the fourth `-serial`) on a local TCP port; the host
    tool connects with `--port tcp:127.0.0.1:PORT`.
  * Pins: only the three GPIO BSRR registers are watched during a print (every STEP edge,
    DIR change, valve, enable and LED write is one debugger stop). QEMU drops stores to
    its unimplemented GPIO block anyway, so the harness records the write and moves PC
    past the store instead of single-stepping it.
  * Inputs: QEMU's GPIO reads as 0, which would mean every endstop triggered. Watching
    the control loop's IDR loads would stop four times a control period, so the harness
    finds those loads once (one period with GPIOC IDR watched) and rewrites each into a
    move of the modelled level (`movw Rt, #IDR`, or for a 16-bit load `movs`/`mvns`),
    rewriting the immediates whenever a level changes (a few times a run). The machine
    starts inside its travel; endstops are reported from the true position, which the
    harness counts from STEP rising edges and DIR.
  * E-stop: QEMU's EXTI does not model SWIER and nothing drives its GPIO lines, so the
    harness pends EXTI15_10 in the NVIC and answers the handler's read of EXTI_PR with
    line 13 set (a watchpoint armed only then), and sets PC13 high in the input model.
  * Flash: QEMU's flash is ROM, so the job store's programming stores are done by the
    harness (a write watchpoint on sectors 6..11) and a sector erase (FLASH_CR SER+STRT)
    fills the sector with 0xFF. The flipped-byte scenario flips one byte on its way into
    the store.
"""

import csv
import math
import os
import re
import select
import socket
import subprocess
import sys
import signal
import time
import tomllib

import emulate as E

AXES = ["X", "Y", "Z", "E0", "E1", "E2", "E3"]
STEP_PINS = [("GPIOC", 6), ("GPIOC", 7), ("GPIOC", 8), ("GPIOB", 6), ("GPIOB", 7), ("GPIOB", 8), ("GPIOB", 9)]
DIR_PINS = [("GPIOB", 12), ("GPIOB", 13), ("GPIOB", 14), ("GPIOB", 0), ("GPIOB", 1), ("GPIOB", 10), ("GPIOB", 11)]
VALVE_PINS = [("GPIOA", i) for i in range(4)]
ENABLE_PIN = ("GPIOB", 15)
LED_PIN = ("GPIOA", 5)
BSRR = {"GPIOA": 0x40020018, "GPIOB": 0x40020418, "GPIOC": 0x40020818}
GPIOC_IDR = 0x40020810
GPIOC_BASE = 0x40020800
ENDSTOP_BITS = [0, 1, 2]  # PC0..PC2, active low
ESTOP_BIT = 13  # PC13, high = stop
STORE_BASE, STORE_LEN, SECTOR = 0x08040000, 0xC0000, 0x20000
EXTI_PR = 0x40013C14
ACR_DCEN, ACR_DCRST = 1 << 10, 1 << 12  # FLASH_ACR data cache enable and reset
NVIC_ISPR = 0xE000E200
IWDG_KR = 0x40003000
IWDG_PR = 0x40003004  # PR and RLR (8 bytes)
EXTI15_10_IRQ = 40
UART4_IRQ = 52
UART4_SERIAL_INDEX = 3  # usart_addr[3] = 0x40004C00 in QEMU's stm32f405_soc.c
TICK_NS = 10_000
PERIOD_TICKS = 10
# A pause's head stays on its bead: between the valves' close and the resume's reopen it
# moves by the tail at most (the bundled machines' tails are under 0.7 mm of bead).
PAUSE_TAIL_MM = 1.0
# dollop::wire::Settings::default(): what `dollop send` sends besides the link-loss policy.
HOME_ORDER = [2, 0, 1]
HOME_TO_MAX = [False, False, True]
HOME_BACKOFF_MM = 2.0
LEAD_IN = 3

HOSTS = []  # host-tool subprocesses, killed on every exit path


class FilError(Exception):
    pass


# --------------------------------------------------------------------------------------
# machine


class Machine:
    """The config's axes: steps per mm and travel, and where the harness puts the carriage
    at power-up (`inset_mm` inside the homing end of each axis)."""

    def __init__(self, path, inset_mm):
        with open(path, "rb") as f:
            cfg = tomllib.load(f)
        m = cfg["motion"]
        self.spm = [float(x) for x in m["steps_per_mm"]]
        self.min_mm = [float(x) for x in m["travel_min_mm"]]
        self.max_mm = [float(x) for x in m["travel_max_mm"]]
        self.inlets = len(cfg.get("inlet", []))
        self.start_steps = []
        for a in range(3):
            span = self.max_mm[a] - self.min_mm[a]
            d = min(inset_mm, span / 2)
            mm = self.max_mm[a] - d if HOME_TO_MAX[a] else self.min_mm[a] + d
            self.start_steps.append(round(mm * self.spm[a]))
        self.start_steps += [0] * 4
        # Endstop positions, in steps: triggered at or beyond.
        self.limit_steps = [round((self.max_mm[a] if HOME_TO_MAX[a] else self.min_mm[a]) * self.spm[a])
                            for a in range(3)]

    def home_steps(self, a):
        """The firmware's own position at the endstop: roundf(home_mm * steps_per_mm)."""
        return round((self.max_mm[a] if HOME_TO_MAX[a] else self.min_mm[a]) * self.spm[a])


# --------------------------------------------------------------------------------------
# the pin log


class PinLog:
    """Every BSRR write during the run, with virtual time and step tick, and what it means:
    STEP rising edges counted with DIR into true positions, valve mask and enable changes."""

    def __init__(self, machine):
        self.m = machine
        self.level = {"GPIOA": 0, "GPIOB": 0, "GPIOC": 0}
        self.pos = list(machine.start_steps)  # true position, steps
        self.dir = [0] * 7
        self.writes = []  # (t, ticks, port, word)
        self.edges = []  # (t, ticks, axis, +1/-1)
        self.valves = []  # (t, ticks, mask)
        self.enable = []  # (t, ticks, level)
        self.dirs = []  # (t, ticks, axis, level)
        self.mask = 0
        self.on_edge = None

    def valve_mask(self, level=None):
        lv = self.level["GPIOA"] if level is None else level
        return sum(((lv >> pin) & 1) << i for i, (_, pin) in enumerate(VALVE_PINS))

    def bsrr(self, port, word, t, ticks):
        self.writes.append((t, ticks, port, word))
        sets = word & 0xFFFF
        resets = (word >> 16) & ~sets
        old = self.level[port]
        new = (old | sets) & ~resets & 0xFFFF
        self.level[port] = new
        for a, (p, pin) in enumerate(DIR_PINS):
            if p == port and (sets | resets) >> pin & 1:
                lv = new >> pin & 1
                if lv != self.dir[a] or not any(d[2] == a for d in self.dirs):
                    self.dirs.append((t, ticks, a, lv))
                self.dir[a] = lv
        for a, (p, pin) in enumerate(STEP_PINS):
            if p == port and sets >> pin & 1 and not old >> pin & 1:
                d = 1 if self.dir[a] else -1
                self.pos[a] += d
                self.edges.append((t, ticks, a, d))
                if self.on_edge:
                    self.on_edge(a)
        if port == ENABLE_PIN[0] and (sets | resets) >> ENABLE_PIN[1] & 1:
            self.enable.append((t, ticks, new >> ENABLE_PIN[1] & 1))
        if port == "GPIOA":
            mask = self.valve_mask(new)
            if mask != self.mask:
                self.valves.append((t, ticks, mask))
                self.mask = mask

    def dump(self, path):
        with open(path, "w") as f:
            f.write("t_ns,tick,port,bsrr\n")
            for t, k, p, w in self.writes:
                f.write("%d,%d,%s,0x%08x\n" % (t, k, p, w))


# --------------------------------------------------------------------------------------
# Thumb helpers


def thumb32(emu, pc):
    half = int.from_bytes(emu.r.read(pc, 2), "little")
    return half >> 11 in (0b11101, 0b11110, 0b11111)


def skip_insn(emu, pc, regs, acc, size):
    """Moves PC past a load/store the harness did itself (with base writeback and the IT
    state advanced), as the CPU would have."""
    if acc is not None and acc.wb and not (acc.kind == "ld" and acc.base in acc.regs):
        emu.r.set_reg(acc.base, acc.written_back(regs))
    xpsr = regs[16]
    it = ((xpsr >> 25) & 3) | (((xpsr >> 10) & 0x3F) << 2)
    if it:
        it = 0 if it & 7 == 0 else (it & 0xE0) | ((it << 1) & 0x1F)
        xpsr = (xpsr & ~0x0600FC00) | ((it & 3) << 25) | ((it >> 2) << 10)
        emu.r.set_reg(16, xpsr)
    emu.r.set_reg(15, pc + size)


def it_condition_passes(regs):
    """Whether the instruction at PC executes (IT block condition), from xPSR."""
    xpsr = regs[16]
    it = ((xpsr >> 25) & 3) | (((xpsr >> 10) & 0x3F) << 2)
    if not it & 0xF:
        return True
    cond = it >> 4
    n, z, c, v = (xpsr >> 31) & 1, (xpsr >> 30) & 1, (xpsr >> 29) & 1, (xpsr >> 28) & 1
    base = cond >> 1
    r = [z == 1, c == 1, n == 1, v == 1, c == 1 and z == 0, n == v, n == v and z == 0, True][base]
    if cond & 1 and cond != 0xF:
        r = not r
    return r


CONDS = ("eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le")
DATA_OPS = ("mov", "mvn", "add", "sub", "and", "orr", "orn", "eor", "bic", "lsl", "lsr", "asr", "ror", "mul", "neg",
            "rsb", "ldr", "str", "ldrb", "strb", "ldrh", "strh", "ubfx", "uxtb", "uxth", "sxtb", "sxth", "cmp", "tst")


def thumb_expand_imm(imm12):
    if imm12 >> 10 == 0:
        b, kind = imm12 & 0xFF, (imm12 >> 8) & 3
        return [b, (b << 16) | b, (b << 24) | (b << 8), b * 0x01010101][kind]
    v = 0x80 | (imm12 & 0x7F)
    rot = imm12 >> 7
    return ((v >> rot) | (v << (32 - rot))) & 0xFFFFFFFF


def mov_w(rd, value, orig):
    """`mov.w rd, #value` (T2, flags as in `orig`, the instruction it replaces)."""
    imm12 = next((i for i in range(4096) if thumb_expand_imm(i) == value), None)
    if imm12 is None:
        raise FilError("0x%x is not a Thumb modified immediate" % value)
    hw1 = int.from_bytes(orig[:2], "little") & 0xFBF0 | ((imm12 >> 11) << 10) | 0x000F
    hw2 = (((imm12 >> 8) & 7) << 12) | (rd << 8) | (imm12 & 0xFF)
    return hw1.to_bytes(2, "little") + hw2.to_bytes(2, "little")


def flags_dead_after(image, pc):
    """True if the condition flags at pc are written before anything reads them, or the
    function returns first (a straight-line scan of the disassembly; gives up, False, at
    any other branch)."""
    for a in sorted(a for a in image.insns if pc < a < pc + 256):
        base = image.insns[a][0].split(".")[0]
        if base in ("cmp", "cmn", "tst", "teq"):
            return True
        if base.endswith("s") and base[:-1] in DATA_OPS:
            return True
        if base.startswith("it") or base.startswith("adc") or base.startswith("sbc") or base.startswith("rrx"):
            return False
        if base[:-2] in DATA_OPS + ("b",) and base[-2:] in CONDS:
            return False
        # A return (bx lr, or pop with pc): the AAPCS keeps no flags across a call, so
        # no caller reads the ones this function leaves.
        if base == "bx" and image.insns[a][1].strip() == "lr":
            return True
        if base == "pop" and "pc" in image.insns[a][1]:
            return True
        if base in ("b", "bl", "bx", "blx", "cbz", "cbnz", "pop", "tbb", "tbh"):
            return False
    return False


# --------------------------------------------------------------------------------------
# the harness around one emulated board


class Board:
    """One emulated board printing through the host tool: QEMU with UART4 on TCP, the
    pin log, the input and flash models, and the host-tool subprocesses."""

    def __init__(self, image, args, log_dir, label, machine):
        self.image, self.args, self.log_dir, self.label, self.m = image, args, log_dir, label, machine
        self.port = E.free_port()
        serial = ["null"] * UART4_SERIAL_INDEX + [
            "tcp:127.0.0.1:%d,server=on,wait=off,nodelay=on" % self.port]
        self.emu = E.boot(image, args, log_dir, label, serial=serial)
        if self.emu.boot_result != "control loop":
            raise FilError("boot did not reach the control loop (%s)" % self.emu.boot_result)
        self.emu.stop_at = E.FAULT_STOPS
        if args.usb_workaround:
            self.usb_workaround()
        self.log = PinLog(machine)
        self.log.on_edge = self.on_edge
        self.stops = 0
        self.ticks_at = image.sym("dollop_firmware::step::TICKS")
        self.hit = [False, False, False]
        self.estop = False
        self.sites = []
        self.flip_at = None  # store offset whose byte is flipped on its way into flash
        self.flipped = None
        self.store_writes = 0
        self.erased = []
        # Flash busy (issue 24): each erase start and program store with the outputs as
        # they stood then, and each data-cache reset (FLASH_ACR DCRST), for
        # check_outputs_safe_while_flash_busy.
        self.erase_starts = []  # (t, outputs safe)
        self.programs = 0
        self.programs_unsafe = []  # (t, pin state)
        self.dcrst = []  # t of each ACR write with DCRST set and DCEN clear
        self.exti_armed = False
        self.faults = []
        self.acc_cache = {}
        self.idr_reads = 0
        self.turn = {}
        self.stop_kinds = {}
        self.t_running = 0.0  # axis -> true position where homing turned back (the firmware's home)
        self.homing_hit = {}

    def on_watchdog_write(self, regname, value, t):
        """The watchdog is reconfigured (unlock, PR, RLR) around each flash erase. A feed
        from the control loop between the unlock and the RLR write would lock the
        registers again and drop the change without a word: at each PR write (after the
        unlock) the harness pends the control loop's interrupt and watches the key
        register until the RLR write. With the writes inside a critical section the
        control loop runs only after them; without, it feeds in between."""
        if regname == "PR":
            self.wdg_cfg.append(("PR", value, t))
            self.wdg_window = True
            self.emu.watch(IWDG_KR, 4, self.emu.on_model_access)
            self.emu.poke(NVIC_ISPR + 4 * (E.UART5_IRQ // 32), 1 << (E.UART5_IRQ % 32))
        elif regname == "RLR":
            self.wdg_cfg.append(("RLR", value, t))
            self.wdg_window = False
            self.emu.unwatch(IWDG_KR, 4)
        elif regname == "KR" and self.wdg_window and value == 0xAAAA:
            self.wdg_feeds_in_window += 1

    def usb_workaround(self):
        """The firmware's EitherPort (src/device/serve.rs) reads USB and the UART with
        `select(usb.read, uart.read)`; with no USB host, embassy's OUT endpoint read
        returns Disabled at once (DOEPCTL.USBAEP clear), so the select ends on USB's
        error every time and the UART's bytes are never read: the board never answers on
        its UART while no USB host has configured it. The firmware now listens only to
        open sides; for images from before that fix (--usb-workaround) the model reports
        the OUT endpoints active (USBAEP set), so USB's read waits instead."""
        chip = self.emu.chip
        plain = chip.read_word

        def read_word(addr):
            v = plain(addr)
            off = (addr & ~3) - 0x50000000
            if 0xB00 <= off < 0xB00 + 0x20 * 4 and off % 0x20 == 0:
                v |= 1 << 15
            return v

        chip.read_word = read_word

    # ---- clock ---------------------------------------------------------------------
    def now(self):
        """(virtual ns, step ticks) from the firmware's own tick count (step::TICKS, one
        read): the harness set TIM3's period to exactly 10 us of virtual time, so the tick
        count is virtual time at 10 us resolution."""
        ticks = self.emu.r.read32(self.ticks_at)
        return self.t_ref + ((ticks - self.k_ref) & 0xFFFFFFFF) * TICK_NS, ticks

    # ---- set-up ----------------------------------------------------------------------
    def setup(self):
        emu = self.emu
        t0 = emu.now()
        self.t_ref, self.k_ref = t0, emu.r.read32(self.ticks_at)
        # Erased flash in the job store (QEMU's ROM beyond the image is zeros).
        blank = b"\xff" * 1024
        for off in range(0, STORE_LEN, 1024):
            emu.r.write(STORE_BASE + off, blank)
        # During the run: GPIO writes only through BSRR watches; the watchdog's feeds (10
        # kHz) unwatched (QEMU's unimplemented block takes them); RCC, PWR, flash
        # interface and USB OTG still modelled (rare accesses, at start and on uploads).
        gpio = {p[0] for p in E.PERIPHERALS if p[0].startswith("GPIO")}
        emu.unwatch_model(gpio | {"IWDG", "DBGMCU"})
        self.find_input_sites()
        self.pend_uart_with_control()
        emu.unwatch(E.TIM3, 4)
        emu.unwatch(E.TIM3 + 0x14, 0x1C)
        for port, addr in BSRR.items():
            emu.watch(addr, 4, self.on_bsrr)
            self.log.level[port] = emu.chip.outputs.get(port, 0) & 0xFFFF
        self.log.mask = self.log.valve_mask()
        # The store: write watchpoint (reads of the job stay at full speed).
        emu.r.insert(2, STORE_BASE, STORE_LEN)
        emu.watches[(STORE_BASE, STORE_LEN)] = self.on_store
        emu.on_write_orig = emu.on_write
        emu.on_write = self.on_model_write
        # The watchdog's prescaler and reload (written only when it is reconfigured: around
        # each flash erase of an upload), for check_watchdog_around_erases.
        self.wdg_cfg = []
        self.wdg_window = False
        self.wdg_feeds_in_window = 0
        emu.watch(IWDG_PR, 8, emu.on_model_access)
        self.apply_inputs()
        emu.limit_warp(False)

    def pend_uart_with_control(self):
        """QEMU 7.2's stm32f2xx-usart raises its interrupt only for a received byte (RXNE),
        never for TXE/TC, so embassy's BufferedUart, which sends one byte per UART4
        interrupt with TXEIE set, would stall after its first byte. The step interrupt
        pends the control loop (UART5, NVIC ISPR1 bit 21) every 100 us; the harness widens
        that constant to pend UART4 (bit 20) too, so the UART interrupt runs every control
        period and sends the next byte: 10 kB/s of virtual time (the real UART: 100 kB/s)."""
        lo = self.image.sym("TIM3") & ~1
        hi = next(a for a, _ in self.image.functions if a > lo)
        want = 1 << (E.UART5_IRQ % 32)
        for a in sorted(x for x in self.image.insns if lo <= x < hi):
            mn, ops = self.image.insns[a]
            mm = re.match(r"r(\d+), #(0x[0-9a-f]+|\d+)$", ops)
            if mn == "mov.w" and mm and int(mm.group(2), 0) == want:
                orig = self.emu.r.read(a, 4)
                rd = int(mm.group(1))
                code = mov_w(rd, want | 1 << (UART4_IRQ % 32), orig)
                self.emu.r.write(a, code)
                self.uart_pend_site = self.image.function_at(a)
                return
        raise FilError("no `mov.w rN, #0x%x` (UART5's pend) in the TIM3 handler" % want)

    def find_input_sites(self):
        """The control loop's loads of GPIOC IDR: one control period with IDR watched."""
        emu = self.emu
        seen = []

        def on_idr(w, regs):
            pc = regs[15] & ~1
            acc, insn = self.image.access_at(pc)
            seen.append((pc, acc, insn))
            emu.step_over(pc, w)
            self.idr_reads += 1

        emu.watch(GPIOC_IDR, 4, on_idr)
        wall = time.monotonic() + 20
        while time.monotonic() < wall:
            why = emu.run(5.0, until=lambda: len(seen) >= 2 and seen[-1][0] in [s[0] for s in seen[:-1]])
            if why == "until" or why in E.FAULT_STOPS:
                break
        emu.unwatch(GPIOC_IDR, 4)
        if not seen or seen[-1][0] not in [s[0] for s in seen[:-1]]:
            raise FilError("no repeating GPIOC IDR reads found in the control loop (%d reads)" % len(seen))
        first = [s[0] for s in seen].index(seen[-1][0])
        for pc, acc, insn in seen[first:-1]:
            if acc is None or acc.kind != "ld" or acc.size != 4 or len(acc.regs) != 1 or acc.post or acc.wb:
                raise FilError("GPIOC IDR read at %s is not a plain ldr: %s" % (self.image.function_at(pc), insn))
            wide = thumb32(emu, pc)
            orig = emu.r.read(pc, 4 if wide else 2)
            # A 16-bit load whose flags are live after it has no flag-preserving 16-bit
            # replacement (movs and mvns set them): it stays a load, watched, and each read
            # gets the inputs written into its register (a debugger stop a control period).
            watched = not wide and not flags_dead_after(self.image, pc)
            self.sites.append(dict(pc=pc, rt=acc.regs[0], rn=acc.base, wide=wide, orig=orig, insn=insn,
                                   where=self.image.function_at(pc), watched=watched))
        if any(s["watched"] for s in self.sites):
            emu.watch(GPIOC_IDR, 4, self.on_idr_watched)

    def on_idr_watched(self, w, regs):
        """A watched IDR load: executed (QEMU reads 0), then its register set to the inputs."""
        pc = regs[15] & ~1
        self.emu.step_over(pc, w)
        site = next((s for s in self.sites if s["pc"] == pc), None)
        if site is not None:
            self.emu.r.set_reg(site["rt"], self.idr_value)
        self.idr_reads += 1
        return None

    def idr(self):
        v = 0
        for a, bit in enumerate(ENDSTOP_BITS):
            if not self.hit[a]:
                v |= 1 << bit
        if self.estop:
            v |= 1 << ESTOP_BIT
        return v

    def apply_inputs(self):
        v = self.idr()
        for s in self.sites:
            rt = s["rt"]
            if s["watched"]:
                continue
            if s["wide"]:
                hw1 = 0xF240 | (((v >> 11) & 1) << 10) | ((v >> 12) & 0xF)
                hw2 = (((v >> 8) & 7) << 12) | (rt << 8) | (v & 0xFF)
                code = hw1.to_bytes(2, "little") + hw2.to_bytes(2, "little")
            elif v < 256:
                code = (0x2000 | (rt << 8) | v).to_bytes(2, "little")  # movs rt, #v
            else:
                # mvns rt, rn: rn holds GPIOC's base; its complement has PC0..PC2 and PC13 set.
                want = ~GPIOC_BASE & 0xFFFFFFFF
                bits = [1 << b for b in ENDSTOP_BITS + [ESTOP_BIT]]
                if any((want & b) != (v & b) for b in bits):
                    raise FilError("no 16-bit encoding for IDR 0x%04x at %s" % (v, s["where"]))
                code = (0x43C0 | (s["rn"] << 3) | rt).to_bytes(2, "little")
            self.emu.r.write(s["pc"], code)
        self.idr_value = v

    # ---- handlers ----------------------------------------------------------------------
    def decode(self, pc):
        c = self.acc_cache.get(pc)
        if c is None:
            acc, insn = self.image.access_at(pc)
            c = (acc, insn, 4 if thumb32(self.emu, pc) else 2)
            self.acc_cache[pc] = c
        return c

    def on_bsrr(self, w, regs):
        pc = regs[15] & ~1
        acc, insn, size = self.decode(pc)
        if acc is None or acc.kind != "st":
            # A read or an odd instruction: let the CPU do it (QEMU reads 0).
            self.emu.step_over(pc, w)
            return None
        if not it_condition_passes(regs):
            skip_insn(self.emu, pc, regs, None, size)
            return pc + size
        t, ticks = self.now()
        for addr, sz, rn in acc.transfers(regs):
            port = next((p for p, a in BSRR.items() if a == (addr & ~3)), None)
            if port is None:
                continue
            value = (regs[rn] & ((1 << (8 * sz)) - 1)) << (8 * (addr & 3))
            self.log.bsrr(port, value, t, ticks)
            self.emu.chip.write(addr, sz, regs[rn] & ((1 << (8 * sz)) - 1))
        skip_insn(self.emu, pc, regs, acc, size)
        return pc + size

    def on_edge(self, a):
        if a >= 3:
            return
        pos = self.log.pos[a]
        lim = self.m.limit_steps[a]
        hit = pos >= lim if HOME_TO_MAX[a] else pos <= lim
        if a in self.homing_hit and a not in self.turn and self.log.dirs and self.log.dirs[-1][2] == a:
            pass
        if hit != self.hit[a]:
            self.hit[a] = hit
            if hit:
                self.homing_hit.setdefault(a, pos)
            self.apply_inputs()

    def on_store(self, w, regs):
        pc = regs[15] & ~1
        acc, insn, size = self.decode(pc)
        if acc is None or acc.kind != "st":
            raise FilError("unexpected access to the job store at %s: %s" % (self.image.function_at(pc), insn))
        for addr, sz, rn in acc.transfers(regs):
            data = bytearray((regs[rn] & ((1 << (8 * sz)) - 1)).to_bytes(sz, "little"))
            off = addr - STORE_BASE
            if self.flip_at is not None and off <= self.flip_at < off + sz and self.flipped is None:
                data[self.flip_at - off] ^= 0x01
                self.flipped = (self.flip_at, self.now()[0])
            self.programs += 1
            if not self.outputs_safe():
                self.programs_unsafe.append((self.now()[0], pin_state(self)))
            # Programming only clears bits, as on the chip.
            old = self.emu.r.read(addr, sz)
            self.emu.r.write(addr, bytes(o & d for o, d in zip(old, data)))
            self.store_writes += 1
        skip_insn(self.emu, pc, regs, acc, size)

    def on_model_write(self, periph, regname, value, t):
        self.emu.on_write_orig(periph, regname, value, t)
        if periph == "IWDG":
            self.on_watchdog_write(regname, value, t)
        if periph == "FLASH" and regname == "ACR" and value & ACR_DCRST and not value & ACR_DCEN:
            self.dcrst.append(t)
        if periph == "FLASH" and regname == "CR":
            # The value written: the model clears STRT at once (the erase is done).
            cr = value
            if cr & (1 << 16) and cr & 2:
                self.erase_starts.append((t, self.outputs_safe()))
                snb = (cr >> 3) & 0xF
                if snb >= 5:
                    base = 0x08020000 + (snb - 5) * SECTOR
                    if STORE_BASE <= base < STORE_BASE + STORE_LEN:
                        blank = b"\xff" * 1024
                        for off in range(0, SECTOR, 1024):
                            self.emu.r.write(base + off, blank)
                        self.erased.append(snb)

    def outputs_safe(self):
        """Every valve low and the drivers disabled (PB15 high), from the pin log."""
        return self.log.valve_mask() == 0 and self.log.level["GPIOB"] >> 15 & 1 == 1

    def on_exti(self, w, regs):
        """EXTI_PR read by the e-stop handler: line 13 pending while the e-stop is asserted."""
        pc = regs[15] & ~1
        acc, insn, size = self.decode(pc)
        if acc is not None and acc.kind == "ld" and self.exti_armed:
            self.emu.step_over(pc, w)
            for addr, sz, rn in acc.transfers(regs):
                if addr & ~3 == EXTI_PR:
                    self.emu.r.set_reg(rn, 1 << ESTOP_BIT)
            self.exti_armed = False
        else:
            self.emu.step_over(pc, w)

    # ---- running -------------------------------------------------------------------
    def run(self, wall_s, until=None, poll=0.25):
        """Runs the board until `until()` (checked at least every `poll` s of wall time),
        a fault stop, or wall_s. Returns the reason."""
        emu = self.emu
        deadline = time.monotonic() + wall_s
        pc = emu.r.regs()[15] & ~1
        while True:
            if pc in emu.bps:
                emu.step_over(pc)
            emu.r.cont()
            w0 = time.monotonic()
            stop = emu.r.wait(min(deadline, time.monotonic() + poll))
            self.t_running += time.monotonic() - w0
            if stop.exited:
                raise E.TargetGone("QEMU exited: %s" % stop.text)
            self.stops += 1
            regs = emu.r.regs()
            if E.DEBUG:
                key = (hex(stop.watch[1]) if stop.watch else stop.text[:3], self.image.function_at(regs[15]))
                self.stop_kinds[key] = self.stop_kinds.get(key, 0) + 1
            if stop.watch:
                w = emu.watch_for(stop.watch[1])
                if w is None:
                    raise FilError("unknown watchpoint stop %r" % stop)
                newpc = emu.watches[w](w, regs)
                pc = newpc if newpc is not None else emu.r.regs()[15] & ~1
                if until and until():
                    return "until"
                if time.monotonic() > deadline:
                    return "wall"
                continue
            pc = regs[15] & ~1
            if regs[15] & ~1 in emu.bps:
                name = emu.bps[regs[15] & ~1]
                t = emu.now()
                emu.bp_hits.append((name, t, regs[15], regs[14]))
                if name in ("HardFault", "DefaultHandler"):
                    emu.fault_info = emu.describe_fault(regs)
                self.faults.append((name, t, getattr(emu, "fault_info", "")))
                if name in emu.stop_at:
                    return name
            elif stop.signal in (2, 5):
                pass
            else:
                raise FilError("unexpected stop %r at 0x%08x" % (stop, regs[15]))
            if until and until():
                return "until"
            if time.monotonic() > deadline:
                return "wall"

    def pend_estop(self):
        """E-stop asserted: PC13 high in the input model, EXTI line 13 pending, EXTI15_10
        pended in the NVIC."""
        self.estop = True
        self.apply_inputs()
        if (EXTI_PR, 4) not in self.emu.watches:
            self.emu.watch(EXTI_PR, 4, self.on_exti)
        self.exti_armed = True
        t, _ = self.now()
        self.emu.poke(NVIC_ISPR + 4 * (EXTI15_10_IRQ // 32), 1 << (EXTI15_10_IRQ % 32))
        return t

    def release_estop(self):
        self.estop = False
        self.apply_inputs()

    def kill(self):
        self.emu.kill()


# --------------------------------------------------------------------------------------
# the host tool


class Host:
    """One `dollop` subprocess against the board's TCP port."""

    def __init__(self, args, board, words, label):
        self.label = label
        self.cmd = [args.dollop] + words + ["--port", "tcp:127.0.0.1:%d" % board.port]
        self.out_path = os.path.join(board.log_dir, "host-%s-%s.log" % (board.label, label))
        self.out = open(self.out_path, "w")
        self.t_start = time.monotonic()
        self.p = subprocess.Popen(self.cmd, stdout=self.out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                  preexec_fn=E.die_with_parent)
        HOSTS.append(self)

    def done(self):
        return self.p.poll() is not None

    def text(self):
        if not self.out.closed:
            self.out.flush()
        with open(self.out_path, errors="replace") as f:
            return f.read()

    def kill(self, sig=None):
        if self.p.poll() is None:
            if sig is None:
                self.p.kill()
            else:
                self.p.send_signal(sig)
        try:
            self.p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.p.wait()
        if not self.out.closed:
            self.out.close()


def kill_hosts():
    for h in HOSTS:
        try:
            h.kill()
        except OSError:
            pass


def host(board, words, label, until_extra=None, wall=None):
    """Runs a host command to its end while the board runs. Returns (Host, reason)."""
    h = Host(board.args, board, words, label)
    limit = wall or board.args.host_wall
    why = board.run(limit, until=lambda: h.done() or (until_extra is not None and until_extra()))
    if why == "until" and h.done():
        h.kill()
        return h, "exit %d" % h.p.returncode
    return h, why


# --------------------------------------------------------------------------------------
# the simulator


def simulate(args, job, config, log_dir, label, extra=()):
    trace = os.path.join(log_dir, "sim-%s.csv" % label)
    r = subprocess.run([args.dollop, "simulate", job, "--config", config, "--model-only", "--trace", trace]
                       + list(extra), capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise FilError("dollop simulate failed: %s" % (r.stderr.strip() or r.stdout.strip()))
    rows = []
    with open(trace) as f:
        rd = csv.reader(f)
        next(rd)
        for row in rd:
            rows.append((float(row[0]), float(row[1]), float(row[2]), float(row[3]), int(row[4])))
    return rows


CONTROL_S = 1e-4  # the control period
REPLAY_TRIES = 6  # simulator runs to place a replayed pause (one or two usually do)


def replay_pause(args, log_dir, board, rows, t_after_ns, job=None):
    """The simulator's run with the board's pause replayed: the board's first all-shut
    valve change after t_after_ns is the pause's, the next change its resume. The request
    and resume times for `dollop simulate --pause-at/--resume-at` are found by matching
    those two pin changes in job time: a guess a control period early, then corrections,
    up to REPLAY_TRIES runs, keeping the closest. Where the pause's close lands depends on
    the request in steps (the bead's tail is placed by volume), so a correction can
    overshoot; the residual is returned so that a compare's worst offset can be read
    against it. Returns (rows, (close index, figures)) or raises FilError; figures are
    (t_close, t_reopen, request, (close residual ms, reopen residual ms, runs))."""
    brd = board_changes(board)
    sim0 = sim_changes(rows)
    if not brd or not sim0:
        raise FilError("no valve changes to place the pause by")
    origin = brd[0][0] - sim0[0][0] * 1e9
    ic = next((i for i, c in enumerate(brd) if c[0] >= t_after_ns and c[2] == 0), None)
    if ic is None or ic + 1 >= len(brd):
        raise FilError("the board's pause (valves shut, then reopened) is not in the pin log")
    t_close = (brd[ic][0] - origin) / 1e9
    t_reopen = (brd[ic + 1][0] - origin) / 1e9
    req, res = t_close - CONTROL_S, t_reopen - CONTROL_S
    best = None
    for k in range(REPLAY_TRIES):
        prow = simulate(args, job or args.job, args.config, log_dir, "paused-%d" % k,
                        ["--pause-at", "%.6f" % req, "--resume-at", "%.6f" % res])
        sc = sim_changes(prow)
        jc = next((i for i, c in enumerate(sc) if c[0] >= req - 1e-9 and c[1] == 0), None)
        if jc is None or jc + 1 >= len(sc):
            raise FilError("the simulator's replayed pause shows no close and reopen")
        d_close, d_open = t_close - sc[jc][0], t_reopen - sc[jc + 1][0]
        miss = max(abs(d_close), abs(d_open))
        if best is None or miss < best[0]:
            best = (miss, prow, req, d_close, d_open)
        if miss < 0.5 * CONTROL_S:
            break
        req += d_close
        res += d_open
    miss, prow, req, d_close, d_open = best
    return prow, (ic, t_close, t_reopen, req, (d_close * 1e3, d_open * 1e3, k + 1))


def replay_words(residual):
    """The replay's residual in words, for a check's line."""
    dc, do, runs = residual
    return "replayed pause matched to %.3f ms (close) and %.3f ms (reopen) in %d simulator run%s" % (
        abs(dc), abs(do), runs, "" if runs == 1 else "s")


def sim_changes(rows):
    """[(t_s, mask, (x, y, z) mm)] at every valve change (from all closed before t = 0)."""
    out, last = [], 0
    for t, x, y, z, mask in rows:
        if mask != last:
            out.append((t, mask, (x, y, z)))
            last = mask
    return out


# --------------------------------------------------------------------------------------
# comparison


def homing_offsets(board):
    """Per axis X/Y/Z: the firmware's position minus the true one after homing. The
    firmware sets its count to the endstop's position in the control period that first
    reads the endstop, after every step it had asked for so far; those end in the next
    step period, where the axis then turns back (DIR). So the true position at that turn
    is the firmware's home."""
    log, m = board.log, board.m
    off = [0] * 7
    notes = []
    for a in range(3):
        hit_i = None
        pos = m.start_steps[a]
        turned = None
        for i, (t, k, ax, d) in enumerate(log.edges):
            if ax != a:
                continue
            want = 1 if HOME_TO_MAX[a] else -1
            if hit_i is None:
                pos += d
                reached = pos >= m.limit_steps[a] if HOME_TO_MAX[a] else pos <= m.limit_steps[a]
                if reached:
                    hit_i = i
                continue
            if d != want:
                turned = pos
                break
            pos += d
        if turned is None:
            notes.append("%s never reached its endstop and turned back" % AXES[a])
            continue
        off[a] = m.home_steps(a) - turned
    return off, notes


def board_positions_at(board, off, tick_cut):
    """Firmware positions (steps) of X, Y, Z after every STEP edge before tick_cut."""
    pos = list(board.m.start_steps[:3])
    for t, k, a, d in board.log.edges:
        if k >= tick_cut:
            break
        if a < 3:
            pos[a] += d
    return [pos[a] + off[a] for a in range(3)]


def compare(board, rows, t_from_ns=0, pieces=None):
    """The checks of a print against the simulator. Returns (ok, lines, summary)."""
    log, m = board.log, board.m
    off, notes = homing_offsets(board)
    lines = list(notes)
    sim = sim_changes(rows)
    brd = board_changes(board, t_from_ns)
    ok = not notes
    if [c[1] for c in sim] != [b[2] for b in brd]:
        ok = False
        lines.append("valve sequence differs: board %d changes %s..., simulator %d changes %s..." % (
            len(brd), [b[2] for b in brd][:12], len(sim), [c[1] for c in sim][:12]))
    n = min(len(sim), len(brd))
    # Time origin: the job's first command starts in the control period after the lead-in
    # ends; the simulator's t = 0 is that command's first period. The board's first valve
    # change and the simulator's first change are both in the job's first command, so the
    # origin is placed by that pair (t_board0 - t_sim0), then every later change is
    # checked against it; a pause (pieces) restarts the origin at the first change after
    # each resume.
    worst_t, worst_steps = 0.0, 0
    origin = None
    starts = set(pieces or [])
    bad_t, bad_s = [], []
    for i in range(n):
        ts, mask, mm = sim[i]
        tb, kb, _ = brd[i]
        if origin is None or i in starts:
            origin = tb - ts * 1e9
        dt_ms = (tb - ts * 1e9 - origin) / 1e6
        if abs(dt_ms) > abs(worst_t):
            worst_t = dt_ms
        if abs(dt_ms) > 1.0:
            bad_t.append((i, dt_ms))
        # Steps the firmware asked for up to this control period end one step period later.
        period = (kb - 1) // PERIOD_TICKS
        cut = (period + 2) * PERIOD_TICKS + 1
        bpos = board_positions_at(board, off, cut)
        for a in range(3):
            want = round(mm[a] * m.spm[a])
            d = bpos[a] - want
            if abs(d) > abs(worst_steps):
                worst_steps = d
            if abs(d) > 1:
                bad_s.append((i, AXES[a], bpos[a], want))
    if bad_t:
        ok = False
        lines.append("%d valve changes off by more than 1 ms: %s" % (len(bad_t), ", ".join(
            "#%d %+.3f ms" % x for x in bad_t[:6])))
    if bad_s:
        ok = False
        lines.append("%d axis positions at valve changes off by more than 1 step: %s" % (len(bad_s), ", ".join(
            "#%d %s board %d sim %d" % x for x in bad_s[:6])))
    final_b = board_positions_at(board, off, 1 << 62)
    final_s = [round(rows[-1][1 + a] * m.spm[a]) for a in range(3)]
    steps_equal = final_b == final_s
    if not steps_equal:
        ok = False
        lines.append("final steps differ: board %s, simulator %s" % (final_b, final_s))
    summary = dict(changes=n, worst_ms=worst_t, worst_steps=worst_steps, final=final_b, steps_equal=steps_equal,
                   offsets=off)
    return ok, lines, summary


def board_changes(board, t_from=0, t_to=None):
    """The board's valve changes, one per control period (a switch that opens one valve
    and closes another in the same period is one change, as in the simulator's trace)."""
    out, last = [], None
    prev_mask = 0
    for t, k, mask in board.log.valves:
        if t < t_from:
            prev_mask = mask
            continue
        if t_to is not None and t >= t_to:
            break
        period = (k - 1) // PERIOD_TICKS
        if out and out[-1][3] == period:
            out[-1] = (out[-1][0], out[-1][1], mask, period)
        else:
            out.append((t, k, mask, period))
    res = []
    for t, k, mask, _ in out:
        if mask != (res[-1][2] if res else prev_mask):
            res.append((t, k, mask))
    return res


# --------------------------------------------------------------------------------------
# scenarios


def new_board(image, args, log_dir, label, machine, boards):
    b = Board(image, args, log_dir, label, machine)
    boards.append(b)
    b.setup()
    return b


def run_host(board, words, label, wall, until_extra=None):
    h = Host(board.args, board, words, label)
    why = board.run(wall, until=lambda: h.done() or (until_extra is not None and until_extra()))
    return h, why


def virtual_wait(board, seconds, wall):
    t0 = board.now()[0]
    return board.run(wall, until=lambda: board.now()[0] - t0 >= seconds * 1e9, poll=0.1)


def pin_state(board):
    lv = board.log.level
    return "valves %s, drivers %s" % ("".join(str(lv["GPIOA"] >> i & 1) for i in range(4)),
                                      "disabled" if lv["GPIOB"] >> 15 & 1 else "ENABLED")


def safe_by(board, after):
    """When, after `after`, the valves were all low and the drivers disabled (both, from
    the pin log), or None."""
    t_valves = t_enable = None
    mask = None
    en = None
    for t, k, port, word in board.log.writes:
        if t < after:
            continue
    # Replay levels up to each write after `after`.
    level = {"GPIOA": 0, "GPIOB": 0, "GPIOC": 0}
    for t, k, port, word in board.log.writes:
        sets = word & 0xFFFF
        resets = (word >> 16) & ~sets
        level[port] = (level[port] | sets) & ~resets & 0xFFFF
        if t < after:
            continue
        if t_valves is None and level["GPIOA"] & 0xF == 0:
            t_valves = t
        if t_enable is None and level["GPIOB"] >> 15 & 1:
            t_enable = t
    if t_valves is None or t_enable is None:
        return None
    # Already safe before `after`: the first write after it that finds them safe.
    return max(t_valves, t_enable)


def opened_after(board, after):
    """Writes after `after` that opened a valve or enabled the drivers, and STEP edges."""
    opens = [(t, port, w) for t, k, port, w in board.log.writes if t > after and (
        (port == "GPIOA" and w & 0xF) or (port == "GPIOB" and w >> (16 + 15) & 1))]
    steps = [e for e in board.log.edges if e[0] > after]
    return opens, steps


def scenario_print(image, args, log_dir, machine, boards, rows):
    """The whole job: send, home, print to the end, compare."""
    b = new_board(image, args, log_dir, "print", machine, boards)
    w0, v0 = time.monotonic(), b.now()[0]
    h, why = run_host(b, ["send", args.job, "--config", args.config], "send", args.job_wall)
    out = h.text()
    h.kill()
    res = dict(board=b, why=why, host=out, exit=h.p.returncode, wall=time.monotonic() - w0,
               virtual=(b.now()[0] - v0) / 1e9, stops=b.stops, running=b.t_running)
    ok, lines, summ = compare(b, rows)
    res.update(ok=ok, lines=lines, summary=summ)
    return res


def check_print(res):
    out = []
    b = res["board"]
    done = res["exit"] == 0 and "done in" in res["host"]
    out.append(("job sent, homed, printed, Done over the link", done,
                "dollop send exit %s (%s); %.1f s virtual in %.1f s wall (%.1f s of it QEMU running), %d stops "
                "(%.0f/s), %d STEP edges" % (
                    res["exit"], last_line(res["host"]), res["virtual"], res["wall"], res["running"], res["stops"],
                    res["stops"] / max(res["wall"], 1e-9), len(b.log.edges))))
    return out + check_printed(res, res["host"])


def check_printed(res, host_text):
    """The checks every whole print makes of the board, whoever drove it (`dollop send` or
    the dashboard): no fault stop and no Late/Underrun in what the host said
    (`host_text`), the watchdog around the upload's erases, and the pins against the
    simulator (`compare`'s result in res)."""
    b = res["board"]
    out = [("no fault, Late or Underrun", not b.faults and "Underrun" not in host_text and "Late" not in host_text,
            "; ".join("%s at %.3f s: %s" % (f[0], f[1] / 1e9, f[2]) for f in b.faults)
            or "none (halt reasons come over the link)")]
    out.append(check_watchdog_around_erases(b))
    out.append(check_outputs_safe_while_flash_busy(b))
    s = res["summary"]
    out.append(("pins match the simulator", res["ok"],
                "%d valve changes, worst offset %.3f ms, worst axis %+d steps at a change, final X/Y/Z %s steps%s" % (
                    s["changes"], s["worst_ms"], s["worst_steps"], s["final"],
                    "; " + "; ".join(res["lines"]) if res["lines"] else "")))
    return out


def summary_line(label, s):
    """The run's last line for a print that passed: "firmware in the loop[ (label)]: N valve
    changes, worst offset X ms, steps equal"."""
    return "firmware in the loop%s: %d valve changes, worst offset %.3f ms, steps %s" % (
        " (%s)" % label if label else "", s["changes"], abs(s["worst_ms"]), "equal" if s["steps_equal"] else "DIFFER")


def check_watchdog_around_erases(b):
    """The upload's erase ran under the long timeout (PR /256, RLR 1500: 8.2 s at LSI's
    fastest) and the normal one came back after (PR /32, RLR 250), and no feed landed
    between an unlock and its reload write although the control loop was pended there."""
    cfg = b.wdg_cfg
    pairs = [(cfg[i][1], cfg[i + 1][1]) for i in range(len(cfg) - 1) if cfg[i][0] == "PR" and cfg[i + 1][0] == "RLR"]
    long_then_normal = any(p == (6, 1500) for p in pairs) and pairs[-1:] == [(3, 250)]
    ok = long_then_normal and b.wdg_feeds_in_window == 0
    return ("watchdog around flash erases", ok,
            "%d reconfigurations (PR, RLR): %s; control loop pended after each unlock: %d feed(s) "
            "between an unlock and its reload write" % (
                len(pairs), ", ".join("(%d, %d)" % p for p in pairs) or "none", b.wdg_feeds_in_window))


def check_outputs_safe_while_flash_busy(b):
    """While the flash erases or programs it stalls every fetch from it, the e-stop's
    handler included (RM0090 3.5), so the firmware forces the outputs safe first: every
    erase start (FLASH_CR SER+STRT) and every program store into the job store must find
    the valves low and the drivers disabled, and each erase must be followed by a
    data-cache reset (FLASH_ACR DCRST with DCEN clear, RM0090 3.5.2) before the next
    erase or the end of the run."""
    unsafe_erases = [t for t, safe in b.erase_starts if not safe]
    starts = [t for t, _ in b.erase_starts]
    uncleared = [t for i, t in enumerate(starts)
                 if not any(t < d < (starts[i + 1] if i + 1 < len(starts) else float("inf")) for d in b.dcrst)]
    ok = bool(starts) and b.programs > 0 and not unsafe_erases and not b.programs_unsafe and not uncleared
    fig = "%d erase(s), %d program store(s): outputs safe at %s; data cache reset after %d of %d erase(s)" % (
        len(starts), b.programs,
        "every one" if not unsafe_erases and not b.programs_unsafe else
        "NOT: erases at %s ms, programs %s" % (
            ", ".join("%.3f" % (t / 1e6) for t in unsafe_erases),
            "; ".join("%.3f ms (%s)" % (t / 1e6, st) for t, st in b.programs_unsafe[:3])),
        len(starts) - len(uncleared), len(starts))
    return ("outputs safe while the flash is busy", ok, fig)


def last_line(text):
    lines = [l.strip() for l in text.replace("\r", "\n").splitlines() if l.strip()]
    return lines[-1][:160] if lines else "no output"


def mid_print(board, changes):
    return lambda: len(board.log.valves) >= changes


def scenario_pause(image, args, log_dir, machine, boards, rows):
    b = new_board(image, args, log_dir, "pause", machine, boards)
    h, why = run_host(b, ["send", args.job, "--config", args.config], "send", args.job_wall,
                      until_extra=mid_print(b, args.fault_after))
    t_pause = b.now()[0]
    h.p.send_signal(signal.SIGINT)  # Ctrl-C: send asks the board to pause, then exits
    b.run(60, until=lambda: h.done())
    sent = h.text()
    h.kill()
    virtual_wait(b, 0.5, 60)  # the head stops mid-bead at the pause point, then the board holds
    t_hold = b.now()[0]
    virtual_wait(b, 0.25, 60)
    held_opens, held_steps = opened_after(b, t_hold)
    held_opens = [o for o in held_opens if o[0] >= t_hold]
    r, why = run_host(b, ["resume"], "resume", args.job_wall)
    resumed = r.text()
    r.kill()
    # The pause is mid-bead: the simulator replays it (dollop simulate --pause-at/--resume-at
    # at the board's pin times) and every valve change and step, before and after, is
    # compared with one time origin.
    try:
        prow, (ic, t_close, t_reopen, t_req, residual) = replay_pause(args, log_dir, b, rows, t_pause)
    except FilError as e:
        return [("pause then resume mid-print", False, "Ctrl-C to send at %.3f s: %s; %s" % (
            t_pause / 1e9, last_line(sent), e))]
    ok, lines, summ = compare(b, prow)
    brd = board_changes(b)
    off, _ = homing_offsets(b)
    at = [board_positions_at(b, off, brd[i][1]) for i in (ic, ic + 1)]
    moved_mm = math.sqrt(sum(((at[1][a] - at[0][a]) / machine.spm[a]) ** 2 for a in range(2)))
    # Mid-bead: the head did not travel between the pause's close and the resume's reopen,
    # and the bead's valve was open before the close.
    mid_bead = moved_mm <= PAUSE_TAIL_MM and ic > 0 and brd[ic - 1][2] != 0
    fine = ("pausing" in sent and r.p.returncode == 0 and "done in" in resumed and ok and not held_opens
            and not held_steps and mid_bead)
    return [("pause then resume mid-print", fine,
             "Ctrl-C to send at %.3f s (after %d valve changes): %s; valves shut at %.4f s (job time), %s; "
             "head moved %.3f mm from the close to the reopen (%s); held %.2f s with %d valve-open writes and %d "
             "steps; resume: %s; reopened at %.4f s; against the simulator with the same pause (requested at "
             "%.4f s; %s): %d changes, worst offset %.3f ms, final %s%s" % (
                 t_pause / 1e9, args.fault_after, last_line(sent), t_close, "mid-bead" if mid_bead else "NOT mid-bead",
                 moved_mm, "tail" if moved_mm <= PAUSE_TAIL_MM else "a travel", 0.25, len(held_opens),
                 len(held_steps), last_line(resumed), t_reopen, t_req, replay_words(residual), summ["changes"],
                 summ["worst_ms"],
                 summ["final"], "; " + "; ".join(lines) if lines else ""))]


def scenario_abort(image, args, log_dir, machine, boards):
    b = new_board(image, args, log_dir, "abort", machine, boards)
    h, why = run_host(b, ["send", args.job, "--config", args.config], "send", args.job_wall,
                      until_extra=mid_print(b, args.fault_after))
    h.kill()  # the host goes; `dollop abort` comes in before the link-loss timeout
    t0 = b.now()[0]
    a, why = run_host(b, ["abort"], "abort", 60)
    text = a.text()
    a.kill()
    t1 = b.now()[0]
    virtual_wait(b, 0.2, 60)
    safe = safe_by(b, t0)
    opens, steps = opened_after(b, (safe or t1) + 0.0002e9)
    ok = a.p.returncode == 0 and safe is not None and safe <= t1 and not opens and not steps
    return [("abort mid-print", ok, "send killed at %.3f s, `dollop abort`: %s; valves low and drivers disabled at "
             "%.3f s; afterwards %d opening writes, %d steps; now %s" % (
                 t0 / 1e9, last_line(text), (safe or 0) / 1e9, len(opens), len(steps), pin_state(b)))]


def scenario_link_cut(image, args, log_dir, machine, boards):
    b = new_board(image, args, log_dir, "link-cut", machine, boards)
    # At the print's first valve write: the link timeout (3 s) must run out before the job ends.
    h, why = run_host(b, ["send", args.job, "--config", args.config, "--on-link-loss", "stop"], "send",
                      args.job_wall, until_extra=mid_print(b, 1))
    h.kill()  # SIGKILL: the host vanishes without a word
    t0 = b.now()[0]
    virtual_wait(b, 3.4, 120)
    safe = safe_by(b, t0)
    opens, steps = opened_after(b, (safe or t0) + 0.0002e9)
    delay = (safe - t0) / 1e9 if safe else None
    ok = safe is not None and 2.9 <= delay <= 3.3 and not opens and not steps
    return [("host link cut mid-print (--on-link-loss stop)", ok,
             "host killed at %.3f s; valves low and drivers disabled %s later (link timeout 3 s); afterwards %d "
             "opening writes, %d steps; now %s" % (t0 / 1e9, "%.3f s" % delay if delay else "NEVER", len(opens),
                                                   len(steps), pin_state(b)))]


def scenario_estop(image, args, log_dir, machine, boards):
    b = new_board(image, args, log_dir, "estop", machine, boards)
    h, why = run_host(b, ["send", args.job, "--config", args.config], "send", args.job_wall,
                      until_extra=mid_print(b, args.fault_after))
    before = pin_state(b)
    t0 = b.pend_estop()
    virtual_wait(b, 0.05, 60)
    safe = safe_by(b, t0)
    b.release_estop()
    t_rel = b.now()[0]
    virtual_wait(b, 0.2, 60)
    opens, steps = opened_after(b, (safe or t0) + 0.0002e9)
    b.run(30, until=lambda: h.done())
    sent = h.text()
    h.kill()
    s, _ = run_host(b, ["status"], "status", 30)
    st = s.text()
    s.kill()
    a, _ = run_host(b, ["abort"], "abort", 30)
    ab = a.text()
    a.kill()
    s2, _ = run_host(b, ["status"], "status2", 30)
    st2 = s2.text()
    s2.kill()
    within = safe is not None and safe - t0 <= 100_000
    latched = "halted" in st and not opens and not steps
    cleared = "halt cleared" in ab and "halted" not in st2
    ok = within and latched and cleared
    return [("e-stop mid-print: safe within a control cycle, latched", ok,
             "%s when PC13 went high (EXTI13 pended) at %.4f s; valves low and drivers disabled %s later; input "
             "released at %.4f s, then %d opening writes and %d steps in 0.2 s; send: %s; status: %s; abort: %s; "
             "then: %s" % (before, t0 / 1e9, "%.1f us" % ((safe - t0) / 1e3) if safe else "NEVER", t_rel / 1e9,
                           len(opens), len(steps), last_line(sent), first_match(st, "halted"), last_line(ab),
                           first_match(st2, "mode")))]


def first_match(text, word):
    for l in text.splitlines():
        if word in l:
            return l.strip()
    return last_line(text)


def scenario_flipped(image, args, log_dir, machine, boards):
    b = new_board(image, args, log_dir, "flipped", machine, boards)
    with open(args.job, "rb") as f:
        data = f.read()
    b.flip_at = min(40, len(data) // 2)  # a byte of the body, in the store
    h, why = run_host(b, ["send", args.job, "--config", args.config], "send", 120)
    text = h.text()
    h.kill()
    opens, steps = opened_after(b, 0)
    enabled = [e for e in b.log.enable if e[2] == 0]
    refused = h.p.returncode != 0 and b.flipped is not None
    ok = refused and not opens and not steps and not enabled
    return [("job with a flipped byte refused before anything moves", ok,
             "byte %s of the body flipped on its way into flash; dollop send exit %s: %s; %d valve-open writes, "
             "%d steps, drivers enabled %d times" % (
                 b.flipped[0] if b.flipped else "NOT", h.p.returncode, last_line(text), len(opens), len(steps),
                 len(enabled)))]


# QEMU 7.2's own assertion, hit now and then by -icount with debugger watchpoints at a
# watched store: the emulator stops, not the firmware.
QEMU_ICOUNT_ABORT = "Raised interrupt while not in I/O function"


def qemu_aborted(boards):
    """True when a board's QEMU stopped on its own icount assertion."""
    for b in boards:
        try:
            b.emu.qemu_log.flush()
            with open(b.emu.qemu_log.name) as f:
                if QEMU_ICOUNT_ABORT in f.read():
                    return True
        except (OSError, ValueError):
            pass
    return False


def passed(out):
    """Every (name, ok, figure) check of a scenario passed."""
    return all(ok for _, ok, _ in out)


def once_more_if_qemu_aborted(name, boards, attempt, failed=lambda r: False):
    """Runs `attempt()`; if it raised or `failed(result)` because QEMU aborted on its own
    assertion (not anything the firmware did), says so and runs it once more. A second
    such abort, or any other failure, stands."""
    try:
        r = attempt()
        if not (failed(r) and qemu_aborted(boards)):
            return r
    except (FilError, E.TargetGone, RuntimeError, OSError):
        if not qemu_aborted(boards):
            raise
    print("emulate: %s: QEMU itself aborted (\"%s\"), not the firmware: running it once more"
          % (name, QEMU_ICOUNT_ABORT), file=sys.stderr, flush=True)
    finish(boards)
    return attempt()


def run(image, args, log_dir, results):
    """Firmware in the loop: the print and the fault scenarios. Appends (name, ok, figure)."""
    machine = Machine(args.config, args.inset_mm)
    boards = []
    summaries = []
    try:
        rows = simulate(args, args.job, args.config, log_dir, "job")
        which = args.fil
        if "print" in which:
            res = once_more_if_qemu_aborted(
                "print", boards, lambda: scenario_print(image, args, log_dir, machine, boards, rows),
                failed=lambda r: not r["ok"])
            out = check_print(res)
            results.extend(out)
            if passed(out):
                summaries.append(summary_line("", res["summary"]))
            finish(boards)
        if "serve" in which:
            # The dashboard drives the board (emulator/serve.py); the same checks of the pins.
            from emulator import serve
            w0 = time.monotonic()
            try:
                out, summ = once_more_if_qemu_aborted(
                    "serve", boards, lambda: serve.scenario_serve(image, args, log_dir, machine, boards, rows),
                    failed=lambda r: not passed(r[0]))
            except (FilError, E.TargetGone, RuntimeError, OSError) as e:
                out, summ = [("dashboard drives the board", False, "error: %s" % e)], None
            results.extend((n, ok, fig + " [%.0f s wall]" % (time.monotonic() - w0)) for n, ok, fig in out)
            if summ is not None and passed(out):
                summaries.append(summary_line("dashboard", summ))
            finish(boards)
        for name, fn in (("pause", lambda: scenario_pause(image, args, log_dir, machine, boards, rows)),
                         ("abort", lambda: scenario_abort(image, args, log_dir, machine, boards)),
                         ("link-cut", lambda: scenario_link_cut(image, args, log_dir, machine, boards)),
                         ("estop", lambda: scenario_estop(image, args, log_dir, machine, boards)),
                         ("flipped", lambda: scenario_flipped(image, args, log_dir, machine, boards))):
            if name in which:
                w0 = time.monotonic()
                try:
                    out = once_more_if_qemu_aborted(name, boards, fn, failed=lambda r: not passed(r))
                except (FilError, E.TargetGone, RuntimeError, OSError) as e:
                    out = [(name, False, "error: %s" % e)]
                results.extend((n, ok, fig + " [%.0f s wall]" % (time.monotonic() - w0)) for n, ok, fig in out)
                finish(boards)
    except FilError as e:
        results.append(("firmware in the loop", False, str(e)))
    finally:
        kill_hosts()
        finish(boards)
    return "\n".join(summaries) or None


def finish(boards):
    while boards:
        b = boards.pop()
        try:
            b.log.dump(os.path.join(b.log_dir, "pins-%s.csv" % b.label))
            b.emu.log.dump(os.path.join(b.log_dir, "writes-%s.csv" % b.label))
        except OSError:
            pass
        b.kill()
        kill_hosts()
