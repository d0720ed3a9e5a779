//! The reports that several requests make up, for every front end alike: `info`, a read of an entry or
//! group, and a write with what the unit holds afterwards ([`crate::results`] serialises them).

use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataEntry, DataEntryExt, DataIndex, Item, PositionCounts};
use crate::results::{ActuatorState, GetReport, InfoReport, WriteReport};
use crate::value::Value;
use crate::wire::Command;

#[cfg(feature = "tokio")]
use super::AsyncClient;
use super::Client;

/// `info` from what was read: the firmware and configuration texts (0x0001, 0x0002), battery/mains and
/// Error_Code 1 (0x0100, 0x00D1), every actuator's status 1 and position.
fn info_report(
    [firmware, configuration]: [Value; 2],
    [battery_mains, last_error]: [Value; 2],
    statuses: [ActuatorStatus1; 6],
    positions: [PositionCounts; 6],
) -> Result<InfoReport, Error> {
    let text = |v: Value| match v {
        Value::Text(t) => Ok(t),
        v => Err(unexpected("an info text", &v)),
    };
    let (firmware, configuration) = (text(firmware)?, text(configuration)?);
    let battery_mains = match battery_mains {
        Value::Flags(f) => f,
        v => return Err(unexpected("battery_mains", &v)),
    };
    let last_error = match last_error {
        Value::ErrorCode(c) => c,
        v => return Err(unexpected("error_code_1", &v)),
    };
    let actuators = Actuator::all()
        .zip(statuses)
        .filter(|(_, s)| s.available())
        .map(|(a, s)| ActuatorState::new(a, positions[usize::from(a.number() - 1)], s, None))
        .collect();
    Ok(InfoReport { firmware, configuration, battery_mains, last_error, actuators })
}

/// `what` read from the unit was not of its entry's kind.
fn unexpected(what: &str, v: &Value) -> Error {
    Error::UnexpectedReply { command: Command::Get, detail: format!("{what} read as {v}") }
}

impl Client {
    /// Firmware and configuration texts, battery/mains, Error_Code 1 and every connected actuator with its
    /// position and status 1: six reads, one after the other.
    pub fn info(&self) -> Result<InfoReport, Error> {
        let texts = [self.get_value(DataIndex(0x0001))?, self.get_value(DataIndex(0x0002))?];
        let words = [self.get_value(DataIndex(0x0100))?, self.get_value(DataIndex(0x00D1))?];
        info_report(texts, words, self.statuses()?, self.positions()?)
    }

    /// Reads a data-list entry or group ([`Client::get`]), with the unit its values are given in.
    pub fn read(&self, item: Item) -> Result<GetReport, Error> {
        let values = self.get(item.index())?;
        Ok(GetReport { item, values, speed_mode: self.config().speed_mode })
    }

    /// Writes `value` into the remote data entry `entry` ([`Client::set`]: RT, read back and compared where
    /// the unit reads remote data back), then reads what the unit holds now (`read_back`; None where the
    /// write could not be read back, and the report says why).
    pub fn write(&self, entry: &'static DataEntry, value: Value) -> Result<WriteReport, Error> {
        let set = self.set(entry.index(), &value)?;
        let read_back = if set.verified { Some(self.get_value(entry.index())?) } else { None };
        Ok(WriteReport { entry, value, read_back, set, speed_mode: self.config().speed_mode })
    }
}

#[cfg(feature = "tokio")]
impl AsyncClient {
    /// As [`Client::info`].
    pub async fn info(&self) -> Result<InfoReport, Error> {
        let texts = [self.get_value(DataIndex(0x0001)).await?, self.get_value(DataIndex(0x0002)).await?];
        let words = [self.get_value(DataIndex(0x0100)).await?, self.get_value(DataIndex(0x00D1)).await?];
        info_report(texts, words, self.statuses().await?, self.positions().await?)
    }

    /// As [`Client::read`].
    pub async fn read(&self, item: Item) -> Result<GetReport, Error> {
        let values = self.get(item.index()).await?;
        Ok(GetReport { item, values, speed_mode: self.config().speed_mode })
    }

    /// As [`Client::write`].
    pub async fn write(&self, entry: &'static DataEntry, value: Value) -> Result<WriteReport, Error> {
        let set = self.set(entry.index(), &value).await?;
        let read_back = if set.verified { Some(self.get_value(entry.index()).await?) } else { None };
        Ok(WriteReport { entry, value, read_back, set, speed_mode: self.config().speed_mode })
    }
}
