//! The link's server in a task, over USART2 (PA2 TX, PA3 RX, 460,800 baud 8N1) and,
//! with the feature `usb`, the USB socket (`usb.rs`): the same frames on both.
//!
//! Each transport moves bytes between its wire and two lock-free rings (a [`Port`]):
//! the USART's interrupt, below the tick's priority, and the USB task. The task here
//! wakes when a byte arrived or the tick queued an answer (each signals it), hands
//! the received bytes to the one server, lets it forward the tick's answers, and
//! queues the frames on the transport they answer. Nothing here runs in the tick,
//! which only takes a command from a lock-free queue. The USART's registers are
//! driven directly: its data register, its status flags and two interrupt enables
//! are all the link uses.

use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::gpio::{AfType, Flex, OutputType, Speed};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::{PA2, PA3, USART2};
use embassy_stm32::{interrupt, pac, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{with_timeout, Duration, Instant, Timer};
use heapless::spsc::{Consumer, Producer, Queue};
use sleeve_firmware::link::LinkServer;
use touch_protocol::link::MAX_ENCODED;

use super::flash::BankFlash;

/// Baud rate of the link's USART.
pub const BAUD: u32 = 460_800;

/// APB1, USART2's clock (see `board::config`).
const PCLK1_HZ: u32 = 42_000_000;

/// A frame begun on one transport and silent this long gives way to the other's.
const FRAME_IDLE: Duration = Duration::from_millis(100);

/// Bytes received and not yet taken by the task (0.5 ms at 460,800 baud is 23).
pub const RX_LEN: usize = 257;
/// Bytes waiting to be sent: two frames of the largest size, and events.
pub const TX_LEN: usize = 3 * touch_protocol::link::MAX_ENCODED;

/// Wakes the link's task: a byte arrived, or the tick has answers.
static WAKE: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Wakes the link's task: bytes arrived (USB), or the tick queued answers or wants
/// a player built (from the tick's follow-up interrupt, `tick.rs`).
#[inline(never)]
pub fn wake() {
    WAKE.signal(());
}

static mut RX: Queue<u8, RX_LEN> = Queue::new();
static mut TX: Queue<u8, TX_LEN> = Queue::new();
/// The interrupt's ends of the rings, set once before the interrupt is enabled.
static mut ISR_ENDS: Option<(Producer<'static, u8, RX_LEN>, Consumer<'static, u8, TX_LEN>)> = None;

/// The task's end of one transport: the bytes it received, the frames to send, and
/// how to tell its sender that some wait.
pub struct Port {
    /// Bytes from the wire.
    pub rx: Consumer<'static, u8, RX_LEN>,
    /// Frames to the wire.
    pub tx: Producer<'static, u8, TX_LEN>,
    /// Called after a frame was queued on `tx`.
    pub kick: fn(),
}

impl Port {
    /// True while the largest frame fits in the ring to the wire: the server reads
    /// a request, or takes an answer from the tick, only then, so that none is lost.
    fn has_room(&self) -> bool {
        self.tx.capacity() - self.tx.len() >= MAX_ENCODED
    }

    /// Queues a frame to send, whole or not at all (a frame that does not fit is
    /// dropped: the host times out and asks again, it never sees a wrong frame).
    fn send(&mut self, frame: &[u8]) {
        if self.tx.capacity() - self.tx.len() >= frame.len() {
            for &b in frame {
                // SAFETY: room was checked above.
                unsafe { self.tx.enqueue_unchecked(b) };
            }
            (self.kick)();
        }
    }
}

/// USART2's end of the link and its pins (kept so nothing else takes them).
pub struct Uart {
    port: Port,
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
            port: Port {
                rx: rx_end,
                tx: tx_end,
                kick: || pac::USART2.cr1().modify(|w| w.set_txeie(true)),
            },
            _pins: (tx_pin, rx_pin),
        }
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
        // Reading DR clears RXNE and the overrun flag.
        let byte = u.dr().read().dr() as u8;
        // SAFETY: only this handler touches the frame state.
        receive(byte, rx, unsafe { &mut *addr_of_mut!(RX_FRAME) });
        wake();
    }
    if sr.txe() && u.cr1().read().txeie() {
        match tx.dequeue() {
            Some(b) => u.dr().write(|w| w.set_dr(u16::from(b))),
            None => {
                u.cr1().modify(|w| w.set_txeie(false));
                // What waited for room to answer goes on.
                wake();
            }
        }
    }
}

/// Where the USART's handler is in the frame it receives.
#[derive(Clone, Copy, PartialEq, Eq)]
enum RxFrame {
    /// Between frames.
    Idle,
    /// The frame's bytes so far are in the ring.
    Kept,
    /// Some of its bytes are in the ring, the rest found it full: its end goes in
    /// (one place is kept free for it) and the server answers it unreadable.
    Cut,
    /// Its first byte found the ring full: dropped whole, counted in [`DROPPED`].
    Dropped,
}

static mut RX_FRAME: RxFrame = RxFrame::Idle;
/// Frames the USART's handler dropped whole (wrapping): each is answered
/// `Unreadable(Overrun)`, so that every request gets an answer.
static DROPPED: AtomicU32 = AtomicU32::new(0);

/// One byte from the wire into the ring, a frame at a time: a host faster than the
/// device's answers fills the ring (the server reads a frame only when it has room
/// to answer it), and what does not fit is dropped by frame, never a frame's end
/// alone (that would join two requests into one unreadable frame).
fn receive(byte: u8, rx: &mut Producer<'static, u8, RX_LEN>, state: &mut RxFrame) {
    // One place stays free for the end of a frame begun in the ring.
    let fits = rx.capacity() - rx.len() > 1;
    *state = match (*state, byte) {
        (RxFrame::Dropped, 0) => {
            DROPPED.fetch_add(1, Ordering::Relaxed);
            RxFrame::Idle
        }
        (_, 0) => {
            // Room is certain after a frame's bytes; an empty frame may be lost.
            let _ = rx.enqueue(0);
            RxFrame::Idle
        }
        (RxFrame::Idle | RxFrame::Kept, b) if fits => {
            let _ = rx.enqueue(b);
            RxFrame::Kept
        }
        (RxFrame::Idle, _) => RxFrame::Dropped,
        (RxFrame::Kept, _) => RxFrame::Cut,
        (other, _) => other,
    };
}

/// The link's transports: USART2, and the USB socket when built in (feature `usb`).
pub struct Transports {
    /// USART2.
    pub uart: Uart,
    /// The USB socket (`usb.rs`'s end of its rings).
    #[cfg(feature = "usb")]
    pub usb: Port,
}

/// Serves the link on every transport until a restart. The server's frame decoder
/// holds one transport's frame at a time: the other's bytes wait in its ring until
/// that frame ends (or its transport falls silent mid-frame, [`FRAME_IDLE`]). A
/// request is answered on the transport it came from; the tick's answers and events
/// go to the transport that last sent a frame.
#[embassy_executor::task]
pub async fn serve(transports: Transports, mut server: LinkServer<'static, BankFlash>) {
    let Transports {
        uart: Uart { port: uart, _pins },
        #[cfg(feature = "usb")]
        usb,
    } = transports;
    let mut ports = [
        uart,
        #[cfg(feature = "usb")]
        usb,
    ];
    // The transport whose frame the decoder holds, and when it last sent a byte.
    let mut owner: Option<usize> = None;
    let mut owner_heard = Instant::now();
    // The transport that gets the tick's answers and events.
    let mut last = 0;
    let mut batch = [0u8; RX_LEN];
    loop {
        // Woken by a byte, an answer, or a ring to the wire gone empty (what waited
        // for room there goes on); once a second anyway, for the upload timeout.
        let _ = with_timeout(Duration::from_secs(1), WAKE.wait()).await;
        for (i, port) in ports.iter_mut().enumerate() {
            if owner.is_some_and(|o| o != i) {
                continue;
            }
            if !port.has_room() {
                // Its requests wait (and hold their host back) until their answers
                // fit: the ring's sender wakes this task once it is empty.
                continue;
            }
            // Up to the end of a frame: the next frame may be the other transport's.
            let mut n = 0;
            while n < batch.len() {
                match port.rx.dequeue() {
                    Some(b) => batch[n] = b,
                    None => break,
                }
                n += 1;
                if batch[n - 1] == 0 {
                    break;
                }
            }
            if n == 0 {
                continue;
            }
            owner_heard = Instant::now();
            server.heard(owner_heard.as_millis());
            owner = (batch[n - 1] != 0).then_some(i);
            last = i;
            server.receive(&batch[..n], &mut |f: &[u8]| port.send(f));
            if port.rx.len() > 0 {
                // More than a batch, or a frame after this one: come back after a yield.
                wake();
            }
        }
        if let Some(o) = owner {
            let waiting = ports
                .iter()
                .enumerate()
                .any(|(i, p)| i != o && p.rx.len() > 0);
            if waiting && owner_heard.elapsed() > FRAME_IDLE {
                // The half frame ends here (answered as unreadable on its transport),
                // and the decoder is free for the other one.
                let port = &mut ports[o];
                server.receive(&[0], &mut |f: &[u8]| port.send(f));
                owner = None;
                wake();
            }
        }
        // The USART's dropped frames are answered on the transport of the tick's
        // answers: the last to send a frame, the USART's when it floods.
        server.dropped(DROPPED.load(Ordering::Relaxed));
        let port = &mut ports[last];
        while port.has_room() && server.poll_one(&mut |f: &[u8]| port.send(f)) {}
        // After a commit or an abort, or an upload abandoned by its host
        // (`sleeve_firmware::link::server::UPLOAD_IDLE_MS`): the task wakes at least
        // once a second to see it.
        if server.restart_due(Instant::now().as_millis()) {
            // Let the last reply leave: the USART's ring empties at 46 bytes per ms;
            // the USB one as the host reads, if it does (not waited for past 100 ms).
            let since = Instant::now();
            while ports.iter().any(|p| p.tx.len() > 0)
                && since.elapsed() < Duration::from_millis(100)
            {
                Timer::after_millis(1).await;
            }
            Timer::after_millis(20).await;
            defmt::info!("link: restarting into the bank in flash");
            cortex_m::peripheral::SCB::sys_reset();
        }
    }
}
