//! An in-memory sleeve for host tests (feature `sim`): the firmware's engine,
//! controller and link server, a flash model for the bank region, and byte queues
//! for the wire, driven one millisecond at a time.
//!
//! It is wired as the firmware wires them: bytes from the host go to the server at
//! once (as the USART interrupt hands them over), and every tick runs the engine
//! (the frame computed last tick goes out first) and then lets the server forward
//! what the tick answered. A restart boots again from the flash model's bytes.

use std::collections::VecDeque;
use std::vec::Vec;

use touch_protocol::OutputSink;

use super::bank::model::FlashModel;
use super::server::identity;
use super::{Channels, LinkServer};
use crate::boot::{bank_source, check_bank};
use crate::button::{Buttons, Event, Mode};
use crate::control::{Controller, Report};
use crate::engine::{Engine, Watchdog};
use crate::output::{device_config, Frame};

/// What the outputs hold once each tick's handler returned (index = tick).
#[derive(Debug, Default)]
pub struct Outputs(pub Vec<Frame>);

impl Outputs {
    /// Ends a tick that began with `before` frames recorded: a tick that starts a
    /// slot by command writes twice (its first frame follows the last tick's), and
    /// the outputs hold the second.
    fn settle(&mut self, before: usize) {
        if self.0.len() > before + 1 {
            self.0.drain(before..self.0.len() - 1);
        }
    }
}

impl OutputSink for Outputs {
    fn write(&mut self, codes: &Frame) {
        self.0.push(*codes);
    }
}

/// Counts feeds.
#[derive(Debug, Default)]
pub struct Dog(pub u64);

impl Watchdog for Dog {
    fn feed(&mut self) {
        self.0 += 1;
    }
}

/// The sleeve in memory.
pub struct Device {
    engine: Engine<'static, Outputs, Dog, 1>,
    server: LinkServer<'static, FlashModel>,
    to_host: VecDeque<u8>,
    reports: Vec<(u32, Report)>,
    builtin: &'static [u8],
    /// Restarts so far.
    pub boots: u32,
    /// Milliseconds since the first boot (a restart does not reset it): the link
    /// server's clock.
    pub ms: u64,
}

impl Device {
    /// Boots with `region` in the bank region (padded with 0xFF) and `builtin` as
    /// the built-in bank, as the firmware does: the boot check, the controller, the
    /// link. A refused region boots too (nothing plays; the link answers).
    pub fn boot(region: &[u8], builtin: &[u8]) -> Self {
        let flash = FlashModel::with(region);
        let builtin: &'static [u8] = Box::leak(builtin.to_vec().into_boxed_slice());
        Device::from_flash(flash, builtin, 0, 0)
    }

    fn from_flash(flash: FlashModel, builtin: &'static [u8], boots: u32, ms: u64) -> Self {
        // The controller reads the bank as it was at boot: on the device it reads
        // flash, which nothing writes until an upload locks it out of the bank.
        let snapshot: &'static [u8] = Box::leak(flash.bytes.clone().into_boxed_slice());
        let source = bank_source(snapshot, builtin);
        let checked = check_bank(source);
        let id = identity(source, builtin, checked);
        let bank = checked.ok();
        let channels: &'static mut Channels = Box::leak(Box::new(Channels::new()));
        let (link_port, tick_port) = channels.split();
        let controller = bank.map(|b| Controller::new(b, device_config()));
        let mut controller = controller.unwrap_or_else(|| {
            // No bank: a controller over none, so the link still answers (the
            // firmware blinks its LED code and plays nothing).
            Controller::empty(device_config())
        });
        controller.attach(tick_port);
        let engine = Engine::new(
            Outputs::default(),
            Dog::default(),
            Buttons::new(Mode::PlayNext),
            controller,
        );
        let mut server = LinkServer::new(link_port, flash, id);
        server.heard(ms);
        Device {
            engine,
            server,
            to_host: VecDeque::new(),
            reports: Vec::new(),
            builtin,
            boots,
            ms,
        }
    }

    /// Bytes from the host.
    pub fn write(&mut self, bytes: &[u8]) {
        let to_host = &mut self.to_host;
        self.server.heard(self.ms);
        self.server
            .receive(bytes, &mut |f: &[u8]| to_host.extend(f));
    }

    /// Takes the bytes the device sent so far.
    pub fn read(&mut self) -> Vec<u8> {
        self.to_host.drain(..).collect()
    }

    /// One millisecond: the engine's tick, then the server forwards the answers.
    /// After a committed, aborted or abandoned upload, the device restarts (as the
    /// firmware does once the reply went out).
    pub fn tick(&mut self) {
        let tick = self.engine.controller().now();
        let reports = &mut self.reports;
        let before = self.engine.sink().0.len();
        self.engine.tick([None], |r| reports.push((tick, r)), || {});
        self.engine.sink_mut().settle(before);
        let to_host = &mut self.to_host;
        self.server.poll(&mut |f: &[u8]| to_host.extend(f));
        self.ms += 1;
        if self.server.restart_due(self.ms) {
            self.restart();
        }
    }

    /// `ms` ticks.
    pub fn run(&mut self, ms: usize) {
        for _ in 0..ms {
            self.tick();
        }
    }

    /// A button gesture, as the button task would deliver it.
    pub fn press(&mut self, event: Event) -> Option<Report> {
        self.engine.inject(event)
    }

    /// A power cycle: the outputs at 0 A, the boot check of what flash holds now.
    pub fn restart(&mut self) {
        let flash = self.server_flash().clone();
        let to_host = core::mem::take(&mut self.to_host);
        *self = Device::from_flash(flash, self.builtin, self.boots + 1, self.ms);
        self.to_host = to_host;
    }

    fn server_flash(&self) -> &FlashModel {
        self.server.flash()
    }

    /// Every frame written to the outputs since the last boot (index = tick).
    pub fn outputs(&self) -> &[Frame] {
        &self.engine.sink().0
    }

    /// The bank region as flash holds it.
    pub fn region(&self) -> &[u8] {
        &self.server.flash().bytes
    }

    /// The controller.
    pub fn controller(&self) -> &Controller<'static> {
        self.engine.controller()
    }

    /// What the tick reported (for the log), with the tick.
    pub fn reports(&self) -> &[(u32, Report)] {
        &self.reports
    }
}
