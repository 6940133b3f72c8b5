//! The link over the USB socket: a CDC-ACM serial port on OTG FS (PA11 DM, PA12 DP,
//! VBUS sensed on PA9, the 48 MHz clock from the PLL's Q output, see `board::config`),
//! carrying the same COBS frames as USART2 to the same server (`link::serve`).
//!
//! A task here moves bytes between the USB endpoints and a [`Port`]'s two rings, as
//! USART2's interrupt does for its own. It starts the USB core only once VBUS is on
//! PA9: before that no host listens, and the driver's first act, the core's soft
//! reset, spins until the core reports its AHB master idle; a core that never does
//! would stop every task on the executor there. After the start the driver follows
//! VBUS itself (plug and unplug). The twin models OTG FS (`twin/otg_fs.py`) and
//! enumerates this port with a scripted host (`twin/test_usb.py`).

use core::ptr::addr_of_mut;

use embassy_futures::join::join3;
use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::{PA11, PA12, PA9, USB_OTG_FS};
use embassy_stm32::usb::{self as otg, Driver};
use embassy_stm32::{bind_interrupts, interrupt, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::Timer;
use embassy_usb::class::cdc_acm::{CdcAcmClass, State};
use embassy_usb::Builder;
use heapless::spsc::{Consumer, Producer, Queue};

use super::link::{self, Port, RX_LEN, TX_LEN};
use super::otg::OtgDriver;

/// The USB ids, a build setting: `SLEEVE_USB_VID` and `SLEEVE_USB_PID` (hexadecimal,
/// e.g. `SLEEVE_USB_PID=0x5a01`) when the firmware is built, else pid.codes' vendor
/// id with its product id 0x0001, which pid.codes sets aside for testing (shared
/// with other devices). A sleeve that ships needs a product id of its own.
pub const USB_IDS: (u16, u16) = (
    hex_id(option_env!("SLEEVE_USB_VID"), 0x1209),
    hex_id(option_env!("SLEEVE_USB_PID"), 0x0001),
);

/// A 16-bit id from a build setting ("0x1209" or "1209"), else `default`; a value
/// that is not 1-4 hexadecimal digits stops the build.
const fn hex_id(setting: Option<&str>, default: u16) -> u16 {
    let Some(s) = setting else {
        return default;
    };
    let b = s.as_bytes();
    let mut i = if b.len() > 2 && b[0] == b'0' && (b[1] == b'x' || b[1] == b'X') {
        2
    } else {
        0
    };
    if b.len() == i || b.len() - i > 4 {
        panic!("SLEEVE_USB_VID / SLEEVE_USB_PID: 1 to 4 hexadecimal digits");
    }
    let mut v = 0u16;
    while i < b.len() {
        let d = match b[i] {
            c @ b'0'..=b'9' => c - b'0',
            c @ b'a'..=b'f' => c - b'a' + 10,
            c @ b'A'..=b'F' => c - b'A' + 10,
            _ => panic!("SLEEVE_USB_VID / SLEEVE_USB_PID: 1 to 4 hexadecimal digits"),
        };
        v = v * 16 + d as u16;
        i += 1;
    }
    v
}
/// The product string the port shows (`touchc sleeve list` prints it).
pub const PRODUCT: &str = "touchc sleeve";

/// Bytes in a full-speed bulk packet.
const PACKET: usize = 64;

bind_interrupts!(struct Irqs {
    OTG_FS => otg::InterruptHandler<USB_OTG_FS>;
});

/// Wakes the USB sender: frames wait in its ring.
static SEND: Signal<CriticalSectionRawMutex, ()> = Signal::new();

static mut RX: Queue<u8, RX_LEN> = Queue::new();
static mut TX: Queue<u8, TX_LEN> = Queue::new();

/// The USB peripheral and its pins, until VBUS comes.
pub struct Usb {
    /// The OTG FS core.
    pub otg: Peri<'static, USB_OTG_FS>,
    /// D-.
    pub dm: Peri<'static, PA11>,
    /// D+.
    pub dp: Peri<'static, PA12>,
    /// VBUS sense.
    pub vbus: Peri<'static, PA9>,
}

/// The USB task's ends of the rings.
pub struct Wire {
    rx: Producer<'static, u8, RX_LEN>,
    tx: Consumer<'static, u8, TX_LEN>,
}

/// The rings, split once: the server's end (the link's USB transport) and the USB
/// task's.
pub fn split() -> (Port, Wire) {
    // SAFETY: called once at boot (`hw::run`), so each ring is split once and each
    // end has one owner.
    let ((rx_prod, rx_cons), (tx_prod, tx_cons)) =
        unsafe { ((*addr_of_mut!(RX)).split(), (*addr_of_mut!(TX)).split()) };
    (
        Port {
            rx: rx_cons,
            tx: tx_prod,
            kick: || SEND.signal(()),
        },
        Wire {
            rx: rx_prod,
            tx: tx_cons,
        },
    )
}

/// The device's descriptor fields.
fn device_config() -> embassy_usb::Config<'static> {
    let mut config = embassy_usb::Config::new(USB_IDS.0, USB_IDS.1);
    config.manufacturer = Some("touchc");
    config.product = Some(PRODUCT);
    // The chip's 96-bit unique ID in hexadecimal: two sleeves on one computer are
    // told apart by it (`touchc sleeve list`).
    config.serial_number = Some(embassy_stm32::uid::uid_hex());
    // The sleeve has its own supply and only senses VBUS; the controller board may
    // still run from the cable, within 100 mA.
    config.self_powered = true;
    config.max_power = 100;
    config.max_packet_size_0 = PACKET as u8;
    config
}

/// Waits for VBUS, then runs the USB device and its CDC-ACM port for good.
#[embassy_executor::task]
pub async fn run(usb: Usb, wire: Wire) {
    let Usb { otg, dm, dp, vbus } = usb;
    // Kept as an input for good: the pull-down holds an unconnected PA9 low.
    let vbus = Input::new(vbus, Pull::Down);
    while vbus.is_low() {
        Timer::after_millis(100).await;
    }
    // Below the tick (the driver only enables the interrupt, at its reset priority 0).
    interrupt::OTG_FS.set_priority(Priority::P2);

    let mut ep_out = [0u8; 2 * PACKET];
    let mut otg_config = otg::Config::default();
    // Plug and unplug are followed through PA9 after the first start.
    otg_config.vbus_detection = true;
    let driver = OtgDriver(Driver::new_fs(otg, Irqs, dp, dm, &mut ep_out, otg_config));

    let config = device_config();
    let mut config_descriptor = [0u8; 128];
    let mut bos_descriptor = [0u8; 32];
    let mut control = [0u8; PACKET];
    let mut state = State::new();
    let mut builder = Builder::new(
        driver,
        config,
        &mut config_descriptor,
        &mut bos_descriptor,
        &mut [],
        &mut control,
    );
    let class = CdcAcmClass::new(&mut builder, &mut state, PACKET as u16);
    let mut device = builder.build();
    let (mut sender, mut receiver) = class.split();
    let Wire { mut rx, mut tx } = wire;

    let receive = async {
        let mut packet = [0u8; PACKET];
        loop {
            receiver.wait_connection().await;
            loop {
                // A packet is read only when it fits: the host's next one waits (NAK)
                // meanwhile, so no byte is dropped.
                while rx.capacity() - rx.len() < PACKET {
                    Timer::after_millis(1).await;
                }
                let Ok(n) = receiver.read_packet(&mut packet).await else {
                    break;
                };
                for &b in &packet[..n] {
                    // SAFETY: room for a whole packet was checked above.
                    unsafe { rx.enqueue_unchecked(b) };
                }
                link::wake();
            }
        }
    };
    let send = async {
        let mut packet = [0u8; PACKET];
        loop {
            sender.wait_connection().await;
            // What was queued while no host listened is stale: its requests were
            // answered to nobody, and the host has given up on them.
            while tx.dequeue().is_some() {}
            'connected: loop {
                SEND.wait().await;
                loop {
                    let mut n = 0;
                    while n < PACKET {
                        match tx.dequeue() {
                            Some(b) => packet[n] = b,
                            None => break,
                        }
                        n += 1;
                    }
                    if n == 0 {
                        // All sent: what waited for room to answer goes on.
                        link::wake();
                        break;
                    }
                    if sender.write_packet(&packet[..n]).await.is_err() {
                        break 'connected;
                    }
                    // A full packet does not end a transfer: a short (here empty)
                    // one does, so the host sees the last bytes now.
                    if n == PACKET && tx.len() == 0 && sender.write_packet(&[]).await.is_err() {
                        break 'connected;
                    }
                }
            }
        }
    };
    join3(device.run(), receive, send).await;
}
