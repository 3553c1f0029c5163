//! dollop's STM32F405 firmware: embassy glue around the board-independent
//! `dollop::device`. Interrupt priorities, highest first: e-stop (EXTI, forces the safe
//! state through registers), step pulses (TIM3, 100 kHz) and the host UART's receive
//! (UART4, at the same level: a byte lasts 10 us at 1 Mbaud and must be read before the
//! next one ends), the control loop (UART5 used as a software interrupt, pended every
//! 10th step tick), then USB and the thread-mode executor that runs the link. Boot order:
//! safe outputs before RAM is initialised (`preinit`), the brown-out level, the watchdog,
//! the crystal with a bounded wait (`boot`), then embassy's clocks. The control loop and the link share only `shared`'s
//! queues and snapshot. Pins and clocks come from `board`. The big state (control loop,
//! link) lives in statics built at compile time: nothing large is ever on the stack.
#![no_std]
#![no_main]

mod board;
mod boot;
mod control;
mod faults;
mod host;
mod line;
mod preinit;
mod shared;
mod step;
mod store;
mod wdg;

use control::{ControlCtx, PinOutputs};
use core::cell::RefCell;
use defmt_rtt as _;
use dollop::device::{BoardInfo, BoardLink, Control, ResetCause};
use dollop::wire;
use embassy_executor::Spawner;
use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::USB_OTG_FS;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::usb::Driver;
use embassy_stm32::{bind_interrupts, interrupt, pac, usart, usb};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_usb::class::cdc_acm::{CdcAcmClass, State};
use embassy_usb::UsbDevice;
use static_cell::StaticCell;
use step::Stepper;
use store::FlashStore;

bind_interrupts!(struct Irqs {
    OTG_FS => usb::InterruptHandler<USB_OTG_FS>;
    // The line-error count first: embassy's handler clears the flags it reads.
    UART4 => line::CountErrors, usart::BufferedInterruptHandler<embassy_stm32::peripherals::UART4>;
});

type UsbDriver = Driver<'static, USB_OTG_FS>;

/// What the board tells the host about itself.
const INFO: BoardInfo = BoardInfo {
    name: board::NAME,
    firmware: env!("CARGO_PKG_VERSION"),
    max_step_hz: board::MAX_STEP_HZ as f32,
    control_hz: board::CONTROL_HZ,
};

/// The control loop's state (58 KiB: the executor, its flow model and speed-ramp window)
/// and the link's (6 KiB: frame buffer, chunk window, reply queue), in `.bss`: all but
/// about 40 of their bytes are zeros, and a `const` initialiser would put them in `.data`,
/// whose whole image is stored in flash and copied at boot. Built in place at start
/// (`uninit().write`, from a value the compiler cannot fold into a constant), never on the
/// stack: `.ci/firmware-stack` fails on any frame over 4 KiB.
static CONTROL_STATE: StaticCell<Control> = StaticCell::new();
static LINK: StaticCell<BoardLink<FlashStore>> = StaticCell::new();

/// Handed to the interrupts once at start (a reference: the contexts live in statics).
static STEPPER: Mutex<CriticalSectionRawMutex, RefCell<Option<&'static mut Stepper>>> =
    Mutex::new(RefCell::new(None));
static CONTROL: Mutex<CriticalSectionRawMutex, RefCell<Option<&'static mut ControlCtx>>> =
    Mutex::new(RefCell::new(None));

#[interrupt]
fn TIM3() {
    static mut S: Option<&'static mut Stepper> = None;
    if S.is_none() {
        *S = STEPPER.lock(|c| c.borrow_mut().take());
    }
    if let Some(s) = S {
        if s.on_tick() {
            interrupt::UART5.pend();
        }
    }
}

#[interrupt]
fn UART5() {
    static mut C: Option<&'static mut ControlCtx> = None;
    if C.is_none() {
        *C = CONTROL.lock(|c| c.borrow_mut().take());
    }
    if let Some(c) = C {
        c.on_period();
    }
}

#[interrupt]
fn EXTI15_10() {
    let line = board::ESTOP.pin as usize;
    if pac::EXTI.pr(0).read().line(line) {
        pac::EXTI.pr(0).write(|w| w.set_line(line, true));
        // A spike shorter than the three samples is noise, not an e-stop; a real
        // opening that bounces raises another edge, and the control loop's filtered
        // level catches it regardless.
        if control::estop_confirmed() {
            control::estop_tripped();
        }
    }
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let (p, reset) = boot::start();
    let parts = board::parts(p);
    let mut out = PinOutputs {
        valves: parts.valves,
        enable: parts.enable,
    };
    let control = control_state(reset);
    control.power_up(&mut out);
    estop_interrupt();

    static CTX: StaticCell<ControlCtx> = StaticCell::new();
    let ctx = CTX.init(ControlCtx::new(
        control,
        out,
        parts.endstops,
        parts.estop,
        parts.led,
    ));
    CONTROL.lock(|c| *c.borrow_mut() = Some(ctx));

    let timer = Timer::new(parts.step_timer);
    timer.set_frequency(Hertz(board::STEP_TICK_HZ), RoundTo::Faster);
    timer.enable_update_interrupt(true);
    static STEP: StaticCell<Stepper> = StaticCell::new();
    let stepper = STEP.init(Stepper::new(timer, parts.step, parts.dir));
    stepper.timer.start();
    STEPPER.lock(|c| *c.borrow_mut() = Some(stepper));
    interrupt::EXTI15_10.set_priority(Priority::P0);
    interrupt::TIM3.set_priority(Priority::P1);
    interrupt::UART5.set_priority(Priority::P2);
    // SAFETY: the three handlers touch only what was handed to them above through the
    // critical-section mutexes, atomics and GPIO set/reset registers; no priority-based
    // locking exists in this firmware, so enabling them cannot break a critical section.
    unsafe {
        interrupt::EXTI15_10.enable();
        interrupt::TIM3.enable();
        interrupt::UART5.enable();
    }

    // USB CDC-ACM.
    static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
    let mut usb_config = usb::Config::default();
    // The board has its own supply: it must watch VBUS (PA9) to see the cable.
    usb_config.vbus_detection = true;
    let (otg, dp, dm) = parts.usb;
    let driver = Driver::new_fs(otg, Irqs, dp, dm, EP_OUT.init([0; 256]), usb_config);
    interrupt::OTG_FS.set_priority(Priority::P5);
    let mut dev_config = embassy_usb::Config::new(wire::USB_VID, wire::USB_PID);
    dev_config.manufacturer = Some("dollop");
    dev_config.product = Some(wire::USB_PRODUCT);
    // The chip's 96-bit unique ID: two boards on one host must be told apart.
    dev_config.serial_number = Some(embassy_stm32::uid::uid_hex());
    dev_config.self_powered = true;
    dev_config.max_power = 100;
    dev_config.max_packet_size_0 = 64;
    static CONFIG_DESC: StaticCell<[u8; 256]> = StaticCell::new();
    static BOS_DESC: StaticCell<[u8; 256]> = StaticCell::new();
    static CONTROL_BUF: StaticCell<[u8; 64]> = StaticCell::new();
    static CDC_STATE: StaticCell<State> = StaticCell::new();
    let mut builder = embassy_usb::Builder::new(
        driver,
        dev_config,
        CONFIG_DESC.init([0; 256]),
        BOS_DESC.init([0; 256]),
        &mut [],
        CONTROL_BUF.init([0; 64]),
    );
    let class = CdcAcmClass::new(
        &mut builder,
        CDC_STATE.init(State::new()),
        dollop::device::serve::PACKET as u16,
    );
    let usb = builder.build();

    // The host UART: the same protocol as USB, for boards wired to a host's serial port.
    static UART_TX: StaticCell<[u8; 1024]> = StaticCell::new();
    static UART_RX: StaticCell<[u8; 1024]> = StaticCell::new();
    let mut uart_config = usart::Config::default();
    uart_config.baudrate = board::HOST_UART_BAUD;
    // An unconnected or unpowered host leaves RX floating: noise would make garbage
    // frames (and switch the link's reply side to the UART).
    uart_config.rx_pull = Pull::Up;
    let (uart, rx, tx) = parts.uart;
    // With the step timer: above the control loop (whose tick is 7-12 us, longer than a
    // byte), below only the e-stop.
    interrupt::UART4.set_priority(Priority::P1);
    let uart = match usart::BufferedUart::new(
        uart,
        rx,
        tx,
        UART_TX.init([0; 1024]),
        UART_RX.init([0; 1024]),
        Irqs,
        uart_config,
    ) {
        Ok(u) => u,
        Err(_) => {
            defmt::error!("host UART: configuration refused");
            return;
        }
    };

    let link = link_state();
    link.store_mut().attach(parts.flash);
    match usb_task(usb) {
        Ok(t) => spawner.spawn(t),
        Err(_) => defmt::error!("usb task did not spawn"),
    }
    let port = dollop::device::serve::EitherPort::new(
        host::UsbPort::new(class),
        host::UartPort::new(uart),
    );
    match link_task(port, link) {
        Ok(t) => spawner.spawn(t),
        Err(_) => defmt::error!("link task did not spawn"),
    }
}

/// The control loop's state, built in its static (once: a second call panics). Out of
/// line, so that whatever the compiler stages on the stack while building it is in this
/// short-lived frame, not in the main task's.
#[inline(never)]
fn control_state(reset: ResetCause) -> &'static mut Control {
    CONTROL_STATE
        .uninit()
        .write(Control::new(core::hint::black_box(reset)))
}

/// The link's state, likewise.
#[inline(never)]
fn link_state() -> &'static mut BoardLink<FlashStore> {
    LINK.uninit().write(BoardLink::new(
        FlashStore::new(),
        core::hint::black_box(INFO),
    ))
}

/// E-stop on EXTI line 13, port C, rising edge (the normally-closed switch opens).
fn estop_interrupt() {
    let line = board::ESTOP.pin as usize;
    pac::RCC.apb2enr().modify(|w| w.set_syscfgen(true));
    pac::SYSCFG
        .exticr(line / 4)
        .modify(|w| w.set_exti(line % 4, board::ESTOP.port));
    pac::EXTI.rtsr(0).modify(|w| w.set_line(line, true));
    pac::EXTI.imr(0).modify(|w| w.set_line(line, true));
}

#[embassy_executor::task]
async fn usb_task(mut usb: UsbDevice<'static, UsbDriver>) -> ! {
    usb.run().await
}

/// The link over USB and the host UART: `dollop::device::serve`, paced by the control
/// loop's millisecond.
#[embassy_executor::task]
async fn link_task(
    mut port: dollop::device::serve::EitherPort<host::UsbPort<UsbDriver>, host::UartPort>,
    link: &'static mut BoardLink<FlashStore>,
) -> ! {
    dollop::device::serve(
        &mut port,
        &mut host::Millis::new(),
        link,
        &mut shared::LinkEnd,
    )
    .await
}
