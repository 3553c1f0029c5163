#!/usr/bin/env python3
"""dollop's firmware in an emulator: the release image on QEMU's netduinoplus2 (an
STM32F405), driven over QEMU's gdb remote-protocol stub, with the peripherals QEMU does not
model (RCC, Flash interface, PWR, GPIO, IWDG, USB OTG FS, DBGMCU) supplied by a register
model in this script. Everything asserted comes from what the emulated chip did: the
register writes it made (each with its virtual time), the counters in its RAM, the stack it
used. `scripts/emulate` is the entry point; `--help` lists the options.

Layout, so later work can extend one part without touching the others:
  Remote      the gdb remote serial protocol (packets, registers, memory, watchpoints)
  Image       the ELF: symbols (llvm-nm) and the decoded loads/stores (llvm-objdump)
  Chip        the register model of the unmodelled peripherals: read values, write effects,
              input pin levels, output pin levels
  EventLog    every register write to the modelled peripherals, with virtual time and PC
  Emulator    QEMU process, virtual clock, watch/breakpoint handling, CPU-executed pokes
  scenarios   boot / run / watchdog / fault runs, producing measurements
  checks      one function per assertion, reading only the log and the measurements

How QEMU 7.2 forces the details (see docs/emulator.md, "Running the firmware in an
emulator"):
  * No CCM: the image's stack (0x1000_0000..0x1001_0000) does not exist; at reset the
    harness moves SP to 0x2003_0000, the 64 KiB of SRAM above the chip's 128 KiB (no
    static lives there), and paints everything from the end of the statics up to it.
  * Reads of unimplemented peripherals return 0 and writes are dropped; the gdb stub's
    own memory writes to any MMIO register are dropped too. Data watchpoints stop *before*
    the access: the harness decodes the load/store at PC, steps it with that watchpoint
    removed, and then writes the modelled value into the load's destination register;
    stores update the model and the log. Writes the harness must make to real devices
    (TIM2/TIM4 set-up, TIM3 period, NVIC) are executed by the CPU: a one-instruction
    `str r1, [r0]` stub in unused flash, single-stepped with interrupts masked.
  * Memory QEMU lacks altogether (system memory with the unique ID and flash size, the
    CCM) would BusFault: the harness executes those loads itself and moves PC past them.
  * QEMU 7.2's stm32f2xx-timer counts at a fixed 1 GHz (the SoC sets the property, so
    `-global` cannot change it) and re-arms its update event (ARR + tick_offset) *
    (PSC + 1) ns after each one, where tick_offset is the tick count at the last
    PSC/CNT/UG write. After the firmware starts TIM3 the harness writes TIM3's CNT once so
    that this period equals what the firmware's PSC/ARR give on the real chip at the
    timer clock its own RCC writes configured (84 MHz: 840 cycles = 10 us).
  * Virtual time: -icount shift=3,sleep=off (8 ns an instruction; idle time skipped to
    the next timer deadline, so runs are deterministic and faster than real time). TIM2
    (unused by the firmware) counts virtual nanoseconds from reset (its reset state at
    1 GHz); TIM4, programmed at reset to PSC=999, counts microseconds; the two give the
    exact virtual time in ns at every stop without wrap-around. QEMU also skips to the next
    timer deadline each time the debugger stops the CPU: while the harness stops often
    (boot, the watchdog window, the faults) TIM2 runs a 1 us update event, whose interrupt
    is never enabled, to bound each such skip to 1 us.
"""

import argparse
import os
import re
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

# --------------------------------------------------------------------------------------
# gdb remote serial protocol


class TargetGone(Exception):
    """QEMU closed the connection (exited)."""


class Stop:
    """A stop reply: signal, and the watchpoint that fired, if any."""

    def __init__(self, text):
        self.text = text
        self.signal = None
        self.watch = None  # (kind, address)
        self.exited = text[:1] in ("W", "X")
        if text[:1] in ("T", "S"):
            self.signal = int(text[1:3], 16)
            for field in text[3:].split(";"):
                if ":" in field:
                    k, v = field.split(":", 1)
                    if k in ("watch", "rwatch", "awatch"):
                        self.watch = (k, int(v, 16))

    def __repr__(self):
        return "Stop(%r)" % self.text


class Remote:
    """A minimal client for QEMU's gdbstub (all-stop, no-ack mode)."""

    def __init__(self, port, connect_timeout=10.0):
        deadline = time.monotonic() + connect_timeout
        while True:
            try:
                self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)
        self.sock.settimeout(None)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = b""
        self.ack = True
        r = self.cmd("QStartNoAckMode")
        if r == "OK":
            self.ack = False
        self.cmd("qSupported:swbreak+;hwbreak+;xmlRegisters=arm")
        # QEMU accepts single-register writes ('P') only from a client that read the
        # target description.
        self.cmd("qXfer:features:read:target.xml:0,ffb")
        self.running = False

    def _send(self, payload):
        data = payload.encode("latin-1")
        self.sock.sendall(b"$" + data + b"#%02x" % (sum(data) & 0xFF))
        if self.ack:
            while True:
                c = self._byte(None)
                if c == b"+":
                    break
                if c == b"-":
                    self.sock.sendall(b"$" + data + b"#%02x" % (sum(data) & 0xFF))

    def _byte(self, deadline):
        while not self.buf:
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                r, _, _ = select.select([self.sock], [], [], left)
                if not r:
                    return None
            chunk = self.sock.recv(65536)
            if not chunk:
                raise TargetGone("QEMU closed the gdb connection")
            self.buf += chunk
        c, self.buf = self.buf[:1], self.buf[1:]
        return c

    def _recv(self, deadline=None):
        """One packet's payload, or None at the deadline."""
        while True:
            c = self._byte(deadline)
            if c is None:
                return None
            if c == b"$":
                break
        body = b""
        while True:
            c = self._byte(None)
            if c == b"#":
                break
            body += c
        self._byte(None)
        self._byte(None)
        if self.ack:
            self.sock.sendall(b"+")
        text = body.decode("latin-1")
        if "*" in text:  # run-length encoding
            out, i = [], 0
            while i < len(text):
                if text[i] == "*" and out:
                    out.append(out[-1][-1] * (ord(text[i + 1]) - 29))
                    i += 2
                else:
                    out.append(text[i])
                    i += 1
            text = "".join(out)
        return text

    def cmd(self, payload):
        self._send(payload)
        return self._recv()

    # registers: r0..r15 then xPSR (QEMU's M-profile core feature; xPSR is number 25)
    def regs(self):
        g = self.cmd("g")
        words = [int.from_bytes(bytes.fromhex(g[i : i + 8]), "little") for i in range(0, 17 * 8, 8)]
        return words

    def set_reg(self, n, value):
        n = 25 if n == 16 else n
        r = self.cmd("P%x=%s" % (n, (value & 0xFFFFFFFF).to_bytes(4, "little").hex()))
        if r != "OK":
            raise RuntimeError("cannot write register %d: %r" % (n, r))

    def read(self, addr, length):
        out = b""
        while length > 0:
            n = min(length, 1024)
            r = self.cmd("m%x,%x" % (addr, n))
            if not r or r.startswith("E"):
                raise RuntimeError("cannot read 0x%08x: %r" % (addr, r))
            out += bytes.fromhex(r)
            addr += n
            length -= n
        return out

    def read32(self, addr):
        return int.from_bytes(self.read(addr, 4), "little")

    def write(self, addr, data):
        """RAM/flash only: QEMU drops the stub's writes to device registers."""
        while data:
            chunk, data = data[:1024], data[1024:]
            r = self.cmd("M%x,%x:%s" % (addr, len(chunk), chunk.hex()))
            if r != "OK":
                raise RuntimeError("cannot write 0x%08x: %r" % (addr, r))
            addr += len(chunk)

    def insert(self, kind, addr, length):
        r = self.cmd("Z%d,%x,%x" % (kind, addr, length))
        if r != "OK":
            raise RuntimeError("Z%d at 0x%08x refused: %r" % (kind, addr, r))

    def remove(self, kind, addr, length):
        self.cmd("z%d,%x,%x" % (kind, addr, length))

    def step(self):
        """One instruction, interrupts masked (QEMU's default single-step flags)."""
        return Stop(self.cmd("s"))

    def cont(self):
        self._send("c")
        self.running = True

    def wait(self, deadline):
        """The stop reply; at the deadline, interrupts the target and returns that stop."""
        text = self._recv(deadline)
        if text is None:
            self.sock.sendall(b"\x03")
            text = self._recv(time.monotonic() + 10.0)
            if text is None:
                raise RuntimeError("target did not stop after an interrupt")
        self.running = False
        return Stop(text)

    def close(self):
        try:
            self.sock.close()
        except OSError:
            pass


# --------------------------------------------------------------------------------------
# the image: symbols and decoded loads/stores

REGNAMES = {"sp": 13, "lr": 14, "pc": 15, "ip": 12, "fp": 11, "sl": 10, "sb": 9}
CONDS = "eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al"
LDST = re.compile(r"^(ldr|str)(sb|sh|b|h|d|ex|exb|exh)?(%s)?(\.w|\.n)?$" % CONDS)
LDSTM = re.compile(r"^(ldm|stm)(ia|db|fd|ea)?(%s)?(\.w|\.n)?$" % CONDS)
IMM = r"#(-?(?:0x[0-9a-f]+|\d+))"


def reg(name):
    name = name.strip()
    if name in REGNAMES:
        return REGNAMES[name]
    if re.fullmatch(r"r\d+", name):
        return int(name[1:])
    raise ValueError(name)


class Access:
    """One decoded load/store: kind 'ld'/'st', bytes per transfer, registers, addressing."""

    def __init__(self, kind, size, signed, regs, base, offset=0, index=None, shift=0, post=False, down=False,
                 wb=False):
        self.wb = wb or post  # base register written back
        self.kind, self.size, self.signed, self.regs = kind, size, signed, regs
        self.base, self.offset, self.index, self.shift, self.post = base, offset, index, shift, post
        self.down = down  # ldmdb/stmdb

    def written_back(self, r):
        """The base register's value after the access (writeback forms)."""
        if self.down:
            return r[self.base] - 4 * len(self.regs)
        if self.index is None and self.offset == 0 and not self.post:
            return r[self.base] + self.size * len(self.regs)  # ldm/stm increment after
        return r[self.base] + self.offset + ((r[self.index] << self.shift) if self.index is not None else 0)

    def transfers(self, r):
        """[(address, size, register)] for the register values r (before execution)."""
        if self.down:
            start = r[self.base] - 4 * len(self.regs)
            return [(start + 4 * i, 4, x) for i, x in enumerate(self.regs)]
        addr = r[self.base]
        if not self.post:
            addr += self.offset
            if self.index is not None:
                addr += r[self.index] << self.shift
        addr &= 0xFFFFFFFF
        return [(addr + self.size * i, self.size, x) for i, x in enumerate(self.regs)]


def decode(mnemonic, ops):
    """An Access for a load/store in llvm-objdump's syntax, else None."""
    m = LDST.match(mnemonic)
    if m:
        kind = "ld" if m.group(1) == "ldr" else "st"
        suffix = m.group(2) or ""
        if suffix.startswith("ex"):
            return None
        size = {"": 4, "b": 1, "sb": 1, "h": 2, "sh": 2, "d": 4}[suffix]
        mm = re.match(r"^(.*?)\[([^\]]*)\](!?)(?:,\s*%s)?\s*$" % IMM, ops)
        if not mm:
            return None
        regs = [reg(x) for x in mm.group(1).split(",") if x.strip()]
        inner = [x.strip() for x in mm.group(2).split(",")]
        base = reg(inner[0])
        if base == 15:
            return None  # literal pool
        offset, index, shift, post = 0, None, 0, False
        if mm.group(4) is not None:
            post = True
        for part in inner[1:]:
            im = re.fullmatch(IMM, part)
            if im:
                offset = int(im.group(1), 0)
            elif part.startswith("lsl"):
                shift = int(re.search(IMM, part).group(1), 0)
            else:
                index = reg(part.lstrip("+"))
        return Access(kind, size, suffix in ("sb", "sh"), regs, base, offset, index, shift, post,
                      wb=mm.group(3) == "!")
    m = LDSTM.match(mnemonic)
    if m:
        mm = re.match(r"^(\w+)(!?),\s*\{([^}]*)\}", ops)
        if not mm:
            return None
        regs = []
        for part in mm.group(3).split(","):
            if "-" in part:
                a, b = part.split("-")
                regs += list(range(reg(a), reg(b) + 1))
            else:
                regs.append(reg(part))
        kind = "ld" if m.group(1) == "ldm" else "st"
        return Access(kind, 4, False, sorted(regs), reg(mm.group(1)), down=(m.group(2) in ("db", "ea")),
                      wb=mm.group(2) == "!")
    return None


class Image:
    def __init__(self, path, tools):
        self.path = path
        nm = subprocess.run([os.path.join(tools, "llvm-nm"), "-C", "-n", path], check=True,
                            capture_output=True, text=True).stdout
        self.symbols = {}
        self.functions = []
        for line in nm.splitlines():
            parts = line.split(" ", 2)
            if len(parts) != 3 or not re.fullmatch(r"[0-9a-f]{8}", parts[0]):
                continue
            addr, typ, name = int(parts[0], 16), parts[1], parts[2]
            self.symbols.setdefault(name, addr)
            short = re.sub(r"::h[0-9a-f]{16}$", "", name)
            self.symbols.setdefault(short, addr)
            if typ in "tT" and 0x08000000 <= addr < 0x08100000:
                self.functions.append((addr, short))
        self.functions.sort()
        dis = subprocess.run([os.path.join(tools, "llvm-objdump"), "-d", "--no-show-raw-insn", path],
                             check=True, capture_output=True, text=True).stdout
        self.insns = {}
        line_re = re.compile(r"^\s*([0-9a-f]+):\s+([a-z][a-z0-9.]*)\s*([^@]*)")
        for line in dis.splitlines():
            m = line_re.match(line)
            if m:
                self.insns[int(m.group(1), 16)] = (m.group(2), m.group(3).strip())
        self.udf = sorted(a for a, (mn, _) in self.insns.items() if mn == "udf")

    def sym(self, *names):
        for n in names:
            if n in self.symbols:
                return self.symbols[n]
        return None

    def function_at(self, addr):
        best = None
        for a, name in self.functions:
            if a > addr:
                break
            best = (a, name)
        return "%s+0x%x" % (best[1], addr - best[0]) if best else "0x%08x" % addr

    def access_at(self, pc):
        insn = self.insns.get(pc & ~1)
        if not insn:
            return None, None
        return decode(*insn), insn

    def panic_location(self):
        """A Location the firmware itself passes to core::panicking::panic_bounds_check
        (movw/movt r2 just before a call), for a genuine index panic."""
        target = self.sym("core::panicking::panic_bounds_check")
        if target is None:
            return None, None
        addrs = sorted(self.insns)
        pos = {a: i for i, a in enumerate(addrs)}
        for a in addrs:
            mn, ops = self.insns[a]
            if mn in ("bl", "b.w") and ops.startswith("0x%x" % target):
                lo = hi = None
                for b in addrs[max(0, pos[a] - 6) : pos[a]]:
                    mb, ob = self.insns[b]
                    mm = re.match(r"r2, #(0x[0-9a-f]+|\d+)$", ob)
                    if mm and mb == "movw":
                        lo = int(mm.group(1), 0)
                    elif mm and mb == "movt":
                        hi = int(mm.group(1), 0)
                if lo is not None and hi is not None:
                    return target, (hi << 16) | lo
        return target, None


# --------------------------------------------------------------------------------------
# the register model of what QEMU leaves unimplemented

GPIO_REGS = {0x00: "MODER", 0x04: "OTYPER", 0x08: "OSPEEDR", 0x0C: "PUPDR", 0x10: "IDR", 0x14: "ODR",
             0x18: "BSRR", 0x1C: "LCKR", 0x20: "AFRL", 0x24: "AFRH"}
PERIPHERALS = [
    # name, base, size, register names
    ("RCC", 0x40023800, 0x400, {0x00: "CR", 0x04: "PLLCFGR", 0x08: "CFGR", 0x0C: "CIR", 0x10: "AHB1RSTR",
                                0x14: "AHB2RSTR", 0x18: "AHB3RSTR", 0x20: "APB1RSTR", 0x24: "APB2RSTR",
                                0x30: "AHB1ENR", 0x34: "AHB2ENR", 0x38: "AHB3ENR", 0x40: "APB1ENR",
                                0x44: "APB2ENR", 0x50: "AHB1LPENR", 0x54: "AHB2LPENR", 0x58: "AHB3LPENR",
                                0x60: "APB1LPENR", 0x64: "APB2LPENR", 0x70: "BDCR", 0x74: "CSR",
                                0x80: "SSCGR", 0x84: "PLLI2SCFGR"}),
    ("FLASH", 0x40023C00, 0x400, {0x00: "ACR", 0x04: "KEYR", 0x08: "OPTKEYR", 0x0C: "SR", 0x10: "CR", 0x14: "OPTCR"}),
    ("PWR", 0x40007000, 0x400, {0x00: "CR", 0x04: "CSR"}),
    ("IWDG", 0x40003000, 0x400, {0x00: "KR", 0x04: "PR", 0x08: "RLR", 0x0C: "SR"}),
] + [("GPIO" + "ABCDEFGHI"[i], 0x40020000 + 0x400 * i, 0x400, GPIO_REGS) for i in range(9)] + [
    ("OTG_FS", 0x50000000, 0x1000, {0x00: "GOTGCTL", 0x04: "GOTGINT", 0x08: "GAHBCFG", 0x0C: "GUSBCFG",
                                    0x10: "GRSTCTL", 0x14: "GINTSTS", 0x18: "GINTMSK", 0x24: "GRXFSIZ",
                                    0x28: "DIEPTXF0", 0x38: "GCCFG", 0x3C: "CID", 0x800: "DCFG",
                                    0x804: "DCTL", 0x808: "DSTS", 0x810: "DIEPMSK", 0x814: "DOEPMSK",
                                    0x818: "DAINT", 0x81C: "DAINTMSK", 0xE00: "PCGCCTL"}),
    ("DBGMCU", 0xE0042000, 0x10, {0x00: "IDCODE", 0x04: "CR", 0x08: "APB1_FZ", 0x0C: "APB2_FZ"}),
    # Not in QEMU's memory map at all (an access is a BusFault there): the harness executes
    # these loads itself. System memory: the unique ID and the flash size; the CCM, which
    # nothing should touch once the stack is moved.
    ("SYSMEM", 0x1FFF7800, 0x230, {0x210: "UID0", 0x214: "UID1", 0x218: "UID2", 0x220: "FLASH_SIZE"}),
    ("CCM", 0x10000000, 0x10000, {}),
]
ABSENT = ("SYSMEM", "CCM")
RESET_VALUES = {
    0x40023800: 0x00000083,  # RCC_CR: HSION, HSIRDY
    0x40023804: 0x24003010,  # RCC_PLLCFGR
    0x40023874: 0x0E000000,  # RCC_CSR: POR/PIN/BOR reset flags (not the watchdog's)
    0x40020000: 0xA8000000,  # GPIOA_MODER (debug pins)
    0x40020400: 0x00000280,  # GPIOB_MODER
    0x4002000C: 0x64000000,
    0x40020408: 0x000000C0,
    0x4002040C: 0x00000100,
    0x50000010: 0x80000000,  # OTG GRSTCTL: AHBIDL
    0x5000003C: 0x00001200,  # OTG CID (STM32F405 OTG_FS)
    0xE0042000: 0x10076413,  # DBGMCU IDCODE: STM32F405, rev Z
    0x1FFF7A10: 0x00440031,  # UID (any fixed value)
    0x1FFF7A14: 0x3436510D,
    0x1FFF7A18: 0x37323834,
    0x1FFF7A20: 0x04000000,  # flash size 1024 KiB (half-word at 0x1FFF7A22)
    0x40023C14: 0x0FFFAAED,  # FLASH_OPTCR: factory option bytes (BOR off, OPTLOCK set)
}
FLASH_OPTCR = 0x40023C14
OPTKEYS = (0x08192A3B, 0x4C5D6E7F)


class Chip:
    """Values the unmodelled registers read as, and what writes to them do.

    Reads return the last value written (or the reset value) with the status bits the
    firmware waits for derived from the control bits it set: a clock is ready once it is
    switched on, the system clock source follows SW, Flash latency reads back, the OTG
    core is idle and out of reset. Inputs: `inputs[port]` is the IDR level; outputs:
    `outputs[port]` follows ODR/BSRR writes.
    """

    def __init__(self):
        self.values = dict(RESET_VALUES)
        # The crystal: False models a dead one (HSERDY never set).
        self.hse_ok = True
        # Option-key sequence progress (FLASH_OPTKEYR); OPTCR takes writes once unlocked.
        self.optkeys = 0
        # Inputs: e-stop PC13 low (closed switch: not stopped), endstops PC0..PC2 high
        # (active low: not triggered), VBUS PA9 low (no cable).
        self.inputs = {"GPIOA": 0, "GPIOB": 0, "GPIOC": 0b111}
        self.outputs = {}

    @staticmethod
    def locate(addr):
        for name, base, size, regs in PERIPHERALS:
            if base <= addr < base + size:
                off = addr - base
                return name, off, regs.get(off & ~3, "+0x%03x" % (off & ~3))
        return None, None, None

    def read_word(self, addr):
        addr &= ~3
        name, off, _ = self.locate(addr)
        v = self.values.get(addr, 0)
        if name == "RCC":
            if off == 0x00:
                v = (v & ~((1 << 1) | (1 << 17) | (1 << 25) | (1 << 27))) | ((v & 1) << 1) | (
                    ((v >> 16) & 1 & self.hse_ok) << 17) | (((v >> 24) & 1) << 25) | (((v >> 26) & 1) << 27)
            elif off == 0x08:
                v = (v & ~0xC) | ((v & 3) << 2)
            elif off == 0x70:
                v = (v & ~2) | ((v & 1) << 1)
            elif off == 0x74:
                v = (v & ~2) | ((v & 1) << 1)
        elif name == "PWR" and off == 0x04:
            v |= 1 << 14  # VOSRDY
        elif name == "FLASH" and off == 0x0C:
            v = 0  # never busy
        elif name == "IWDG" and off == 0x0C:
            v = 0  # prescaler/reload updates done
        elif name and name.startswith("GPIO"):
            if off == 0x10:
                v = self.inputs.get(name, 0)
            elif off == 0x14:
                v = self.outputs.get(name, 0)
            elif off == 0x18:
                v = 0
        elif name == "OTG_FS" and off == 0x10:
            v = (v | 0x80000000) & ~0x31  # AHBIDL, CSRST/FIFO flushes done
        return v & 0xFFFFFFFF

    def read(self, addr, size):
        word = self.read_word(addr)
        return (word >> (8 * (addr & 3))) & ((1 << (8 * size)) - 1)

    def write(self, addr, size, value):
        """Applies a write; returns the whole register's new value."""
        waddr = addr & ~3
        name, off, _ = self.locate(waddr)
        shift = 8 * (addr & 3)
        mask = ((1 << (8 * size)) - 1) << shift
        old = self.values.get(waddr, 0)
        new = (old & ~mask) | ((value << shift) & mask)
        if name and name.startswith("GPIO"):
            if off == 0x18:
                out = self.outputs.get(name, 0)
                out = (out | (new & 0xFFFF)) & ~(new >> 16)
                self.outputs[name] = out
                return new
            if off == 0x14:
                self.outputs[name] = new & 0xFFFF
        if name == "OTG_FS" and off in (0x04, 0x14):
            new = old & ~(value << shift)  # GOTGINT, GINTSTS: write 1 to clear
        if name == "RCC" and off == 0x74 and new & (1 << 24):
            new &= 0x00FFFFFF  # RMVF clears the reset flags
        if name == "FLASH" and off == 0x08:
            # OPTKEYR: the two keys in order clear OPTLOCK; anything else restarts.
            self.optkeys = self.optkeys + 1 if value == OPTKEYS[self.optkeys % 2] and self.optkeys < 2 else 0
            if self.optkeys == 2:
                self.values[FLASH_OPTCR] = self.values.get(FLASH_OPTCR, 0) & ~1
        if name == "FLASH" and off == 0x10:
            # CR.STRT: the erase it starts is done at once here (SR never busy), and the
            # bit clears with BSY, as on the chip, so a later CR write starts nothing.
            new &= ~(1 << 16)
        if name == "FLASH" and off == 0x14:
            if old & 1 and self.optkeys < 2:
                return old  # locked: the write is ignored
            # OPTSTRT: the option bytes are programmed (at once here) and the bit clears;
            # OPTLOCK written 1 locks again until the next key sequence.
            new &= ~2
            if new & 1:
                self.optkeys = 0
        self.values[waddr] = new
        return new

    def pin(self, port, n):
        return (self.outputs.get(port, 0) >> n) & 1


# --------------------------------------------------------------------------------------
# the event log


class Event:
    __slots__ = ("t", "pc", "periph", "reg", "addr", "size", "value", "word", "where")

    def __init__(self, t, pc, periph, reg, addr, size, value, word, where):
        self.t, self.pc, self.periph, self.reg, self.addr = t, pc, periph, reg, addr
        self.size, self.value, self.word, self.where = size, value, word, where

    def row(self):
        return "%d,%s,%s,0x%08x,%d,0x%08x,0x%08x,0x%08x,%s" % (
            self.t, self.periph, self.reg, self.addr, self.size, self.value, self.word, self.pc, self.where)


class EventLog:
    """Register writes to the modelled peripherals, in order, plus named marks."""

    def __init__(self):
        self.events = []
        self.marks = {}
        self.reads = {}

    def write(self, ev):
        self.events.append(ev)

    def mark(self, name, t):
        self.marks.setdefault(name, t)

    def read(self, periph, regname):
        k = "%s.%s" % (periph, regname)
        self.reads[k] = self.reads.get(k, 0) + 1

    def find(self, periph, regname, after=0, before=None):
        return [e for e in self.events if e.periph == periph and e.reg == regname and e.t >= after
                and (before is None or e.t < before)]

    def dump(self, path):
        with open(path, "w") as f:
            f.write("t_ns,periph,reg,addr,size,value,register_after,pc,function\n")
            for e in self.events:
                f.write(e.row() + "\n")
            for k, v in sorted(self.marks.items(), key=lambda kv: kv[1]):
                f.write("# mark %s at %d ns\n" % (k, v))


# --------------------------------------------------------------------------------------
# the emulator: QEMU, the virtual clock, watch and breakpoint handling

SRAM_TOP = 0x20030000  # QEMU's 192 KiB; the real chip's SRAM is 128 KiB + 64 KiB CCM
STACK_SIZE = 64 * 1024  # what memory.x gives the stack (the CCM)
PAINT = 0xC5AC_CE55
STUB = 0x0803FF00  # unused flash inside the firmware's 256 KiB (the image is far smaller)
TIM2, TIM3, TIM4 = 0x40000000, 0x40000400, 0x40000800
NVIC_ICER = 0xE000E180
UART5_IRQ = 53
TIM3_IRQ = 29


class Emulator:
    def __init__(self, image, args, log_dir, label, serial=None):
        """serial: QEMU -serial backends in USART order (USART1, USART2, USART3, UART4, ...)."""
        self.image, self.args, self.label = image, args, label
        self.chip = Chip()
        self.log = EventLog()
        self.watches = {}  # (addr, len) -> handler
        self.bps = {}  # addr -> name
        self.bp_hits = []  # (name, t, pc, lr)
        self.notes = []
        self.high_time = 0
        self.tim3_fixed = None
        port = free_port()
        self.qemu_log = open(os.path.join(log_dir, "qemu-%s.log" % label), "w")
        serial_args = []
        for backend in serial or ["null"]:
            serial_args += ["-serial", backend]
        cmd = [args.qemu, "-M", "netduinoplus2", "-display", "none", "-monitor", "none"] + serial_args + [
               "-kernel", image.path, "-S",
               # nodelay: the stub's small replies must not wait for delayed ACKs
               "-chardev", "socket,id=gdb,host=127.0.0.1,port=%d,server=on,wait=off,nodelay=on" % port,
               "-gdb", "chardev:gdb",
               "-icount", "shift=%d,align=off,sleep=%s" % (args.icount_shift, getattr(args, "icount_sleep", "off"))]
        self.qemu = subprocess.Popen(cmd, stdout=self.qemu_log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     preexec_fn=die_with_parent)
        EMULATORS.append(self)
        try:
            self.r = Remote(port)
        except Exception:
            self.kill()
            raise

    def kill(self):
        if getattr(self, "r", None):
            self.r.close()
        if self.qemu.poll() is None:
            self.qemu.kill()
        self.qemu.wait()
        if not self.qemu_log.closed:
            self.qemu_log.close()

    # ---- virtual time ------------------------------------------------------------
    def now(self):
        """Virtual ns since reset: TIM2 counts ns (mod 2^32), TIM4 counts us."""
        fine = self.r.read32(TIM2 + 0x24)
        coarse = self.r.read32(TIM4 + 0x24) * 1000
        k = round((coarse - fine) / 2**32)
        t = fine + k * 2**32
        self.high_time = max(self.high_time, t)
        return t

    # ---- CPU-executed writes -------------------------------------------------------
    def poke(self, addr, value):
        regs = self.r.regs()
        removed = [w for w in self.watches if w[0] <= addr < w[0] + w[1]]
        for w in removed:
            self.r.remove(4, *w)
        self.r.set_reg(0, addr)
        self.r.set_reg(1, value)
        self.r.set_reg(15, STUB)
        self.r.set_reg(16, (regs[16] & ~0x0600FC00) | 0x01000000)  # no IT block, Thumb
        stop = self.r.step()
        for w in removed:
            self.r.insert(4, *w)
        after = self.r.regs()
        for n in (0, 1, 15, 16):
            self.r.set_reg(n, regs[n])
        if after[15] != STUB + 2:
            raise RuntimeError("poke of 0x%08x did not execute (%r, pc 0x%08x)" % (addr, stop, after[15]))

    # ---- set-up at reset -------------------------------------------------------------
    def reset_setup(self):
        regs = self.r.regs()
        reset = self.image.sym("Reset")
        if regs[15] & ~1 != reset & ~1:
            raise RuntimeError("not halted at Reset (pc 0x%08x)" % regs[15])
        self.vector_sp = regs[13]
        self.r.write(STUB, bytes.fromhex("0160"))  # str r1, [r0]
        self.r.set_reg(13, SRAM_TOP)
        bottom = (self.image.sym("__euninit", "__ebss") + 7) & ~7
        self.paint_bottom = bottom
        self.r.write(bottom, PAINT.to_bytes(4, "little") * ((SRAM_TOP - bottom) // 4))
        # TIM4 counts microseconds: PSC 999, then CNT set so that it reads floor(t / 1 us)
        # (QEMU keeps the count across a PSC write).
        self.poke(TIM4 + 0x28, 999)
        self.poke(TIM4 + 0x24, self.r.read32(TIM2 + 0x24) // 1000)
        self.t_reset = self.now()
        self.limit_warp(True)

    def limit_warp(self, on):
        """QEMU (icount, sleep=off) moves virtual time to the next timer deadline whenever
        the CPU stops, which each debugger stop does. While the harness stops often (boot,
        the watchdog window, the faults) TIM2 raises a 1 us update event (its interrupt is
        never enabled in the NVIC, so the firmware sees nothing), which bounds each such
        jump to 1 us. Off during the long measurements, where nothing stops."""
        if on:
            self.poke(TIM2 + 0x2C, 1000)  # ARR: 1000 ns a period at QEMU's 1 GHz
            self.poke(TIM2 + 0x0C, 1)  # DIER.UIE
            self.poke(TIM2, 1)  # CR1.CEN
        else:
            self.poke(TIM2 + 0x0C, 0)
            self.poke(TIM2, 0)

    # ---- watches and breakpoints ------------------------------------------------------
    def watch(self, addr, length, handler):
        if (addr, length) not in self.watches:
            self.r.insert(4, addr, length)
        self.watches[(addr, length)] = handler

    def unwatch(self, addr, length):
        if (addr, length) in self.watches:
            self.r.remove(4, addr, length)
            del self.watches[(addr, length)]

    def watch_model(self, names):
        for name, base, size, _ in PERIPHERALS:
            if name in names:
                self.watch(base, size, self.on_model_access)

    def unwatch_model(self, names):
        for name, base, size, _ in PERIPHERALS:
            if name in names:
                self.unwatch(base, size)

    def breakpoint(self, addr, name):
        if addr is None:
            return
        addr &= ~1
        self.r.insert(0, addr, 2)
        self.bps[addr] = name

    def clear_breakpoint(self, name):
        for a, n in list(self.bps.items()):
            if n == name:
                self.r.remove(0, a, 2)
                del self.bps[a]

    def step_over(self, pc, skip_watch=None):
        """Executes the instruction at pc with the breakpoint/watchpoints that stop it removed."""
        removed_bp = pc in self.bps
        if removed_bp:
            self.r.remove(0, pc, 2)
        removed = []
        if skip_watch:
            removed.append(skip_watch)
            self.r.remove(4, *skip_watch)
        for _ in range(4):
            stop = self.r.step()
            if stop.watch and self.r.regs()[15] & ~1 == pc:
                w = self.watch_for(stop.watch[1])
                if w is None or w in removed:
                    break
                removed.append(w)
                self.r.remove(4, *w)
                continue
            break
        for w in removed:
            self.r.insert(4, *w)
        if removed_bp:
            self.r.insert(0, pc, 2)

    def watch_for(self, addr):
        for w in self.watches:
            if w[0] <= addr < w[0] + w[1]:
                return w
        return None

    # ---- handlers ------------------------------------------------------------------
    def on_model_access(self, w, regs):
        """Stopped before a load/store touching an unmodelled peripheral."""
        pc = regs[15] & ~1
        acc, insn = self.image.access_at(pc)
        if acc is None:
            self.notes.append("unhandled access at %s: %s" % (self.image.function_at(pc), insn))
            self.step_over(pc, w)
            return
        transfers = [x for x in acc.transfers(regs)]
        t = self.now()
        if self.chip.locate(transfers[0][0])[0] in ABSENT:
            self.execute_absent(pc, regs, acc, transfers, t)
            return
        if acc.kind == "st":
            for addr, size, rn in transfers:
                value = regs[rn] & ((1 << (8 * size)) - 1)
                name, _, regname = self.chip.locate(addr)
                if name is None:
                    continue
                word = self.chip.write(addr, size, value)
                self.log.write(Event(t, pc, name, regname, addr, size, value, word, self.image.function_at(pc)))
                self.on_write(name, regname, value, t)
            self.step_over(pc, w)
        else:
            self.step_over(pc, w)
            for addr, size, rn in transfers:
                name, _, regname = self.chip.locate(addr)
                if name is None:
                    continue
                v = self.chip.read(addr, size)
                if acc.signed and v >> (8 * size - 1):
                    v -= 1 << (8 * size)
                self.r.set_reg(rn, v)
                self.log.read(name, regname)

    def execute_absent(self, pc, regs, acc, transfers, t):
        """A load/store to memory QEMU does not have: done here, then PC moves past it."""
        name = self.chip.locate(transfers[0][0])[0]
        if name == "CCM":
            self.notes.append("CCM accessed at %s (the stack was moved out of it)" % self.image.function_at(pc))
        for addr, size, rn in transfers:
            if acc.kind == "ld":
                v = self.chip.read(addr, size)
                if acc.signed and v >> (8 * size - 1):
                    v -= 1 << (8 * size)
                self.r.set_reg(rn, v)
                self.log.read(name, self.chip.locate(addr)[2])
        if acc.wb and not (acc.kind == "ld" and acc.base in acc.regs):
            self.r.set_reg(acc.base, acc.written_back(regs))
        half = int.from_bytes(self.r.read(pc, 2), "little")
        size = 4 if half >> 11 in (0b11101, 0b11110, 0b11111) else 2
        xpsr = regs[16]
        it = ((xpsr >> 25) & 3) | (((xpsr >> 10) & 0x3F) << 2)
        if it:
            it = 0 if it & 7 == 0 else (it & 0xE0) | ((it << 1) & 0x1F)
            xpsr = (xpsr & ~0x0600FC00) | ((it & 3) << 25) | ((it >> 2) << 10)
            self.r.set_reg(16, xpsr)
        self.r.set_reg(15, pc + size)

    def on_write(self, periph, regname, value, t):
        if periph == "RCC" and regname in ("PLLCFGR", "CFGR"):
            self.log.mark("first clock-tree write", t)
        if periph == "IWDG" and regname == "KR" and value == 0xAAAA:
            self.feeds += 1

    def on_timer_access(self, w, regs):
        """TIM3 (the step timer, modelled by QEMU): after any write, fix its period."""
        pc = regs[15] & ~1
        self.step_over(pc, w)
        self.fix_step_timer()

    def timer_clock(self):
        """TIM3's clock on the real chip, from the firmware's own RCC writes."""
        pll = self.chip.values.get(0x40023804, 0)
        cfgr = self.chip.values.get(0x40023808, 0)
        m, n, p = pll & 0x3F, (pll >> 6) & 0x1FF, 2 * (((pll >> 16) & 3) + 1)
        src = 8_000_000 if pll & (1 << 22) else 16_000_000
        sw = cfgr & 3
        sys_hz = {0: 16_000_000, 1: 8_000_000}.get(sw, src // max(m, 1) * n // p)
        hpre = (cfgr >> 4) & 0xF
        hclk = sys_hz >> ({8: 1, 9: 2, 10: 3, 11: 4, 12: 6, 13: 7, 14: 8, 15: 9}.get(hpre, 0))
        ppre1 = (cfgr >> 10) & 7
        div = 1 << (ppre1 - 3) if ppre1 >= 4 else 1
        return hclk // div * (2 if div > 1 else 1)

    def fix_step_timer(self):
        cr1 = self.r.read32(TIM3)
        psc = self.r.read32(TIM3 + 0x28) & 0xFFFF
        arr = self.r.read32(TIM3 + 0x2C) & 0xFFFF
        if not cr1 & 1 or arr == 0:
            return
        clk = self.timer_clock()
        period_ns = (psc + 1) * (arr + 1) * 1_000_000_000 // clk
        # QEMU runs the timer's callback at the first instruction boundary after its
        # deadline and re-arms from there: one icount quantum late every period.
        quantum = 1 << self.args.icount_shift
        want_offset = (period_ns - quantum) // (psc + 1) - arr
        t = self.now()
        value = (t // (psc + 1) - want_offset) & 0xFFFFFFFF
        self.poke(TIM3 + 0x24, value)
        self.tim3_fixed = dict(t=t, psc=psc, arr=arr, clk=clk, period_ns=period_ns, quantum=quantum)

    def on_foreign_timer(self, w, regs):
        pc = regs[15] & ~1
        self.notes.append("the firmware touched TIM2/TIM4 (the harness's clock) at %s" % self.image.function_at(pc))
        self.step_over(pc, w)

    def on_stack_guard(self, w, regs):
        pc = regs[15] & ~1
        self.log.mark("stack past 64 KiB", self.now())
        self.stack_crossing = self.image.function_at(pc)
        self.unwatch(*w)

    # ---- running -------------------------------------------------------------------
    def run(self, wall_s, until=None):
        """Runs until `until()` is true after a stop, a breakpoint handler says stop, or
        wall_s seconds of wall time. Returns the reason."""
        deadline = time.monotonic() + wall_s
        while True:
            pc = self.r.regs()[15] & ~1
            if pc in self.bps:
                self.step_over(pc)
            self.r.cont()
            stop = self.r.wait(deadline)
            if stop.exited:
                raise TargetGone("QEMU exited: %s" % stop.text)
            regs = self.r.regs()
            if DEBUG:
                print("stop %s pc %s" % (stop.text, self.image.function_at(regs[15])), file=sys.stderr)
            if stop.watch:
                w = self.watch_for(stop.watch[1])
                if w is None:
                    raise RuntimeError("unknown watchpoint stop %r" % stop)
                self.watches[w](w, regs)
            elif regs[15] & ~1 in self.bps:
                name = self.bps[regs[15] & ~1]
                t = self.now()
                self.bp_hits.append((name, t, regs[15], regs[14]))
                if name in ("HardFault", "DefaultHandler"):
                    self.fault_info = self.describe_fault(regs)
                self.log.mark(name, t)
                if name in self.stop_at:
                    return name
            elif stop.signal == 2:
                return "wall"
            elif stop.signal == 5:
                pass  # stray trap (an interrupt that raced with a watch stop)
            else:
                raise RuntimeError("unexpected stop %r at 0x%08x" % (stop, regs[15]))
            if until and until():
                return "until"
            if time.monotonic() > deadline:
                return "wall"

    def describe_fault(self, regs):
        """Where an exception came from: the stacked PC, CFSR/HFSR, the active vector."""
        lr = regs[14]
        sp = regs[13]
        try:
            frame = self.r.read(sp, 32)
            stacked_pc = int.from_bytes(frame[24:28], "little")
            cfsr, hfsr = self.r.read32(0xE000ED28), self.r.read32(0xE000ED2C)
            bfar = self.r.read32(0xE000ED38)
        except RuntimeError as e:
            return "exception frame unreadable (%s)" % e
        return "vector %d from %s (pc 0x%08x), CFSR 0x%08x HFSR 0x%08x BFAR 0x%08x, EXC_RETURN 0x%08x" % (
            regs[16] & 0x1FF, self.image.function_at(stacked_pc), stacked_pc, cfsr, hfsr, bfar, lr)

    def read_u32_sym(self, addr):
        return self.r.read32(addr) if addr is not None else None

    def outputs_state(self):
        return ("valves PA0..PA3 %s, drivers %s (PB15 %d)" % (
            "".join(str(self.chip.pin("GPIOA", i)) for i in range(4)),
            "disabled" if self.chip.pin("GPIOB", 15) else "ENABLED", self.chip.pin("GPIOB", 15)))


FIL_SCENARIOS = ["print", "pause", "abort", "link-cut", "estop", "flipped", "serve"]
# Without --fil: all but serve, which needs the design the job was sliced from (--design).
FIL_DEFAULT = [s for s in FIL_SCENARIOS if s != "serve"]
EMULATORS = []
DEBUG = bool(os.environ.get("EMULATE_DEBUG"))


def die_with_parent():
    """QEMU gets SIGKILL if this script dies, however it dies (Linux prctl)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except OSError:
        pass


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


FAULT_STOPS = ("HardFault", "DefaultHandler", "panic", "Reset")


def boot(image, args, log_dir, label, serial=None, prepare=None, stops=()):
    """A fresh QEMU halted at reset, relocated and clocked, run until the control loop's
    first period (the UART5 handler), with every unmodelled register modelled.
    prepare(emu), if given, runs just before the firmware starts (a scenario's own chip
    state and watches); stops: more (address, name) breakpoints that end the boot."""
    emu = Emulator(image, args, log_dir, label, serial)
    emu.feeds = 0
    emu.stack_crossing = None
    emu.reset_setup()
    emu.watch_model({p[0] for p in PERIPHERALS})
    # TIM3: CR1 and EGR..ARR (not SR, which the step interrupt writes every tick)
    emu.watch(TIM3, 4, emu.on_timer_access)
    emu.watch(TIM3 + 0x14, 0x1C, emu.on_timer_access)
    emu.watch(TIM2, 0x30, emu.on_foreign_timer)
    emu.watch(TIM4, 0x30, emu.on_foreign_timer)
    emu.watch(SRAM_TOP - STACK_SIZE - 4, 4, emu.on_stack_guard)
    emu.breakpoint(image.sym("UART5"), "control loop")
    emu.breakpoint(image.sym("HardFault"), "HardFault")
    emu.breakpoint(image.sym("DefaultHandler"), "DefaultHandler")
    emu.breakpoint(image.sym("rust_begin_unwind", "__rustc::rust_begin_unwind"), "panic")
    emu.breakpoint(image.sym("Reset"), "Reset")
    emu.stop_at = ("control loop",) + FAULT_STOPS
    for addr, name in stops:
        emu.breakpoint(addr, name)
        emu.stop_at += (name,)
    if prepare:
        prepare(emu)
    why = emu.run(args.boot_wall)
    emu.boot_result = why
    if why == "control loop":
        emu.clear_breakpoint("control loop")
    return emu


# --------------------------------------------------------------------------------------
# scenarios: each returns measurements for the checks


def scenario_main(image, args, log_dir):
    m = {}
    emu = boot(image, args, log_dir, "main")
    m["emu"] = emu
    m["boot"] = emu.boot_result
    m["boot_t"] = emu.now()
    if emu.boot_result != "control loop":
        return m
    emu.stop_at = FAULT_STOPS
    # Steady state: no watchpoints but the stack guard; counters and virtual time.
    emu.unwatch_model({p[0] for p in PERIPHERALS} - set(ABSENT))
    emu.unwatch(TIM3, 4)
    emu.unwatch(TIM3 + 0x14, 0x1C)
    ticks_at = image.sym("dollop_firmware::step::TICKS")
    periods_at = image.sym("dollop_firmware::control::PERIODS")
    m["periods_symbol"] = periods_at is not None
    emu.limit_warp(False)
    t0, k0 = emu.now(), emu.read_u32_sym(ticks_at)
    p0 = emu.read_u32_sym(periods_at)
    target = int(args.seconds * 1e9)
    wall0 = time.monotonic()
    why = "wall"
    while emu.now() - t0 < target and time.monotonic() - wall0 < args.run_wall:
        why = emu.run(min(1.0, args.run_wall), until=lambda: False)
        if why in FAULT_STOPS:
            break
    t1, k1 = emu.now(), emu.read_u32_sym(ticks_at)
    p1 = emu.read_u32_sym(periods_at)
    m["run"] = dict(why=why, dt=t1 - t0, ticks=(k1 - k0) & 0xFFFFFFFF if k0 is not None else None,
                    periods=(p1 - p0) & 0xFFFFFFFF if p0 is not None else None, wall=time.monotonic() - wall0)
    if why in FAULT_STOPS:
        m["fault_in_run"] = why
        return finish_main(emu, m)
    if periods_at is None:
        # Fallback: count control-loop entries over a short window.
        emu.breakpoint(image.sym("UART5"), "control period")
        n, ta = 0, emu.now()
        while n < 2000:
            why = emu.run(5.0)
            if why != "wall" and emu.bp_hits and emu.bp_hits[-1][0] == "control period":
                n += 1
            if why in FAULT_STOPS or why == "wall":
                break
        emu.clear_breakpoint("control period")
        m["run"]["bp_periods"] = (n, emu.now() - ta)
    # Watchdog feeds at the control loop's pace.
    emu.feeds = 0
    emu.limit_warp(True)
    emu.watch(0x40003000, 4, emu.on_model_access)
    ta, pa, ka = emu.now(), emu.read_u32_sym(periods_at), emu.read_u32_sym(ticks_at)
    why = emu.run(args.run_wall / 4, until=lambda: emu.feeds >= args.feeds)
    tb, pb, kb = emu.now(), emu.read_u32_sym(periods_at), emu.read_u32_sym(ticks_at)
    m["wdg_window"] = dict(why=why, feeds=emu.feeds, dt=tb - ta, ticks=(kb - ka) & 0xFFFFFFFF,
                           periods=None if pa is None else (pb - pa) & 0xFFFFFFFF)
    if why in FAULT_STOPS:
        m["fault_in_run"] = why
        return finish_main(emu, m)
    # Stop the control loop (disable UART5 in the NVIC); feeds must stop.
    emu.poke(NVIC_ICER + 4 * (UART5_IRQ // 32), 1 << (UART5_IRQ % 32))
    emu.limit_warp(False)
    emu.feeds = 0
    tc, kc, pc_ = emu.now(), emu.read_u32_sym(ticks_at), emu.read_u32_sym(periods_at)
    wall0 = time.monotonic()
    while emu.now() - tc < int(args.stopped_seconds * 1e9) and time.monotonic() - wall0 < args.run_wall / 4:
        why = emu.run(0.5)
        if why in FAULT_STOPS:
            break
    td, kd, pd = emu.now(), emu.read_u32_sym(ticks_at), emu.read_u32_sym(periods_at)
    m["wdg_stopped"] = dict(why=why, feeds=emu.feeds, dt=td - tc, ticks=(kd - kc) & 0xFFFFFFFF,
                            periods=None if pc_ is None else (pd - pc_) & 0xFFFFFFFF)
    return finish_main(emu, m)


def finish_main(emu, m):
    data = emu.r.read(emu.paint_bottom, SRAM_TOP - emu.paint_bottom)
    pat = PAINT.to_bytes(4, "little")
    lowest = None
    for off in range(0, len(data), 4):
        if data[off : off + 4] != pat:
            lowest = emu.paint_bottom + off
            break
    m["stack_used"] = SRAM_TOP - lowest if lowest is not None else 0
    m["stack_painted"] = SRAM_TOP - emu.paint_bottom
    return m


def scenario_fault(image, args, log_dir, kind):
    """Boots, then forces a HardFault ('hardfault') or a panic ('panic') from the control
    interrupt with valve 0 open and the drivers enabled in the pin model."""
    m = {}
    emu = boot(image, args, log_dir, kind)
    m["emu"] = emu
    m["boot"] = emu.boot_result
    if emu.boot_result != "control loop":
        return m
    emu.stop_at = ("Reset",)
    # The control interrupt is about to run: open valve 0, enable the drivers (pin model).
    emu.chip.outputs["GPIOA"] = emu.chip.outputs.get("GPIOA", 0) | 1
    emu.chip.outputs["GPIOB"] = emu.chip.outputs.get("GPIOB", 0) & ~(1 << 15)
    m["before"] = emu.outputs_state()
    # The step interrupt is switched off first: its STEP/DIR writes (GPIOB/GPIOC, 100 kHz)
    # would stop the emulator at every tick and, through QEMU's icount warp at each
    # resume, keep it pending so the forced fault would wait behind it.
    emu.poke(NVIC_ICER + 4 * (TIM3_IRQ // 32), 1 << (TIM3_IRQ % 32))
    emu.watch_model({"GPIOA", "GPIOB", "GPIOC"})
    regs = emu.r.regs()
    if kind == "hardfault":
        target = emu.image.udf[0] if emu.image.udf else 0xFFFFFFF0
        emu.r.set_reg(15, target)
        m["how"] = "PC := 0x%08x (udf) in the UART5 handler" % target
    else:
        fn, loc = emu.image.panic_location()
        if fn is None or loc is None:
            m["how"] = "no panic_bounds_check call site with a constant Location found"
            return m
        emu.r.set_reg(0, 7)
        emu.r.set_reg(1, 3)
        emu.r.set_reg(2, loc)
        emu.r.set_reg(14, regs[15] | 1)
        emu.r.set_reg(15, fn)
        m["how"] = "call panic_bounds_check(7, 3, Location@0x%08x) from the UART5 handler" % loc
    m["t_fault"] = emu.now()
    emu.log.mark("fault forced", m["t_fault"])
    why = emu.run(args.fault_wall)
    m["why"] = why
    m["after"] = emu.outputs_state()
    return m


# --------------------------------------------------------------------------------------
# checks: (name, ok, figure)


def ms(t):
    return "%.3f ms" % (t / 1e6)


def check_boot(m):
    ok = m["boot"] == "control loop"
    emu = m["emu"]
    fig = "control loop first ran at %s" % ms(m["boot_t"]) if ok else "never reached the control loop (%s%s)" % (
        m["boot"], "; " + "; ".join(emu.notes) if emu.notes else "")
    return "boot to the control loop", ok, fig


def pin_drives(events, port, pin, after=0, before=None):
    """[(t, level)] for every write to `port` that drives `pin` (BSRR set/reset, ODR)."""
    out = []
    for e in events:
        if e.periph != port or e.t < after or (before is not None and e.t >= before):
            continue
        if e.reg == "BSRR":
            if e.word >> (16 + pin) & 1:
                out.append((e.t, 0))
            elif e.word >> pin & 1:
                out.append((e.t, 1))
        elif e.reg == "ODR":
            out.append((e.t, e.word >> pin & 1))
    return out


def driven_to(events, port, pins, level, after=0, before=None):
    """When the last of `pins` was driven to `level` (each left there), or None."""
    when = []
    for pin in pins:
        d = pin_drives(events, port, pin, after, before)
        if not d or d[-1][1] != level:
            return None
        when.append(next(t for t, lv in d if lv == level))
    return max(when)


def check_safe_before_clocks(m):
    log = m["emu"].log
    t_clk = log.marks.get("first clock-tree write")
    if t_clk is None:
        return "safe outputs before clock set-up", False, "no RCC PLLCFGR/CFGR write seen"
    valves = driven_to(log.events, "GPIOA", range(4), 0, before=t_clk)
    drivers = driven_to(log.events, "GPIOB", [15], 1, before=t_clk)
    moder = [e for e in log.events if e.t < t_clk and e.periph in ("GPIOA", "GPIOB") and e.reg == "MODER"]
    ok = valves is not None and drivers is not None
    fig = "valves PA0..PA3 driven low by %s, drivers disabled (PB15 high) by %s, %d MODER writes; first PLLCFGR/CFGR write at %s" % (
        ms(valves) if valves is not None else "NEVER", ms(drivers) if drivers is not None else "NEVER", len(moder), ms(t_clk))
    return "safe outputs before clock set-up", ok, fig


def check_clock_tree(m):
    emu = m["emu"]
    log = emu.log
    pll = log.find("RCC", "PLLCFGR")
    cfgr = [e for e in log.find("RCC", "CFGR") if e.word & 3 == 2]
    acr = log.find("FLASH", "ACR")
    if not pll or not cfgr:
        return "clock tree 168/48 MHz", False, "PLLCFGR written %d times, CFGR with SW=PLL %d times" % (len(pll), len(cfgr))
    p = pll[-1].word
    src, mdiv, n, pdiv, q = (p >> 22) & 1, p & 0x3F, (p >> 6) & 0x1FF, 2 * (((p >> 16) & 3) + 1), (p >> 24) & 0xF
    c = cfgr[0].word
    sw, hpre, ppre1, ppre2 = c & 3, (c >> 4) & 0xF, (c >> 10) & 7, (c >> 13) & 7
    lat_before = [e for e in acr if e.t <= cfgr[0].t]
    lat = lat_before[-1].word & 0xF if lat_before else None
    vco = 8_000_000 // max(mdiv, 1) * n
    sysclk, usb = vco // pdiv, vco // max(q, 1)
    apb = {0: 1, 4: 2, 5: 4, 6: 8, 7: 16}
    ok = (src == 1 and mdiv == 4 and n == 168 and pdiv == 2 and q == 7 and sw == 2 and hpre == 0
          and apb.get(ppre1) == 4 and apb.get(ppre2) == 2 and lat == 5)
    fig = ("PLLCFGR 0x%08x: %s/%d*%d/%d = %d MHz, Q=%d -> %d MHz; CFGR 0x%08x: SW=%d AHB/%d APB1/%s APB2/%s; "
           "ACR latency %s WS before the switch" % (p, "HSE" if src else "HSI", mdiv, n, pdiv, sysclk // 1_000_000, q,
                                                  usb // 1_000_000, c, sw, 1 if hpre < 8 else 2 ** (hpre - 7),
                                                  apb.get(ppre1, "?"), apb.get(ppre2, "?"), lat))
    return "clock tree 168 MHz core, 48 MHz USB", ok, fig


def check_flash_accelerator(m):
    acr = m["emu"].chip.values.get(0x40023C00, 0)
    bits = {"PRFTEN": 8, "ICEN": 9, "DCEN": 10}
    ok = all(acr >> b & 1 for b in bits.values())
    fig = "FLASH_ACR = 0x%08x: %s, latency %d" % (acr, " ".join("%s=%d" % (k, acr >> b & 1) for k, b in bits.items()), acr & 0xF)
    return "flash accelerator (prefetch, I- and D-cache)", ok, fig


def check_watchdog_setup(m):
    log = m["emu"].log
    kr = log.find("IWDG", "KR")
    keys = [e.value for e in kr]
    try:
        t_start = next(e.t for e in kr if e.value == 0xCCCC)
        t_unlock = next(e.t for e in kr if e.value == 0x5555 and e.t >= t_start)
    except StopIteration:
        return "watchdog started and configured", False, "IWDG KR writes: %s" % ([hex(k) for k in keys[:6]] or "none")
    pr = log.find("IWDG", "PR", after=t_unlock)
    rlr = log.find("IWDG", "RLR", after=t_unlock)
    ok = bool(pr and rlr)
    t_loop = log.marks.get("control loop")
    early = [e for e in kr if e.value == 0xAAAA and (t_loop is None or e.t < t_loop)]
    fig = "KR 0xCCCC at %s, 0x5555 at %s" % (ms(t_start), ms(t_unlock))
    if ok:
        div = 4 << (pr[0].word & 7)
        fig += ", PR=%d (/%d), RLR=%d: timeout %.0f ms at LSI 32 kHz" % (
            pr[0].word, div, rlr[0].word, rlr[0].word * div / 32.0)
    fig += "; %d feed(s) before the control loop started" % len(early)
    return "watchdog started and configured", ok, fig


def check_watchdog_feeds(m):
    w = m.get("wdg_window")
    if not w:
        return "watchdog fed at the control loop's pace", False, "not measured (%s)" % m.get("fault_in_run", m["boot"])
    rate = w["feeds"] / (w["dt"] / 1e9) if w["dt"] else 0
    per = w["periods"] if w["periods"] is not None else w["ticks"] / 10.0
    ratio = w["feeds"] / per if per else 0
    ok = w["feeds"] >= 10 and abs(ratio - 1) <= 0.05
    fig = "%d feeds (KR 0xAAAA) in %s = %.3f kHz; control periods in the window %s (%.3f feeds a period)" % (
        w["feeds"], ms(w["dt"]), rate / 1e3, per, ratio)
    return "watchdog fed at the control loop's pace", ok, fig


def check_watchdog_stops(m):
    s = m.get("wdg_stopped")
    if not s:
        return "feeds stop with the control loop", False, "not measured"
    ok = s["feeds"] <= 1 and s["ticks"] > 0 and (s["periods"] is None or s["periods"] <= 1) and s["dt"] >= 0.25e9
    fig = "UART5 disabled in the NVIC: %d feeds in %s while the step timer ticked %d times" % (
        s["feeds"], ms(s["dt"]), s["ticks"])
    return "feeds stop with the control loop", ok, fig


def check_rates(m, args):
    r = m.get("run")
    out = []
    if not r:
        return [("step interrupt 100 kHz", False, "not measured"), ("control loop 10 kHz", False, "not measured")]
    secs = r["dt"] / 1e9
    long_enough = secs >= args.seconds * 0.999
    if not long_enough:
        why = m.get("fault_in_run") or "%.3f s of %.1f s" % (secs, args.seconds)
        return [("step interrupt (TIM3) 100 kHz", False, "not measured (%s)" % why),
                ("control loop (UART5) 10 kHz", False, "not measured (%s)" % why)]
    tol = args.rate_tolerance
    step = r["ticks"] / secs if secs else 0
    ok = long_enough and abs(step / 100_000 - 1) <= tol
    out.append(("step interrupt (TIM3) 100 kHz", ok, "%.3f kHz over %.3f s of virtual time (%d ticks, step::TICKS)" % (
        step / 1e3, secs, r["ticks"])))
    if r["periods"] is not None:
        ctl, how, span = r["periods"] / secs if secs else 0, "control::PERIODS, %d periods" % r["periods"], secs
    elif "bp_periods" in r:
        n, dt = r["bp_periods"]
        ctl, how, span = n / (dt / 1e9) if dt else 0, "breakpoint count, %d entries (no control::PERIODS)" % n, dt / 1e9
    else:
        ctl, how, span = 0, "not measured", 0
    ok = long_enough and abs(ctl / 10_000 - 1) <= tol
    out.append(("control loop (UART5) 10 kHz", ok, "%.3f kHz over %.3f s (%s)" % (ctl / 1e3, span, how)))
    return out


def check_stack(m, args):
    used = m.get("stack_used")
    if used is None:
        return "stack high-water mark", False, "not measured"
    gate = int(STACK_SIZE * args.stack_gate)
    ok = used <= gate
    emu = m["emu"]
    fig = "%d B used of the 64 KiB stack (%.1f %%; gate %d B = %.0f %%)" % (used, 100.0 * used / STACK_SIZE, gate, 100 * args.stack_gate)
    if emu.stack_crossing:
        fig += "; went past 64 KiB (the CCM's end) in %s" % emu.stack_crossing
    if used >= m["stack_painted"] - 1024:
        fig += "; it reached the statics (all %d B between them and the top of SRAM)" % m["stack_painted"]
    return "stack high-water mark", ok, fig


def check_fault(m, kind):
    name = {"hardfault": "HardFault ends safe", "panic": "panic ends safe"}[kind]
    emu = m["emu"]
    if m["boot"] != "control loop":
        return name, False, "did not boot to the control loop (%s)" % m["boot"]
    if "t_fault" not in m:
        return name, False, m.get("how", "not run")
    t0 = m["t_fault"]
    handler = [h for h in emu.bp_hits if h[1] >= t0 and h[0] in ("HardFault", "panic", "DefaultHandler")]
    closed = driven_to(emu.log.events, "GPIOA", range(4), 0, after=t0)
    disabled = driven_to(emu.log.events, "GPIOB", [15], 1, after=t0)
    final_ok = all(emu.chip.pin("GPIOA", i) == 0 for i in range(4)) and emu.chip.pin("GPIOB", 15) == 1
    ok = closed is not None and disabled is not None and final_ok
    fig = "%s; handler %s; valves closed %s, drivers disabled %s after the fault; now %s" % (
        m["how"], "/".join(sorted({h[0] for h in handler})) or "NOT ENTERED",
        ms(closed - t0) if closed is not None else "NEVER", ms(disabled - t0) if disabled is not None else "NEVER",
        m["after"])
    if m.get("why") == "Reset":
        fig += "; the chip then reset"
    return name, ok, fig


# --------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser(description="Runs the dollop firmware image on QEMU and checks what the chip does.")
    ap.add_argument("--elf", required=True)
    ap.add_argument("--seconds", type=float, default=5.0, help="virtual seconds for the rate measurement (default 5)")
    ap.add_argument("--keep-log", metavar="DIR", help="keep the register-write logs and QEMU output in DIR")
    ap.add_argument("--tools", required=True, help="directory with llvm-nm and llvm-objdump")
    ap.add_argument("--qemu", default="qemu-system-arm")
    ap.add_argument("--icount-shift", type=int, default=3)
    ap.add_argument("--feeds", type=int, default=200, help="watchdog feeds to time (default 200)")
    ap.add_argument("--stopped-seconds", type=float, default=0.3)
    ap.add_argument("--rate-tolerance", type=float, default=0.005)
    ap.add_argument("--stack-gate", type=float, default=0.75)
    ap.add_argument("--boot-wall", type=float, default=60.0)
    ap.add_argument("--run-wall", type=float, default=150.0)
    ap.add_argument("--fault-wall", type=float, default=2.0)
    ap.add_argument("--only", choices=["main", "hardfault", "panic", "silicon"], action="append",
                    help="silicon: the real-chip checks of scripts/emulator/silicon.py")
    fil = ap.add_argument_group("firmware in the loop (--job): `dollop send` over the emulated UART4, pins "
                                "against `dollop simulate --model-only`")
    fil.add_argument("--job", help="job file (.dlp) to print; runs the firmware-in-the-loop scenarios")
    fil.add_argument("--config", help="its machine config (TOML)")
    fil.add_argument("--fil", action="append", choices=FIL_SCENARIOS,
                     help="scenario to run (repeatable; default: %s; serve: the dashboard, `dollop serve`, "
                          "slices --design and prints it through its HTTP API)" % ", ".join(FIL_DEFAULT))
    fil.add_argument("--design", help="serve: the design the job was sliced from (uploaded to the dashboard)")
    fil.add_argument("--slice-options", default="{}",
                     help="serve: the Design page's slicing options as it posts them (JSON), e.g. "
                          "'{\"width_mm\": 2.4, \"layers\": 2}'")
    fil.add_argument("--pause-at", type=float, default=0.3,
                     help="serve: pause (then resume) through the dashboard at this progress (0 or less: no pause)")
    fil.add_argument("--dollop", default="target/release/dollop", help="the host tool")
    fil.add_argument("--inset-mm", type=float, default=1.0,
                     help="power-up position: this far inside each axis's homing end (default 1)")
    fil.add_argument("--fault-after", type=int, default=8,
                     help="fault scenarios strike after this many valve writes of the print (default 8)")
    fil.add_argument("--job-wall", type=float, default=600.0, help="wall-time bound of one print (s)")
    fil.add_argument("--usb-workaround", dest="usb_workaround", action="store_true",
                     help="report USB OUT endpoints active: only for images from before the "
                          "EitherPort fix (see fil.Board.usb_workaround)")
    args = ap.parse_args()
    if args.job and not args.config:
        ap.error("--job needs --config")
    if args.fil and "serve" in args.fil and not args.design:
        ap.error("--fil serve needs --design (the file the job was sliced from)")

    log_dir = args.keep_log or tempfile.mkdtemp(prefix="dollop-emulate-")
    os.makedirs(log_dir, exist_ok=True)
    image = Image(args.elf, args.tools)
    print("emulate: %s on QEMU netduinoplus2, -icount shift=%d (%d ns an instruction)" % (
        args.elf, args.icount_shift, 1 << args.icount_shift), flush=True)
    results = []
    wall0 = time.monotonic()
    scen = args.only or ([] if args.job else ["main", "hardfault", "panic", "silicon"])
    summary = None
    try:
        run_scenarios(image, args, log_dir, scen, results)
        if args.job:
            from emulator import fil
            args.fil = args.fil or FIL_DEFAULT
            summary = fil.run(image, args, log_dir, results)
    except (TargetGone, RuntimeError, OSError) as e:
        print("emulate: error: %s" % e, file=sys.stderr)
        for em in EMULATORS:
            try:
                em.qemu_log.flush()
                with open(em.qemu_log.name) as f:
                    tail = f.read()[-2000:]
                if tail.strip():
                    print("emulate: QEMU (%s) said:\n%s" % (em.label, tail), file=sys.stderr)
            except OSError:
                pass
        results.append(("emulator ran to the end", False, str(e)))
    finally:
        for e in EMULATORS:
            e.kill()
        if args.job:
            from emulator import fil
            fil.kill_hosts()
    print()
    for name, ok, fig in results:
        print("%s  %-44s %s" % ("PASS" if ok else "FAIL", name, fig))
    failed = [r for r in results if not r[1]]
    print("\nemulate: %d checks, %d failed, %.1f s wall; %s" % (
        len(results), len(failed), time.monotonic() - wall0,
        "logs in %s" % log_dir if args.keep_log else "--keep-log DIR keeps the write logs"))
    if not args.keep_log:
        shutil.rmtree(log_dir, ignore_errors=True)
    if args.job:
        if failed:
            print("firmware in the loop: FAILED (%d of %d checks)" % (len(failed), len(results)))
        else:
            print(summary or "firmware in the loop: %d checks passed (no print compared)" % len(results))
    return 1 if failed else 0


def run_scenarios(image, args, log_dir, scen, results):
    if "main" in scen:
        m = scenario_main(image, args, log_dir)
        emu = m["emu"]
        results.append(check_boot(m))
        if m["boot"] == "control loop":
            results += [check_safe_before_clocks(m), check_clock_tree(m), check_flash_accelerator(m),
                        check_watchdog_setup(m)]
            results += check_rates(m, args)
            results += [check_watchdog_feeds(m), check_watchdog_stops(m)]
            if "fault_in_run" in m:
                h = emu.bp_hits[-1]
                results.append(("no fault while running", False, "%s at %s: %s" % (
                    h[0], ms(h[1]), getattr(emu, "fault_info", ""))))
        results.append(check_stack(m, args))
        if emu.tim3_fixed:
            f = emu.tim3_fixed
            print("emulate: TIM3 PSC=%d ARR=%d at the %d Hz timer clock the firmware configured: "
                  "QEMU's period set to %d ns (less its %d ns re-arm lag) at %s" % (
                      f["psc"], f["arr"], f["clk"], f["period_ns"], f["quantum"], ms(f["t"])))
        if "run" in m:
            print("emulate: %.2f s of virtual time in %.1f s of wall time" % (m["run"]["dt"] / 1e9, m["run"]["wall"]))
        for n in emu.notes:
            print("emulate: note: %s" % n)
        emu.log.dump(os.path.join(log_dir, "writes-main.csv"))
        emu.kill()
    for kind in ("hardfault", "panic"):
        if kind in scen:
            m = scenario_fault(image, args, log_dir, kind)
            results.append(check_fault(m, kind))
            m["emu"].log.dump(os.path.join(log_dir, "writes-%s.csv" % kind))
            m["emu"].kill()
    if "silicon" in scen:
        from emulator import silicon
        silicon.run(image, args, log_dir, results)


if __name__ == "__main__":
    # emulator/fil.py imports this module as `emulate`: the same one, not a second copy.
    sys.modules.setdefault("emulate", sys.modules["__main__"])
    sys.dont_write_bytecode = True  # no __pycache__ in scripts/
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    sys.exit(main())
