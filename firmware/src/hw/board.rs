//! The board: clocks and every pin, in this one file.
//!
//! | channel / use | pin  | peripheral           |
//! |---------------|------|----------------------|
//! | 0             | PA6  | TIM3 CH1 (AF2)       |
//! | 1             | PA7  | TIM3 CH2 (AF2)       |
//! | 2             | PB0  | TIM3 CH3 (AF2)       |
//! | 3             | PB1  | TIM3 CH4 (AF2)       |
//! | 4             | PB6  | TIM4 CH1 (AF2)       |
//! | 5             | PB7  | TIM4 CH2 (AF2)       |
//! | 6             | PB8  | TIM4 CH3 (AF2)       |
//! | 7             | PB9  | TIM4 CH4 (AF2)       |
//! | 0 (`dac-outputs`) | PA4 | DAC OUT1          |
//! | 1 (`dac-outputs`) | PA5 | DAC OUT2          |
//! | button 0      | PA0  | EXTI0, pull-down, active high (Olimex STM32-H405 "BUT") |
//! | buttons 1-3 (`button-per-slot`) | PC1, PC2, PC3 | EXTI1-3, pull-down, active high |
//! | status LED    | PC12 | GPIO, active high (Olimex STM32-H405 "STAT") |
//! | link TX       | PA2  | USART2 TX (AF7), to the host's RX |
//! | link RX       | PA3  | USART2 RX (AF7), from the host's TX |
//!
//! Channel numbering is the sleeve's: `channel = row * 4 + column`.

use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::{Level, Output, Pull, Speed};
use embassy_stm32::{bind_interrupts, interrupt, pac, Config, Peripherals};

use super::outputs::{OutputPin, Outputs, Pins};

const fn out(port: pac::gpio::Gpio, pin: usize) -> OutputPin {
    OutputPin { port, pin }
}

/// Alternate function of TIM3/TIM4 on every PWM pin below (AF2 on the F405).
const PWM_AF: u8 = 2;

/// Timer pins in channel order: TIM3 CH1-CH4, TIM4 CH1-CH4.
const TIMER_PINS: [OutputPin; 8] = [
    out(pac::GPIOA, 6),
    out(pac::GPIOA, 7),
    out(pac::GPIOB, 0),
    out(pac::GPIOB, 1),
    out(pac::GPIOB, 6),
    out(pac::GPIOB, 7),
    out(pac::GPIOB, 8),
    out(pac::GPIOB, 9),
];
/// The PWM pins in use: all eight, or channels 2-7 when 0-1 are on the DAC.
const PWM_PINS: &[OutputPin] = if cfg!(feature = "dac-outputs") {
    TIMER_PINS.split_at(2).1
} else {
    &TIMER_PINS
};
/// DAC pins of channels 0 and 1.
#[cfg(feature = "dac-outputs")]
const DAC_PINS: &[OutputPin] = &[out(pac::GPIOA, 4), out(pac::GPIOA, 5)];
/// The output stage's pins, as the table above has them.
const OUTPUT_PINS: Pins = Pins {
    pwm: PWM_PINS,
    pwm_af: PWM_AF,
    #[cfg(feature = "dac-outputs")]
    dac: DAC_PINS,
};

bind_interrupts!(
    /// EXTI lines of the buttons.
    pub struct Irqs {
        EXTI0 => exti::InterruptHandler<interrupt::typelevel::EXTI0>;
        EXTI1 => exti::InterruptHandler<interrupt::typelevel::EXTI1>;
        EXTI2 => exti::InterruptHandler<interrupt::typelevel::EXTI2>;
        EXTI3 => exti::InterruptHandler<interrupt::typelevel::EXTI3>;
    }
);

/// Number of buttons on this build.
#[cfg(not(feature = "button-per-slot"))]
pub const BUTTONS: usize = 1;
/// Number of buttons on this build.
#[cfg(feature = "button-per-slot")]
pub const BUTTONS: usize = 4;

/// How the buttons map to events on this build.
#[cfg(not(feature = "button-per-slot"))]
pub const BUTTON_MODE: sleeve_firmware::button::Mode = sleeve_firmware::button::Mode::PlayNext;
/// How the buttons map to events on this build.
#[cfg(feature = "button-per-slot")]
pub const BUTTON_MODE: sleeve_firmware::button::Mode = sleeve_firmware::button::Mode::PerSlot;

/// 168 MHz from the internal 16 MHz oscillator (no crystal assumed); APB1 at 42 MHz,
/// so TIM2-7 count at 84 MHz.
pub fn config() -> Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource, Sysclk,
    };
    let mut config = Config::default();
    config.rcc.hsi = true;
    config.rcc.pll_src = PllSource::HSI;
    config.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV8,
        mul: PllMul::MUL168,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    config.rcc.sys = Sysclk::PLL1_P;
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV4;
    config.rcc.apb2_pre = APBPrescaler::DIV2;
    config
}

/// The parts of the board the firmware uses, split out of the peripherals.
pub struct Board {
    /// The eight output channels, at 0 A.
    pub outputs: Outputs,
    /// The buttons, in slot order.
    pub buttons: [ExtiInput<'static, embassy_stm32::mode::Async>; BUTTONS],
    /// The status LED, off.
    pub led: Output<'static>,
    /// The independent watchdog (not started).
    pub iwdg: embassy_stm32::Peri<'static, embassy_stm32::peripherals::IWDG>,
    /// TIM7, the 1 kHz tick.
    pub tick: embassy_stm32::Peri<'static, embassy_stm32::peripherals::TIM7>,
    /// The link's USART, interrupt driven, below the tick's priority.
    pub link: super::link::Uart,
    /// The link's USB socket (started once VBUS comes, see `usb.rs`).
    #[cfg(feature = "usb")]
    pub usb: super::usb::Usb,
}

/// Takes the board's pins. The outputs come first and start at 0 A.
pub fn take(p: Peripherals) -> Board {
    // The output pins are configured by register in `Outputs::new`; taking their
    // singletons here keeps anything else from using them.
    #[cfg(not(feature = "dac-outputs"))]
    let _pins = (p.PA6, p.PA7, p.PB0, p.PB1, p.PB6, p.PB7, p.PB8, p.PB9);
    #[cfg(feature = "dac-outputs")]
    let _pins = (
        p.PA4, p.PA5, p.DAC1, p.PB0, p.PB1, p.PB6, p.PB7, p.PB8, p.PB9,
    );
    let outputs = Outputs::new(p.TIM3, p.TIM4, &OUTPUT_PINS);

    let led = Output::new(p.PC12, Level::Low, Speed::Low);
    #[cfg(not(feature = "button-per-slot"))]
    let buttons = [ExtiInput::new(p.PA0, p.EXTI0, Pull::Down, Irqs)];
    #[cfg(feature = "button-per-slot")]
    let buttons = [
        ExtiInput::new(p.PA0, p.EXTI0, Pull::Down, Irqs),
        ExtiInput::new(p.PC1, p.EXTI1, Pull::Down, Irqs),
        ExtiInput::new(p.PC2, p.EXTI2, Pull::Down, Irqs),
        ExtiInput::new(p.PC3, p.EXTI3, Pull::Down, Irqs),
    ];
    Board {
        outputs,
        buttons,
        led,
        iwdg: p.IWDG,
        tick: p.TIM7,
        link: super::link::Uart::new(p.USART2, p.PA2, p.PA3),
        #[cfg(feature = "usb")]
        usb: super::usb::Usb {
            otg: p.USB_OTG_FS,
            dm: p.PA11,
            dp: p.PA12,
            vbus: p.PA9,
        },
    }
}

/// Button level: pressed is high (pull-down, switch to 3.3 V).
pub fn pressed(button: &ExtiInput<'static, embassy_stm32::mode::Async>) -> bool {
    button.is_high()
}
