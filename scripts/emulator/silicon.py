"""Checks for what the real chip does that a plain boot in QEMU does not show (issue 24,
docs/bring-up.md): the registers the running image set, and boots the harness arranges to
go wrong. Run by emulate.py as the scenario `silicon` (`--only silicon`); every figure
comes from the emulated chip (register writes with their virtual time, registers read
back), never from the source. Stops at what QEMU can model: UART line errors, flash
stalls, brown-outs and the watchdog's reset itself are for the bench (docs/bring-up.md).

  nvic_and_pins(emu) a board 20 ms after its control loop started, every register write
                     watched: NVIC priorities of every interrupt the firmware enables,
                     read back from the NVIC; the UART4 RX pull-up and the STEP/DIR
                     output speed from the GPIO model (QEMU has no GPIO: the values the
                     firmware wrote).
  scenario_cold(...) boot 2, with the option bytes boot 1 (the overflow's) left and a dead
                     crystal (HSERDY never set): the valves and the driver enable are
                     driven safe before the first .data word is written; the BOR
                     option-byte write is not repeated; the boot ends in the clock fault
                     with the watchdog started before the crystal and never fed.
  scenario_overflow  boot 1 (factory option bytes): that board, then the stack exhausted in the control interrupt (SP
                     at the bottom of the memory it lives in): HardFault on its own stack,
                     outputs safe.
"""

import time

import emulate as E

NVIC_IPR = 0xE000E400
NVIC_ISER = 0xE000E100
# STM32F405 interrupt numbers (RM0090 Table 61).
IRQS = {"EXTI15_10": 40, "TIM3": 29, "UART4": 52, "UART5": 53, "TIM5": 50, "OTG_FS": 67}
SCB_SHCSR = 0xE000ED24
UART4_SR = 0x40004C00
UART4_IRQ = 52
NVIC_ISPR = 0xE000E200
SR_PE, SR_FE, SR_NE, SR_ORE = 1, 2, 4, 8
QEMU_SRAM_BASE = 0x20000000  # nothing mapped below it in QEMU (on the chip: the CCM's start)
STEP_DIR = {"GPIOC": [6, 7, 8], "GPIOB": [6, 7, 8, 9, 12, 13, 14, 0, 1, 10, 11]}
GPIO_BASE = {"GPIOA": 0x40020000, "GPIOB": 0x40020400, "GPIOC": 0x40020800}


def peek(emu, addr, size=4):
    """A register read through the gdb stub (QEMU answers for the NVIC)."""
    return int.from_bytes(emu.r.read(addr, size), "little")


def nvic_and_pins(emu):
    out = []
    prio = {}
    enabled = {}
    for name, n in IRQS.items():
        prio[name] = peek(emu, NVIC_IPR + n, 1) >> 4
        enabled[name] = bool(peek(emu, NVIC_ISER + 4 * (n // 32)) >> (n % 32) & 1)
    # Lower number = higher priority; equal priorities do not preempt each other.
    order_ok = (prio["EXTI15_10"] < min(prio["TIM3"], prio["UART4"])
                and max(prio["TIM3"], prio["UART4"]) < prio["UART5"]
                and prio["UART5"] < min(prio["TIM5"], prio["OTG_FS"]))
    ok = order_ok and all(enabled[k] for k in ("EXTI15_10", "TIM3", "UART4", "UART5"))
    out.append(("NVIC priorities read back", ok,
                ", ".join("%s %d%s" % (k, prio[k], "" if enabled[k] else " (disabled)") for k in IRQS)
                + "; e-stop above the step timer and UART4, both above the control loop (UART5), "
                  "USB and the time driver below: %s" % ("yes" if order_ok else "NO")))
    # GPIO configuration from the register model (the values the firmware wrote).
    vals = emu.chip.values
    pupdr_c = vals.get(GPIO_BASE["GPIOC"] + 0x0C, 0)
    pull = (pupdr_c >> 22) & 3
    out.append(("UART4 RX (PC11) pulled up", pull == 1, "GPIOC_PUPDR = 0x%08x: PC11 %s" % (
        pupdr_c, {0: "no pull", 1: "pull-up", 2: "pull-down", 3: "reserved"}[pull])))
    speeds = []
    for port, pins in STEP_DIR.items():
        ospeedr = vals.get(GPIO_BASE[port] + 0x08, 0)
        speeds += [(port, p, (ospeedr >> (2 * p)) & 3) for p in pins]
    names = {0: "low", 1: "medium", 2: "high", 3: "very high"}
    worst = max(s for _, _, s in speeds)
    out.append(("STEP/DIR outputs at a moderate slew rate", worst in (1, 2),
                "OSPEEDR of the %d STEP/DIR pins: %s" % (len(speeds), ", ".join(
                    sorted({names[s] for _, _, s in speeds})))))
    return out


def line_errors(emu, image):
    """QEMU's USART raises no line errors: the harness answers the next read of UART4's SR
    with overrun, framing and noise set (parity clear) and pends UART4; the firmware's
    counters (line::OVERRUN .. PARITY, read from RAM) must show one each, parity none."""
    names = ["OVERRUN", "FRAMING", "NOISE", "PARITY"]
    addrs = [image.sym("dollop_firmware::line::" + n) for n in names]
    if None in addrs:
        return ("UART4 line errors counted", False, "no counters in the image (%s)" % ", ".join(
            n for n, a in zip(names, addrs) if a is None))
    before = [emu.r.read32(a) for a in addrs]
    reads = []

    def on_sr(w, regs):
        pc = regs[15] & ~1
        acc, insn = emu.image.access_at(pc)
        emu.step_over(pc, w)
        if acc is not None and acc.kind == "ld" and not reads:
            for addr, size, rn in acc.transfers(regs):
                if addr & ~3 == UART4_SR:
                    emu.r.set_reg(rn, emu.r.regs()[rn] | SR_ORE | SR_FE | SR_NE)
                    reads.append(emu.image.function_at(pc))
        if reads:
            emu.unwatch(*w)

    emu.watch(UART4_SR, 4, on_sr)
    emu.poke(NVIC_ISPR + 4 * (UART4_IRQ // 32), 1 << (UART4_IRQ % 32))
    t0 = emu.now()
    emu.run(args_wall(emu), until=lambda: bool(reads) and emu.now() - t0 >= 1e6)
    emu.unwatch(UART4_SR, 4)
    after = [emu.r.read32(a) for a in addrs]
    delta = [b - a for a, b in zip(before, after)]
    ok = delta == [1, 1, 1, 0]
    return ("UART4 line errors counted", ok,
            "SR read as ORE|FE|NE once (in %s), UART4 pended: overrun +%d, framing +%d, noise +%d, parity +%d" % (
                reads[0] if reads else "NOT READ", *delta))


def args_wall(emu):
    return max(5.0, emu.args.fault_wall)


def scenario_cold(image, args, log_dir, optcr):
    """Boot 2: the option bytes from boot 1 (`optcr`), a crystal that never starts."""
    sdata = image.sym("__sdata")
    edata = image.sym("__edata")
    fault = image.sym("dollop_firmware::boot::clock_fault")

    def prepare(emu):
        emu.chip.hse_ok = False
        emu.chip.values[E.FLASH_OPTCR] = optcr
        if sdata is not None and edata is not None and edata > sdata:
            def on_data(w, regs):
                emu.log.mark("first .data write", emu.now())
                emu.data_writer = emu.image.function_at(regs[15] & ~1)
                emu.unwatch(*w)
            emu.watch(sdata, 4, on_data)

    emu = E.boot(image, args, log_dir, "cold", prepare=prepare, stops=[(fault, "clock fault")])
    m = dict(emu=emu, boot=emu.boot_result, sdata=sdata)
    if emu.boot_result == "clock fault":
        # Let it blink for a while: the watchdog must not be fed.
        emu.stop_at = E.FAULT_STOPS
        emu.feeds = 0
        t0 = emu.now()
        # The handler ends in a loop with no register writes (no stops): run in slices.
        wall = time.monotonic() + args.fault_wall * 5
        while emu.now() - t0 < 300e6 and time.monotonic() < wall:
            if emu.run(0.25) in E.FAULT_STOPS:
                break
        m["after_fault_ns"] = emu.now() - t0
        m["feeds_after"] = emu.feeds
    m["state"] = emu.outputs_state()
    return m


def check_cold(m, first_optcr_writes):
    emu = m["emu"]
    log = emu.log
    out = []
    # Safe before .data.
    t_data = log.marks.get("first .data write")
    if t_data is None:
        out.append(("safe outputs before .data is copied", False, "no write to __sdata seen (%s)" % (
            "no .data in the image" if m["sdata"] is None else "boot: %s" % m["boot"])))
    else:
        valves = E.driven_to(log.events, "GPIOA", range(4), 0, before=t_data)
        drivers = E.driven_to(log.events, "GPIOB", [15], 1, before=t_data)
        moder = {e.periph: e.word for e in log.events if e.t < t_data and e.reg == "MODER"
                 and e.periph in ("GPIOA", "GPIOB")}
        outputs = (all((moder.get("GPIOA", 0) >> (2 * p)) & 3 == 1 for p in range(4))
                   and (moder.get("GPIOB", 0) >> 30) & 3 == 1)
        ok = valves is not None and drivers is not None and outputs
        out.append(("safe outputs before .data is copied", ok,
                     "valves PA0..PA3 low by %s, drivers disabled (PB15 high) by %s, all five outputs: %s; "
                     "first .data word written at %s (%s)" % (
                         E.ms(valves) if valves is not None else "NEVER",
                         E.ms(drivers) if drivers is not None else "NEVER", "yes" if outputs else "NO",
                         E.ms(t_data), getattr(emu, "data_writer", "?"))))
    # BOR written once: on boot 1, not again on boot 2.
    again = [e for e in log.find("FLASH", "OPTCR") if e.value & 2]
    first = first_optcr_writes
    wrote = [e for e in first if e.value & 2 and (e.value >> 2) & 3 == 0]
    ok = len(wrote) == 1 and not again and (emu.chip.values.get(E.FLASH_OPTCR, 0) >> 2) & 3 == 0
    out.append(("BOR level 3 written once, not on the next boot", ok,
                "boot 1: %d OPTCR write(s) with OPTSTRT and BOR_LEV=00 (OPTCR 0x%08x after); boot 2 with those "
                "option bytes: %d OPTSTRT write(s)" % (
                    len(wrote), wrote[-1].word if wrote else 0, len(again))))
    # Dead crystal.
    kr = log.find("IWDG", "KR")
    t_wdg = next((e.t for e in kr if e.value == 0xCCCC), None)
    hseon = [e for e in log.find("RCC", "CR") if e.value >> 16 & 1]
    t_hse = hseon[0].t if hseon else None
    reached = m["boot"] == "clock fault"
    final_safe = all(emu.chip.pin("GPIOA", i) == 0 for i in range(4)) and emu.chip.pin("GPIOB", 15) == 1
    wait_ms = None
    if reached and t_hse is not None:
        hits = [h for h in emu.bp_hits if h[0] == "clock fault"]
        wait_ms = (hits[0][1] - t_hse) / 1e6 if hits else None
    ok = (reached and t_wdg is not None and t_hse is not None and t_wdg < t_hse and final_safe
          and m.get("feeds_after") == 0 and not log.find("RCC", "PLLCFGR"))
    out.append(("dead crystal: clock fault, watchdog left to reset", ok,
                "%s; watchdog started at %s, HSEON at %s, gave up after %s; then %s: %s IWDG feeds; "
                "PLL never configured: %s; %s" % (
                    "clock_fault reached" if reached else "boot ended: %s" % m["boot"],
                    E.ms(t_wdg) if t_wdg is not None else "NEVER", E.ms(t_hse) if t_hse is not None else "NEVER",
                    "%.1f ms" % wait_ms if wait_ms is not None else "?",
                    E.ms(m.get("after_fault_ns", 0)), m.get("feeds_after", "?"),
                    "yes" if not log.find("RCC", "PLLCFGR") else "NO", m["state"])))
    return out


def scenario_overflow(image, args, log_dir, m):
    """Boots, then in the control interrupt sets SP to the bottom of the memory the stack
    lives in (QEMU: SRAM's start; the chip: the CCM's start), with valve 0 open and the
    drivers enabled in the pin model: the handler's next push is an overflow. Fills m."""
    emu = E.boot(image, args, log_dir, "overflow")
    m.update(emu=emu, boot=emu.boot_result)
    if emu.boot_result != "control loop":
        return m
    # The rest of the set-up (USB, the host UART) runs after the control loop's first
    # period: 20 ms more with every write watched, then the registers are read back.
    emu.stop_at = E.FAULT_STOPS
    t0 = emu.now()
    why = emu.run(args.boot_wall, until=lambda: emu.now() - t0 >= 20e6)
    if why in E.FAULT_STOPS:
        m["boot"] = why
        return m
    m["registers"] = nvic_and_pins(emu)
    m["registers"].append(line_errors(emu, image))
    emu.stop_at = ("Reset",)
    emu.chip.outputs["GPIOA"] = emu.chip.outputs.get("GPIOA", 0) | 1
    emu.chip.outputs["GPIOB"] = emu.chip.outputs.get("GPIOB", 0) & ~(1 << 15)
    m["before"] = emu.outputs_state()
    emu.poke(E.NVIC_ICER + 4 * (E.TIM3_IRQ // 32), 1 << (E.TIM3_IRQ % 32))
    emu.watch_model({"GPIOA", "GPIOB", "GPIOC"})
    emu.r.set_reg(13, QEMU_SRAM_BASE)
    m["how"] = "SP := 0x%08x at the control interrupt's entry" % QEMU_SRAM_BASE
    m["t_fault"] = emu.now()
    emu.log.mark("fault forced", m["t_fault"])
    m["why"] = emu.run(args.fault_wall)
    m["after"] = emu.outputs_state()
    regs = emu.r.regs()
    m["sp_after"] = regs[13]
    fs = image.sym("dollop_firmware::faults::FAULT_STACK")
    m["fault_stack"] = fs
    return m


def check_overflow(m):
    name, ok, fig = E.check_fault(dict(m, **{"how": m.get("how", "not run")}), "hardfault")
    fs = m.get("fault_stack")
    sp = m.get("sp_after")
    on_own = fs is not None and sp is not None and fs <= sp <= fs + 512
    fig += "; SP now 0x%08x (%s)" % (sp or 0, "on the HardFault stack at 0x%08x" % fs if on_own else
                                     "NOT on the HardFault stack")
    return "stack overflow ends safe", ok and on_own, fig


def qemu_said(emu):
    """QEMU's own fatal message (a lockup ends QEMU), if it printed one."""
    try:
        emu.qemu_log.flush()
        with open(emu.qemu_log.name) as f:
            return next((l.strip() for l in f if "fatal" in l), "")
    except OSError:
        return ""


def run(image, args, log_dir, results):
    """Boot 1 (factory option bytes): the registers read back, then the overflow; boot 2
    with the option bytes boot 1 left and a dead crystal. A QEMU that dies (a lockup)
    fails the check it was running, not the others."""
    m = {}
    try:
        scenario_overflow(image, args, log_dir, m)
        overflow = check_overflow(m)
    except (E.TargetGone, RuntimeError) as e:
        overflow = ("stack overflow ends safe", False, "%s: %s" % (e, qemu_said(m["emu"]) if "emu" in m else ""))
    emu = m["emu"]
    first = emu.log.find("FLASH", "OPTCR")
    optcr = emu.chip.values.get(E.FLASH_OPTCR, E.RESET_VALUES[E.FLASH_OPTCR])
    results += m.get("registers") or [("NVIC priorities read back", False, "did not boot (%s)" % m.get("boot"))]
    results.append(overflow)
    emu.log.dump(log_dir + "/writes-overflow.csv")
    emu.kill()
    m = scenario_cold(image, args, log_dir, optcr)
    results += check_cold(m, first)
    m["emu"].log.dump(log_dir + "/writes-cold.csv")
    m["emu"].kill()
