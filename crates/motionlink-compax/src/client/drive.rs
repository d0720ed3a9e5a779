//! [`Drive`]: a handle on one drive of a [`Client`].

use std::time::Duration;

use super::Client;
use crate::error::Result;
use crate::model::{
    Command, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent, StatusId, StatusValue,
};
use crate::session::{MoveOptions, MoveReport, MoveRequest, StartedMove, WatchSample};
use crate::wire::Address;

/// A handle on one drive (address 1..=31) of a [`Client`]: the client's single-drive operations without the
/// address. Made by [`Client::drive`], which refuses the broadcast address 32.
#[derive(Debug, Clone, Copy)]
pub struct Drive<'a> {
    pub(super) client: &'a Client,
    pub(super) address: Address,
}

impl Drive<'_> {
    /// The drive's address (1..=31).
    pub fn address(&self) -> Address {
        self.address
    }

    /// The client, for what involves several drives.
    pub fn client(&self) -> &Client {
        self.client
    }

    /// [`Client::read_status`].
    pub fn read_status(&self, id: StatusId) -> Result<StatusValue> {
        self.client.read_status(self.address, id)
    }

    /// [`Client::read_statuses`].
    pub fn read_statuses(&self, ids: &[StatusId]) -> Result<Vec<(StatusId, StatusValue)>> {
        self.client.read_statuses(self.address, ids)
    }

    /// [`Client::read_position`]: S1.
    pub fn read_position(&self) -> Result<Position> {
        self.client.read_position(self.address)
    }

    /// [`Client::read_target`]: S2.
    pub fn read_target(&self) -> Result<Position> {
        self.client.read_target(self.address)
    }

    /// [`Client::read_s16`].
    pub fn read_s16(&self) -> Result<S16Bits> {
        self.client.read_s16(self.address)
    }

    /// [`Client::read_s17`].
    pub fn read_s17(&self) -> Result<S17Bits> {
        self.client.read_s17(self.address)
    }

    /// [`Client::read_param`].
    pub fn read_param(&self, id: ParamId) -> Result<f64> {
        self.client.read_param(self.address, id)
    }

    /// [`Client::write_param`].
    pub fn write_param(&self, id: ParamId, value: f64) -> Result<()> {
        self.client.write_param(self.address, id, value)
    }

    /// [`Client::set_speed`].
    pub fn set_speed(&self, speed: SpeedPercent, binary: bool) -> Result<()> {
        self.client.set_speed(self.address, speed, binary)
    }

    /// [`Client::set_accel`].
    pub fn set_accel(&self, ramp: RampMs, binary: bool) -> Result<()> {
        self.client.set_accel(self.address, ramp, binary)
    }

    /// [`Client::set_brake`].
    pub fn set_brake(&self, ramp: RampMs, binary: bool) -> Result<()> {
        self.client.set_brake(self.address, ramp, binary)
    }

    /// [`Client::set_output`].
    pub fn set_output(&self, output: u16, state: OutputState, binary: bool) -> Result<()> {
        self.client.set_output(self.address, output, state, binary)
    }

    /// [`Client::move_absolute`].
    pub fn move_absolute(&self, target: Position, opts: MoveOptions) -> Result<()> {
        self.client.move_absolute(self.address, target, opts)
    }

    /// [`Client::move_relative`].
    pub fn move_relative(&self, distance: Position, opts: MoveOptions) -> Result<()> {
        self.client.move_relative(self.address, distance, opts)
    }

    /// [`Client::home`].
    pub fn home(&self, opts: MoveOptions) -> Result<()> {
        self.client.home(self.address, opts)
    }

    /// [`Client::move_to`]: a move that is checked, read back, waited for and verified.
    pub fn move_to(&self, request: &MoveRequest, progress: &mut dyn FnMut(Position)) -> Result<MoveReport> {
        self.client.move_to(self.address, request, progress)
    }

    /// [`Client::start_checked_move`].
    pub fn start_checked_move(&self, request: &MoveRequest) -> Result<StartedMove> {
        self.client.start_checked_move(self.address, request)
    }

    /// [`Client::start_and_release`].
    pub fn start_and_release(&self, request: &MoveRequest) -> Result<StartedMove> {
        self.client.start_and_release(self.address, request)
    }

    /// [`Client::wait_reached`] for this drive.
    pub fn wait_reached(&self, timeout: Option<Duration>, progress: &mut dyn FnMut(Position)) -> Result<()> {
        self.client.wait_reached(&[self.address], timeout, &mut |_, p| progress(p))
    }

    /// [`Client::watch`] of this drive.
    pub fn watch(&self, interval: Duration, sample: &mut dyn FnMut(&WatchSample)) -> Result<()> {
        self.client.watch(self.address, interval, sample)
    }

    /// [`Client::stop`]: `OUTPUT O0=0`.
    pub fn stop(&self) -> Result<()> {
        self.client.stop(self.address)
    }

    /// [`Client::release`]: leaves this drive's move running when the client closes.
    pub fn release(&self) {
        self.client.release(&[self.address])
    }

    /// [`Client::command`].
    pub fn command(&self, cmd: &Command) -> Result<String> {
        self.client.command(self.address, cmd)
    }

    /// [`Client::raw`].
    pub fn raw(&self, text: &str) -> Result<Option<String>> {
        self.client.raw(self.address, text)
    }

    /// [`Client::echo`].
    pub fn echo(&self, text: &str) -> Result<String> {
        self.client.echo(self.address, text)
    }
}
