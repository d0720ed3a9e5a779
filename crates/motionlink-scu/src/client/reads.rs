//! The reports that several requests make up, for every front end alike: `info`, a read of an entry or
//! group, and a write with what the unit holds afterwards ([`crate::results`] serialises them).

use crate::error::Error;
use crate::model::{Actuator, DataEntry, DataEntryExt, DataIndex, Item};
use crate::results::{ActuatorState, GetReport, InfoReport, WriteReport};
use crate::value::Value;
use crate::wire::Command;

#[cfg(feature = "tokio")]
use super::AsyncClient;
use super::Client;

/// `what` read from the unit was not of its entry's kind.
fn unexpected(what: &str, v: &Value) -> Error {
    Error::UnexpectedReply { command: Command::Get, detail: format!("{what} read as {v}") }
}

impl Client {
    /// Firmware and configuration texts, battery/mains, Error_Code 1 and every connected actuator with its
    /// position and status 1: six reads, one after the other.
    pub fn info(&self) -> Result<InfoReport, Error> {
        let text = |index: u16| match self.get_value(DataIndex(index))? {
            Value::Text(t) => Ok(t),
            v => Err(unexpected("an info text", &v)),
        };
        let (firmware, configuration) = (text(0x0001)?, text(0x0002)?);
        let battery_mains = match self.get_value(DataIndex(0x0100))? {
            Value::Flags(f) => f,
            v => return Err(unexpected("battery_mains", &v)),
        };
        let last_error = match self.get_value(DataIndex(0x00D1))? {
            Value::ErrorCode(c) => c,
            v => return Err(unexpected("error_code_1", &v)),
        };
        let statuses = self.statuses()?;
        let positions = self.positions()?;
        let actuators = Actuator::all()
            .zip(statuses)
            .filter(|(_, s)| s.available())
            .map(|(a, s)| ActuatorState::new(a, positions[usize::from(a.number() - 1)], s, None))
            .collect();
        Ok(InfoReport { firmware, configuration, battery_mains, last_error, actuators })
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
    /// As [`Client::write`].
    pub async fn write(&self, entry: &'static DataEntry, value: Value) -> Result<WriteReport, Error> {
        let set = self.set(entry.index(), &value).await?;
        let read_back = if set.verified { Some(self.get_value(entry.index()).await?) } else { None };
        Ok(WriteReport { entry, value, read_back, set, speed_mode: self.config().speed_mode })
    }
}
