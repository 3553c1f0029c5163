//! The dollop F405 board: the whole pin map, clocks and driver timing in one place, so
//! another board is one new module like this. Also the raw-register safe state used
//! before the HAL starts and from the panic handler, which own no pins.

use dollop::{Axis, Outputs};
use embassy_stm32::flash::Flash;
use embassy_stm32::gpio::{Input, Level, Output, Pull, Speed};
use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals::Moder;
use embassy_stm32::peripherals::{PA11, PA12, PC10, PC11, TIM3, UART4, USB_OTG_FS};
use embassy_stm32::rcc::{
    AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource,
    Sysclk,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::{Peri, Peripherals};

/// Board name the host sees.
pub const NAME: &str = "dollop-f405";

/// A GPIO by port (0 = A) and pin number, for register access without owning the pin.
#[derive(Clone, Copy)]
pub struct RawPin {
    /// Port index: 0 = GPIOA, 1 = GPIOB, 2 = GPIOC.
    pub port: u8,
    /// Pin number.
    pub pin: u8,
}

const fn pa(pin: u8) -> RawPin {
    RawPin { port: 0, pin }
}
const fn pc(pin: u8) -> RawPin {
    RawPin { port: 2, pin }
}
const fn pb(pin: u8) -> RawPin {
    RawPin { port: 1, pin }
}

// The pin map (`parts` below takes the same pins from the HAL).
// Step:  X PC6, Y PC7, Z PC8            (one port: cheap to drive together)
// Dir:   X PB12, Y PB13, Z PB14
// Syringe plungers (E axes, inlet order; unused on pneumatic machines):
//        step E0..E3 PB6, PB7, PB8, PB9;  dir E0..E3 PB0, PB1, PB10, PB11
// Enable (all drivers, active low): PB15, pulled up on the board
// Valves 0..3 (MOSFET gates, active high, pulled down on the board): PA0, PA1, PA2, PA3
// Endstops X/Y/Z (active low, internal pull-ups): PC0, PC1, PC2
// E-stop (normally closed to ground; open = stop, pull-up): PC13 -> EXTI13
// Status LED: PA5.  USB OTG FS: PA11 (D-), PA12 (D+), VBUS sense PA9.  HSE 8 MHz: PH0/PH1.
// Host UART (beside USB, same protocol): UART4, TX PC10, RX PC11 (AF8), 3.3 V levels.

/// Valve pins, inlet order.
pub const VALVES: [RawPin; 4] = [pa(0), pa(1), pa(2), pa(3)];
/// Driver enable pin (low = enabled).
pub const DRIVERS_EN: RawPin = pb(15);
/// E-stop input (high = stop, from the pull-up when the switch opens).
pub const ESTOP: RawPin = pc(13);
/// Status LED (high = on).
pub const LED: RawPin = pa(5);

/// STEP and DIR edge rate. Medium (RM0090 OSPEEDR 01; datasheet: about 10 ns rise and
/// fall into 50 pF) is two orders of magnitude faster than any driver needs (DRV8825:
/// 1.9 us high, 650 ns DIR set-up) and, unlike VeryHigh (about 4 ns), does not ring on
/// a driver cable long enough to double an edge.
const STEP_SPEED: Speed = Speed::Medium;

/// Stepper driver timing: the pulse generator's tick must cover all of it.
#[derive(Clone, Copy)]
pub struct DriverTiming {
    /// Minimum STEP high time, ns.
    pub min_high_ns: u32,
    /// Minimum STEP low time, ns.
    pub min_low_ns: u32,
    /// DIR setup before the STEP rising edge, ns.
    pub dir_setup_ns: u32,
}

// The presets a board picks from; each board uses one.
#[allow(dead_code)]
impl DriverTiming {
    /// Trinamic TMC2209 (datasheet: tSH, tSL > 100 ns; tDSU 20 ns).
    pub const TMC2209: DriverTiming = DriverTiming {
        min_high_ns: 100,
        min_low_ns: 100,
        dir_setup_ns: 20,
    };
    /// Allegro A4988 (1 us high and low, 200 ns setup).
    pub const A4988: DriverTiming = DriverTiming {
        min_high_ns: 1_000,
        min_low_ns: 1_000,
        dir_setup_ns: 200,
    };
    /// TI DRV8825 (1.9 us high and low, 650 ns setup).
    pub const DRV8825: DriverTiming = DriverTiming {
        min_high_ns: 1_900,
        min_low_ns: 1_900,
        dir_setup_ns: 650,
    };
}

/// The drivers fitted to this board (the slowest of the three is a safe default).
pub const DRIVER: DriverTiming = DriverTiming::DRV8825;

/// Stepped axes: X, Y, Z and one plunger (E) per inlet, in `Axis::index` order.
pub const STEPPED_AXES: usize = 3 + VALVES.len();

/// Step generator tick: every STEP edge falls on one. A pulse is one tick high and at
/// least one low, so 100 kHz gives 50 kHz per axis, and 10 us covers every driver above.
pub const STEP_TICK_HZ: u32 = 100_000;
/// Step generator ticks per control period.
pub const TICKS_PER_PERIOD: u32 = 10;
/// The control loop's rate, Hz: the link refuses configs that ask for another.
pub const CONTROL_HZ: u32 = STEP_TICK_HZ / TICKS_PER_PERIOD;
/// Most pulses per axis in one control period: ticks 1, 3, 5, 7, 9 (tick 0 sets DIR).
pub const PULSES_PER_PERIOD: u32 = TICKS_PER_PERIOD / 2;
/// Highest step rate per axis, steps/s.
pub const MAX_STEP_HZ: u32 = STEP_TICK_HZ / 2;
const TICK_NS: u32 = 1_000_000_000 / STEP_TICK_HZ;
const _: () = assert!(TICK_NS >= DRIVER.min_high_ns);
const _: () = assert!(TICK_NS >= DRIVER.min_low_ns);
const _: () = assert!(TICK_NS >= DRIVER.dir_setup_ns);

/// Baud rate of the host UART (8 data bits, no parity, one stop bit). UART4 runs from
/// APB1 at 42 MHz, so 1 Mbaud is an exact divisor (BRR 42, 16 times oversampling).
pub const HOST_UART_BAUD: u32 = 1_000_000;

/// Core clock, Hz (`clocks` below).
pub const CORE_HZ: u32 = 168_000_000;

/// Clocks: 168 MHz from the 8 MHz crystal; 48 MHz for USB from the same PLL.
pub fn clocks() -> embassy_stm32::Config {
    let mut c = embassy_stm32::Config::default();
    c.rcc.hse = Some(Hse {
        freq: Hertz(8_000_000),
        mode: HseMode::Oscillator,
    });
    c.rcc.pll_src = PllSource::HSE;
    c.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV4,   // 2 MHz
        mul: PllMul::MUL168,       // 336 MHz VCO
        divp: Some(PllPDiv::DIV2), // 168 MHz system clock
        divq: Some(PllQDiv::DIV7), // 48 MHz USB
        divr: None,
    });
    c.rcc.ahb_pre = AHBPrescaler::DIV1;
    c.rcc.apb1_pre = APBPrescaler::DIV4; // 42 MHz (timers 84 MHz)
    c.rcc.apb2_pre = APBPrescaler::DIV2; // 84 MHz
    c.rcc.sys = Sysclk::PLL1_P;
    c
}

/// The GPIO port of `p`.
pub fn port(p: RawPin) -> pac::gpio::Gpio {
    match p.port {
        0 => pac::GPIOA,
        1 => pac::GPIOB,
        _ => pac::GPIOC,
    }
}

/// Drives a pin through its set/reset register (one write, safe from any context).
pub fn write(p: RawPin, high: bool) {
    port(p).bsrr().write(|w| {
        if high {
            w.set_bs(p.pin as usize, true)
        } else {
            w.set_br(p.pin as usize, true)
        }
    });
}

/// Turns on the flash accelerator (ART: prefetch, instruction and data caches). embassy
/// sets only the wait states; without this, code runs from flash at 5 wait states,
/// uncached, several times slower than the control loop's instruction counts suggest.
pub fn flash_accelerator_on() {
    pac::FLASH.acr().modify(|w| {
        w.set_prften(true);
        w.set_icen(true);
        w.set_dcen(true);
    });
}

// The safe state at reset is `preinit`'s: valves low, drivers disabled, before RAM is
// initialised.

/// Makes the status LED an output (for `boot::clock_fault`, which runs before the HAL).
pub fn led_raw_init() {
    pac::RCC.ahb1enr().modify(|w| w.0 |= 1 << LED.port);
    port(LED)
        .moder()
        .modify(|w| w.set_moder(LED.pin as usize, Moder::OUTPUT));
}

/// Drives the status LED through its set/reset register.
pub fn led_raw(on: bool) {
    write(LED, on);
}

/// The safe state through registers only: for the panic and e-stop handlers.
pub fn force_safe_raw() {
    dollop::device::force_safe(&mut RawOutputs);
}

/// `Outputs` on raw registers, owning nothing; valves and drivers only (steps are moot
/// with the drivers off).
pub struct RawOutputs;

impl Outputs for RawOutputs {
    fn step(&mut self, _axis: Axis, _forward: bool, _count: u32) {}
    fn valve(&mut self, inlet: u8, open: bool) {
        if let Some(p) = VALVES.get(inlet as usize) {
            write(*p, open);
        }
    }
    fn drivers(&mut self, enabled: bool) {
        write(DRIVERS_EN, !enabled);
    }
}

/// The board's peripherals, as the firmware uses them.
pub struct Parts {
    /// Valve outputs, inlet order, closed.
    pub valves: [Output<'static>; 4],
    /// Driver enable, disabled.
    pub enable: Output<'static>,
    /// STEP X, Y, Z, E0..E3.
    pub step: [Output<'static>; STEPPED_AXES],
    /// DIR X, Y, Z, E0..E3.
    pub dir: [Output<'static>; STEPPED_AXES],
    /// Endstops X, Y, Z (low = triggered).
    pub endstops: [Input<'static>; 3],
    /// E-stop (high = stop).
    pub estop: Input<'static>,
    /// Status LED (high = on), off.
    pub led: Output<'static>,
    /// Step tick timer.
    pub step_timer: Peri<'static, TIM3>,
    /// USB OTG FS and its pins (D+, D-).
    pub usb: (
        Peri<'static, USB_OTG_FS>,
        Peri<'static, PA12>,
        Peri<'static, PA11>,
    ),
    /// The host UART and its pins (RX, TX).
    pub uart: (
        Peri<'static, UART4>,
        Peri<'static, PC11>,
        Peri<'static, PC10>,
    ),
    /// Flash, for the job store.
    pub flash: Flash<'static, embassy_stm32::flash::Blocking>,
}

/// Takes the pins of the map above from the HAL, outputs in their safe levels.
pub fn parts(p: Peripherals) -> Parts {
    Parts {
        valves: [
            Output::new(p.PA0, Level::Low, Speed::Low),
            Output::new(p.PA1, Level::Low, Speed::Low),
            Output::new(p.PA2, Level::Low, Speed::Low),
            Output::new(p.PA3, Level::Low, Speed::Low),
        ],
        enable: Output::new(p.PB15, Level::High, Speed::Low),
        step: [
            Output::new(p.PC6, Level::Low, STEP_SPEED),
            Output::new(p.PC7, Level::Low, STEP_SPEED),
            Output::new(p.PC8, Level::Low, STEP_SPEED),
            Output::new(p.PB6, Level::Low, STEP_SPEED),
            Output::new(p.PB7, Level::Low, STEP_SPEED),
            Output::new(p.PB8, Level::Low, STEP_SPEED),
            Output::new(p.PB9, Level::Low, STEP_SPEED),
        ],
        dir: [
            Output::new(p.PB12, Level::Low, STEP_SPEED),
            Output::new(p.PB13, Level::Low, STEP_SPEED),
            Output::new(p.PB14, Level::Low, STEP_SPEED),
            Output::new(p.PB0, Level::Low, STEP_SPEED),
            Output::new(p.PB1, Level::Low, STEP_SPEED),
            Output::new(p.PB10, Level::Low, STEP_SPEED),
            Output::new(p.PB11, Level::Low, STEP_SPEED),
        ],
        endstops: [
            Input::new(p.PC0, Pull::Up),
            Input::new(p.PC1, Pull::Up),
            Input::new(p.PC2, Pull::Up),
        ],
        estop: Input::new(p.PC13, Pull::Up),
        led: Output::new(p.PA5, Level::Low, Speed::Low),
        step_timer: p.TIM3,
        usb: (p.USB_OTG_FS, p.PA12, p.PA11),
        uart: (p.UART4, p.PC11, p.PC10),
        flash: Flash::new_blocking(p.FLASH),
    }
}
