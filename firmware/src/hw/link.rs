//! The link over USART2 (PA2 TX, PA3 RX, 460,800 baud 8N1): the server in a task.
//!
//! The USART's interrupt, below the tick's priority, moves bytes between the data
//! register and two lock-free rings; the task wakes when a byte arrived or the tick
//! queued an answer (each signals it), hands the received bytes to the server, lets
//! it forward the tick's answers, and queues the frames for the interrupt to send. Nothing here runs in the tick, which only takes
//! a command from a lock-free queue. The registers are driven directly: the USART's
//! data register, its status flags and two interrupt enables are all the link uses.

use core::ptr::addr_of_mut;

use embassy_stm32::gpio::{AfType, Flex, OutputType, Speed};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::{PA2, PA3, USART2};
use embassy_stm32::{interrupt, pac, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{with_timeout, Duration, Instant, Timer};
use heapless::spsc::{Consumer, Producer, Queue};
use sleeve_firmware::link::LinkServer;

use super::flash::BankFlash;

/// Baud rate of the link's USART.
pub const BAUD: u32 = 460_800;

/// APB1, USART2's clock (see `board::config`).
const PCLK1_HZ: u32 = 42_000_000;

/// An upload idle this long is abandoned: the host is gone, and the device restarts
/// into the built-in bank rather than stay locked.
const UPLOAD_IDLE: Duration = Duration::from_secs(30);

/// Bytes received and not yet taken by the task (0.5 ms at 460,800 baud is 23).
const RX_LEN: usize = 257;
/// Bytes waiting to be sent: two frames of the largest size, and events.
const TX_LEN: usize = 3 * touch_protocol::link::MAX_ENCODED;

/// Wakes the link's task: a byte arrived, or the tick has answers.
static WAKE: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Wakes the link's task (from the tick, when it queued answers).
pub fn wake() {
    WAKE.signal(());
}

static mut RX: Queue<u8, RX_LEN> = Queue::new();
static mut TX: Queue<u8, TX_LEN> = Queue::new();
/// The interrupt's ends of the rings, set once before the interrupt is enabled.
static mut ISR_ENDS: Option<(Producer<'static, u8, RX_LEN>, Consumer<'static, u8, TX_LEN>)> = None;

/// The task's ends of the rings and the pins (kept so nothing else takes them).
pub struct Uart {
    rx: Consumer<'static, u8, RX_LEN>,
    tx: Producer<'static, u8, TX_LEN>,
    _pins: (Flex<'static>, Flex<'static>),
}

impl Uart {
    /// Configures USART2 and its pins; enables its interrupt at a lower priority than
    /// the tick's. Called once.
    pub fn new(
        _usart: Peri<'static, USART2>,
        tx: Peri<'static, PA2>,
        rx: Peri<'static, PA3>,
    ) -> Self {
        embassy_stm32::rcc::enable_and_reset::<USART2>();
        let mut tx_pin = Flex::new(tx);
        tx_pin.set_as_af_unchecked(7, AfType::output(OutputType::PushPull, Speed::Medium));
        let mut rx_pin = Flex::new(rx);
        rx_pin.set_as_af_unchecked(7, AfType::input(embassy_stm32::gpio::Pull::Up));
        let u = pac::USART2;
        u.brr()
            .write(|w| w.set_brr(((PCLK1_HZ + BAUD / 2) / BAUD) as u16));
        u.cr1().write(|w| {
            w.set_ue(true);
            w.set_te(true);
            w.set_re(true);
            w.set_rxneie(true);
        });
        // SAFETY: `new` runs once (it takes the USART2 singleton), before the
        // interrupt is enabled: the rings are split once and each end has one owner.
        let (rx_end, tx_end) = unsafe {
            let (rx_prod, rx_cons) = (*addr_of_mut!(RX)).split();
            let (tx_prod, tx_cons) = (*addr_of_mut!(TX)).split();
            *addr_of_mut!(ISR_ENDS) = Some((rx_prod, tx_cons));
            (rx_cons, tx_prod)
        };
        interrupt::USART2.set_priority(Priority::P2);
        // SAFETY: the handler below only touches its ring ends, set just above.
        unsafe { interrupt::USART2.enable() };
        Uart {
            rx: rx_end,
            tx: tx_end,
            _pins: (tx_pin, rx_pin),
        }
    }
}

/// Queues a frame to send, whole or not at all (a frame that does not fit is
/// dropped: the host times out and asks again, it never sees a wrong frame).
fn send(tx: &mut Producer<'static, u8, TX_LEN>, frame: &[u8]) {
    if tx.capacity() - tx.len() >= frame.len() {
        for &b in frame {
            // SAFETY: room was checked above.
            unsafe { tx.enqueue_unchecked(b) };
        }
        pac::USART2.cr1().modify(|w| w.set_txeie(true));
    }
}

#[interrupt]
fn USART2() {
    // SAFETY: set before the interrupt was enabled; only this handler uses them.
    let Some((rx, tx)) = (unsafe { (*addr_of_mut!(ISR_ENDS)).as_mut() }) else {
        return;
    };
    let u = pac::USART2;
    let sr = u.sr().read();
    if sr.rxne() || sr.ore() {
        // Reading DR clears RXNE and the overrun flag; a byte that finds the ring full
        // is dropped (the frame fails its CRC and the host retries).
        let byte = u.dr().read().dr() as u8;
        let _ = rx.enqueue(byte);
        WAKE.signal(());
    }
    if sr.txe() && u.cr1().read().txeie() {
        match tx.dequeue() {
            Some(b) => u.dr().write(|w| w.set_dr(u16::from(b))),
            None => u.cr1().modify(|w| w.set_txeie(false)),
        }
    }
}

/// Serves the link until a restart.
#[embassy_executor::task]
pub async fn serve(mut uart: Uart, mut server: LinkServer<'static, BankFlash>) {
    let mut heard = Instant::now();
    let mut batch = [0u8; RX_LEN];
    loop {
        // Woken by a byte or an answer; once a second anyway, for the upload timeout.
        let _ = with_timeout(Duration::from_secs(1), WAKE.wait()).await;
        let mut n = 0;
        while n < batch.len() {
            match uart.rx.dequeue() {
                Some(b) => batch[n] = b,
                None => break,
            }
            n += 1;
        }
        if n > 0 {
            heard = Instant::now();
        }
        let Uart { rx: _, tx, .. } = &mut uart;
        let mut out = |f: &[u8]| {
            send(tx, f);
        };
        server.receive(&batch[..n], &mut out);
        server.poll(&mut out);
        let abandoned = server.locked() && heard.elapsed() > UPLOAD_IDLE;
        if server.restart_requested() || abandoned {
            // Let the last reply leave: the ring empties at 46 bytes per ms.
            while uart.tx.len() > 0 {
                Timer::after_millis(1).await;
            }
            Timer::after_millis(20).await;
            defmt::info!("link: restarting into the bank in flash");
            cortex_m::peripheral::SCB::sys_reset();
        }
    }
}
