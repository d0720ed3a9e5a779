//! [`AsyncDrive`], a handle on one drive of an [`AsyncClient`], and [`AsyncWatch`], a stream of S1 / S17
//! samples of one drive (feature `tokio`).

use std::time::Duration;

use motionlink_link::clock::Timestamp;

use super::AsyncClient;
use crate::error::{Error, Result};
use crate::model::{
    Command, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent, StatusId, StatusValue,
};
use crate::session::{MoveOptions, MoveReport, MoveRequest, StartedMove, WatchSample};
use crate::wire::Address;

/// A handle on one drive (address 1..=31) of an [`AsyncClient`]: its single-drive operations without the
/// address, with the same safety (a dropped future of a wait or checked move stops the axis). Made by
/// [`AsyncClient::drive`], which refuses the broadcast address 32.
#[derive(Debug, Clone, Copy)]
pub struct AsyncDrive<'a> {
    client: &'a AsyncClient,
    address: Address,
}

impl<'a> AsyncDrive<'a> {
    pub(super) fn new(client: &'a AsyncClient, address: Address) -> Result<Self> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("a drive handle is one drive (1..=31)"));
        }
        Ok(AsyncDrive { client, address })
    }

    /// The drive's address (1..=31).
    pub fn address(&self) -> Address {
        self.address
    }

    /// The client, for what involves several drives.
    pub fn client(&self) -> &'a AsyncClient {
        self.client
    }

    /// [`AsyncClient::read_status`].
    pub async fn read_status(&self, id: StatusId) -> Result<StatusValue> {
        self.client.read_status(self.address, id).await
    }

    /// [`AsyncClient::read_statuses`].
    pub async fn read_statuses(&self, ids: &[StatusId]) -> Result<Vec<(StatusId, StatusValue)>> {
        self.client.read_statuses(self.address, ids).await
    }

    /// [`AsyncClient::read_position`]: S1.
    pub async fn read_position(&self) -> Result<Position> {
        self.client.read_position(self.address).await
    }

    /// [`AsyncClient::read_target`]: S2.
    pub async fn read_target(&self) -> Result<Position> {
        self.client.read_target(self.address).await
    }

    /// [`AsyncClient::read_s16`].
    pub async fn read_s16(&self) -> Result<S16Bits> {
        self.client.read_s16(self.address).await
    }

    /// [`AsyncClient::read_s17`].
    pub async fn read_s17(&self) -> Result<S17Bits> {
        self.client.read_s17(self.address).await
    }

    /// [`AsyncClient::read_param`].
    pub async fn read_param(&self, id: ParamId) -> Result<f64> {
        self.client.read_param(self.address, id).await
    }

    /// [`AsyncClient::write_param`].
    pub async fn write_param(&self, id: ParamId, value: f64) -> Result<()> {
        self.client.write_param(self.address, id, value).await
    }

    /// [`AsyncClient::set_speed`].
    pub async fn set_speed(&self, speed: SpeedPercent, binary: bool) -> Result<()> {
        self.client.set_speed(self.address, speed, binary).await
    }

    /// [`AsyncClient::set_accel`].
    pub async fn set_accel(&self, ramp: RampMs, binary: bool) -> Result<()> {
        self.client.set_accel(self.address, ramp, binary).await
    }

    /// [`AsyncClient::set_brake`].
    pub async fn set_brake(&self, ramp: RampMs, binary: bool) -> Result<()> {
        self.client.set_brake(self.address, ramp, binary).await
    }

    /// [`AsyncClient::set_output`].
    pub async fn set_output(&self, output: u16, state: OutputState, binary: bool) -> Result<()> {
        self.client.set_output(self.address, output, state, binary).await
    }

    /// [`AsyncClient::move_absolute`].
    pub async fn move_absolute(&self, target: Position, opts: MoveOptions) -> Result<()> {
        self.client.move_absolute(self.address, target, opts).await
    }

    /// [`AsyncClient::move_relative`].
    pub async fn move_relative(&self, distance: Position, opts: MoveOptions) -> Result<()> {
        self.client.move_relative(self.address, distance, opts).await
    }

    /// [`AsyncClient::home`].
    pub async fn home(&self, opts: MoveOptions) -> Result<()> {
        self.client.home(self.address, opts).await
    }

    /// [`AsyncClient::move_to`]: a move that is checked, read back, waited for and verified. Dropping the
    /// future stops the axis.
    pub async fn move_to(&self, request: &MoveRequest) -> Result<MoveReport> {
        self.client.move_to(self.address, request).await
    }

    /// [`AsyncClient::start_checked_move`].
    pub async fn start_checked_move(&self, request: &MoveRequest) -> Result<StartedMove> {
        self.client.start_checked_move(self.address, request).await
    }

    /// [`AsyncClient::start_and_release`].
    pub async fn start_and_release(&self, request: &MoveRequest) -> Result<StartedMove> {
        self.client.start_and_release(self.address, request).await
    }

    /// [`AsyncClient::wait_reached`] for this drive. Dropping the future stops the axis if this client
    /// started it.
    pub async fn wait_reached(&self, timeout: Option<Duration>) -> Result<()> {
        self.client.wait_reached(&[self.address], timeout).await
    }

    /// [`AsyncClient::stop`]: `OUTPUT O0=0`.
    pub async fn stop(&self) -> Result<()> {
        self.client.stop(self.address).await
    }

    /// [`AsyncClient::release`]: leaves this drive's move running when the client closes.
    pub fn release(&self) {
        self.client.release(&[self.address])
    }

    /// [`AsyncClient::command`].
    pub async fn command(&self, cmd: &Command) -> Result<String> {
        self.client.command(self.address, cmd).await
    }

    /// [`AsyncClient::raw`].
    pub async fn raw(&self, text: &str) -> Result<Option<String>> {
        self.client.raw(self.address, text).await
    }

    /// [`AsyncClient::echo`].
    pub async fn echo(&self, text: &str) -> Result<String> {
        self.client.echo(self.address, text).await
    }

    /// [`AsyncClient::watch`] of this drive.
    pub fn watch(&self, interval: Duration) -> Result<AsyncWatch<'a>> {
        AsyncWatch::new(self.client, self.address, interval)
    }
}

/// S1 and S17 of one drive every interval, for async callers: made by [`AsyncClient::watch`]. Each
/// [`AsyncWatch::next`] waits until the sample is due (one interval after the previous one was due,
/// counted from the start of the previous one, as [`Client::watch`](crate::client::Client::watch) samples), handling
/// what arrives meanwhile, then reads S1 and S17 (the session's [`Op::Pause`](crate::session::Op::Pause) and
/// [`Op::ReadStatuses`](crate::session::Op::ReadStatuses)). The stream has no end of its own: drop it (or
/// stop calling `next`) to end it. A watch reads and moves nothing, so dropping it stops nothing.
#[derive(Debug)]
pub struct AsyncWatch<'a> {
    client: &'a AsyncClient,
    drive: Address,
    interval: Duration,
    /// When the next sample is due (`None`: at once).
    due: Option<Timestamp>,
    /// The previous sample's position (`None` before the first).
    previous: Option<Position>,
}

impl<'a> AsyncWatch<'a> {
    pub(super) fn new(client: &'a AsyncClient, drive: Address, interval: Duration) -> Result<Self> {
        if drive.is_broadcast() {
            return Err(Error::Broadcast("a watch reads one drive's state"));
        }
        Ok(AsyncWatch { client, drive, interval, due: None, previous: None })
    }

    /// The drive watched.
    pub fn drive(&self) -> Address {
        self.drive
    }

    /// The next sample, once it is due. An error (the drive does not answer, the session closed) does not
    /// end the stream: the next call tries again.
    pub async fn next(&mut self) -> Result<WatchSample> {
        let clock = self.client.clock();
        let due = match self.due {
            Some(due) => {
                let now = clock.now();
                if due > now {
                    self.client.pause(due - now).await?;
                }
                due
            }
            None => clock.now(),
        };
        let read = self.client.read_statuses(self.drive, &[StatusId::ACTUAL_POSITION, StatusId::STATUS_BITS_2]).await;
        self.due = Some((due + self.interval).max(clock.now()));
        match read?.as_slice() {
            [(_, StatusValue::Position(position)), (_, StatusValue::S17(s17))] => {
                let tolerance = self.client.config().in_position_tolerance;
                let sample = WatchSample::after(self.previous, self.drive, *position, *s17, tolerance);
                self.previous = Some(*position);
                Ok(sample)
            }
            other => Err(Error::UnexpectedReply {
                address: self.drive,
                command: "S1, S17".into(),
                reply: other.iter().map(|(_, v)| v.to_string()).collect::<Vec<_>>().join(", "),
            }),
        }
    }
}
