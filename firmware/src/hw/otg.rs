//! embassy-stm32's OTG FS driver with its bulk endpoints' data toggles reset where
//! USB 2.0 requires: an endpoint's next packet is DATA0 after every
//! SET_CONFIGURATION (9.1.1.5) and after CLEAR_FEATURE(ENDPOINT_HALT) (9.4.5).
//!
//! The driver (embassy-usb-synopsys-otg 0.3) sets DATA0 only at a bus reset. A host
//! that sends either request (pyusb's `set_configuration()`, FreeBSD's clear-halt at
//! open) resets its own toggles; the sleeve kept its old ones, so the next OUT
//! packet looked like a retransmission and was dropped, and the next IN packet was
//! dropped by the host: a link request or its reply lost (`firmware/twin/test_usb.py`,
//! `DataToggles`). Here the driver's bus is wrapped: after embassy-usb enables an
//! endpoint (it does on every SET_CONFIGURATION) or clears its stall, the endpoint's
//! SD0PID bit is written (RM0090 34.16.4, OTG_FS_DIEPCTLx and OTG_FS_DOEPCTLx).
//! Both happen before the request's status stage, so no packet of the new
//! configuration can come first.

use embassy_stm32::peripherals::USB_OTG_FS;
use embassy_stm32::usb::Driver;
use embassy_usb::driver::{
    self as usb, Direction, EndpointAddress, EndpointAllocError, EndpointType, Event, Unsupported,
};

/// OTG FS's registers (RM0090 table 1).
const OTG_FS: usize = 0x5000_0000;
/// DIEPCTLx and DOEPCTLx: the first endpoint's, and the stride.
const DIEPCTL: usize = 0x900;
const DOEPCTL: usize = 0xB00;
const EP_STRIDE: usize = 0x20;
/// Endpoints 1-3 (endpoint 0's toggles the core sets itself at each SETUP).
const ENDPOINTS: usize = 4;
/// DxEPCTLx.SD0PID: sets the endpoint's data PID to DATA0.
const SD0PID: u32 = 1 << 28;

type Inner<'d> = Driver<'d, USB_OTG_FS>;

/// The OTG FS driver whose bus resets data toggles (see the module).
pub struct OtgDriver<'d>(pub Inner<'d>);

/// The driver's bus, with the toggles reset.
pub struct OtgBus<'d>(<Inner<'d> as usb::Driver<'d>>::Bus);

impl<'d> usb::Driver<'d> for OtgDriver<'d> {
    type EndpointOut = <Inner<'d> as usb::Driver<'d>>::EndpointOut;
    type EndpointIn = <Inner<'d> as usb::Driver<'d>>::EndpointIn;
    type ControlPipe = <Inner<'d> as usb::Driver<'d>>::ControlPipe;
    type Bus = OtgBus<'d>;

    fn alloc_endpoint_out(
        &mut self,
        ep_type: EndpointType,
        ep_addr: Option<EndpointAddress>,
        max_packet_size: u16,
        interval_ms: u8,
    ) -> Result<Self::EndpointOut, EndpointAllocError> {
        self.0
            .alloc_endpoint_out(ep_type, ep_addr, max_packet_size, interval_ms)
    }

    fn alloc_endpoint_in(
        &mut self,
        ep_type: EndpointType,
        ep_addr: Option<EndpointAddress>,
        max_packet_size: u16,
        interval_ms: u8,
    ) -> Result<Self::EndpointIn, EndpointAllocError> {
        self.0
            .alloc_endpoint_in(ep_type, ep_addr, max_packet_size, interval_ms)
    }

    fn start(self, control_max_packet_size: u16) -> (Self::Bus, Self::ControlPipe) {
        let (bus, control) = self.0.start(control_max_packet_size);
        (OtgBus(bus), control)
    }
}

impl usb::Bus for OtgBus<'_> {
    async fn enable(&mut self) {
        self.0.enable().await
    }

    async fn disable(&mut self) {
        self.0.disable().await
    }

    async fn poll(&mut self) -> Event {
        self.0.poll().await
    }

    fn endpoint_set_enabled(&mut self, ep_addr: EndpointAddress, enabled: bool) {
        self.0.endpoint_set_enabled(ep_addr, enabled);
        if enabled {
            data0(ep_addr);
        }
    }

    fn endpoint_set_stalled(&mut self, ep_addr: EndpointAddress, stalled: bool) {
        self.0.endpoint_set_stalled(ep_addr, stalled);
        if !stalled {
            data0(ep_addr);
        }
    }

    fn endpoint_is_stalled(&mut self, ep_addr: EndpointAddress) -> bool {
        self.0.endpoint_is_stalled(ep_addr)
    }

    async fn remote_wakeup(&mut self) -> Result<(), Unsupported> {
        self.0.remote_wakeup().await
    }
}

/// The endpoint's next packet is DATA0.
fn data0(ep: EndpointAddress) {
    let i = ep.index();
    if i == 0 || i >= ENDPOINTS {
        return;
    }
    let base = match ep.direction() {
        Direction::In => DIEPCTL,
        Direction::Out => DOEPCTL,
    };
    let ctl = (OTG_FS + base + EP_STRIDE * i) as *mut u32;
    // The driver changes these registers inside critical sections too; the bits read
    // back (EPENA, STALL, the type and size) are written back unchanged, the
    // write-only ones (CNAK, SNAK, SD1PID) read as 0.
    critical_section::with(|_| {
        // SAFETY: DxEPCTLi of an endpoint the driver allocated, a 32-bit register of
        // the OTG FS block, which is clocked while the bus runs.
        unsafe { ctl.write_volatile(ctl.read_volatile() | SD0PID) }
    });
}
