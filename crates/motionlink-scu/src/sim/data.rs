//! The data list as the emulated unit holds it: reading entries and groups, writing remote data, replies.

use super::*;
use crate::model::{DataEntry, DataEntryExt, Item, Status2Flag};
use crate::value::Value;
use crate::wire::{encode_reply, Reply};

impl Emulator {
    pub(super) fn reply_status(&mut self, command: Command, status: Status) {
        self.push_reply(&Reply::status_only(command, status));
    }

    pub(super) fn push_reply(&mut self, reply: &Reply<'_>) {
        let start = self.reply.len();
        self.reply.resize(start + reply.encoded_len(), 0);
        match encode_reply(reply, &mut self.reply[start..]) {
            Ok(n) => self.reply.truncate(start + n),
            Err(e) => {
                // Data that does not fit a reply (every path that reads data is bounded by the value checks,
                // so this is a defect): the unit answers PDE rather than nothing.
                tracing::error!("SCU emulator: {} reply not encodable ({e}); answering PDE", reply.command);
                self.reply.truncate(start);
                let pde = Reply::status_only(reply.command, Status::ParameterDataError);
                self.reply.resize(start + pde.encoded_len(), 0);
                let n = encode_reply(&pde, &mut self.reply[start..]).unwrap_or(0);
                self.reply.truncate(start + n);
            }
        }
        self.stats.telegrams += 1;
    }

    /// The value bytes of data-list entry `e`.
    pub(super) fn read_entry(&self, e: &DataEntry, out: &mut Vec<u8>) {
        let v = self.entry_value(e).unwrap_or_else(|| {
            tracing::error!("SCU emulator: {} ({}) has no modelled value; answering zeros", e.name, e.index());
            Value::Counter(0)
        });
        // Entries of raw-number kinds are encoded through their own kind's size.
        let start = out.len();
        match (&v, e.kind) {
            (Value::Number(n), _) => out.push(*n),
            (Value::Counter(n), k) => out.extend_from_slice(&n.to_le_bytes()[..k.size()]),
            (v, k) => v.encode(k, out),
        }
        out.resize(start + e.size(), 0);
    }

    /// The emulated unit's value of entry `e`; `None` for an entry the emulator does not model (a test
    /// checks that there is none).
    pub(super) fn entry_value(&self, e: &DataEntry) -> Option<Value> {
        let i = e.index().0;
        let actuator = |base: u16| self.actuators.get(usize::from(i - base).wrapping_sub(1));
        let unshown = self.config.variants.contains(&Variant::SwitchStatusUnshown);
        Some(match i {
            0x0001 => Value::Text(self.config.firmware_info.clone()),
            0x0002 => Value::Text(self.config.configuration_info.clone()),
            0x0011..=0x0016 => Value::PositionCounts(actuator(0x0010).map_or(0, ActuatorState::reported_position)),
            0x0031..=0x0034 => Value::AnalogueCentiVolts(if i == 0x0031 { 250 } else { 0 }),
            0x0061..=0x0066 => Value::Counter(actuator(0x0060).map_or(0, |a| a.relay_in_cycles)),
            0x0071..=0x0076 => Value::Counter(actuator(0x0070).map_or(0, |a| a.relay_out_cycles)),
            0x0081..=0x0086 => Value::Counter(actuator(0x0080).map_or(0, |a| a.error_count)),
            0x0091..=0x0096 => Value::StrokeCounts(actuator(0x0090).map_or(0, |a| a.cumulated_stroke.round() as u32)),
            0x00A1..=0x00A6 => Value::CurrentDeciAmps(actuator(0x00A0).map_or(0, ActuatorState::current)),
            0x00B1..=0x00B6 => Value::CurrentDeciAmps(actuator(0x00B0).map_or(0, |a| a.max_current)),
            0x00BF => Value::CurrentDeciAmps(self.max_total_current),
            0x00C0 => Value::TemperatureAdc(96),
            0x00D1..=0x00D5 => Value::ErrorCode(ErrorCode(self.error_history[usize::from(i - 0x00D1)])),
            0x00E1..=0x00E6 => Value::Number(actuator(0x00E0).map_or(0, |_| {
                if self.emergency_stop {
                    Status2Flag::Initialized.mask()
                } else {
                    Status2Flag::Initialized.mask()
                        | Status2Flag::ReleaseRetraction.mask()
                        | Status2Flag::ReleaseExtension.mask()
                }
            })),
            0x00F1..=0x00F6 => Value::SpeedPercent(actuator(0x00F0).map_or(0, ActuatorState::speed_percent)),
            0x0040 => Value::Counter(self.keys),
            0x0100 => Value::Number(0b0001), // mains connected, no battery
            // A unit of the variant shows output 2, the LEDs and the emergency stop elsewhere, or not at all.
            0x0110 if unshown => Value::Number(self.binary_outputs & 0x01),
            0x0110 => Value::Number(self.binary_outputs),
            0x0120 if unshown => Value::Number(0),
            0x0120 => Value::Number(self.led_hand_switch),
            0x0140 => Value::Number(u8::from(self.buzzer)),
            0x0150 => Value::Number(1),
            0x0162 => Value::Counter(if self.emergency_stop && !unshown { 0x03FF } else { 0 }),
            0x0164 => Value::BatteryDeciVolts(0),
            0x0166 => Value::Number(1),
            0x0171..=0x0176 => Value::Number(actuator(0x0170).map_or(0, ActuatorState::status1)),
            0x1011..=0x1016 => Value::ConversionFactor(if actuator(0x1010).is_some() { 0.31 } else { 0.0 }),
            0x2001..=0x2006 => {
                Value::UserPositions(Box::new(actuator(0x2000).map_or_else(Default::default, |a| a.cfg.user_positions)))
            }
            0x3001..=0x3005 => Value::CyclicObject(self.cyclic_objects[usize::from(i - 0x3001)]),
            0x3011..=0x301A => Value::RemoteSpeed(self.remote_speed[usize::from(i - 0x3011)]),
            0x3021..=0x3026 => Value::RemotePosition(self.remote_position[usize::from(i - 0x3021)]),
            // Nothing is wired to the binary inputs, no locking box is connected, and the model has no
            // temperature rise.
            0x0020 => Value::Number(0),
            0x008F => Value::Counter(self.total_over_current_count),
            0x00C1 => Value::Counter(0),
            0x0130 => Value::Number(0),
            0x0165 => Value::Number(0),
            _ => return None,
        })
    }

    pub(super) fn read_item(&self, it: Item, out: &mut Vec<u8>) {
        match it {
            Item::Entry(e) => self.read_entry(e, out),
            Item::Group(g) => g.members().for_each(|e| self.read_entry(e, out)),
        }
    }

    /// Writes the bytes of remote entry `e` (already checked to be 0x3xxx and of the right size).
    pub(super) fn write_entry(&mut self, e: &DataEntry, bytes: &[u8]) -> Result<(), Status> {
        let v = Value::decode(e.kind, bytes).map_err(|_| Status::ParameterCountError)?;
        v.check_range(self.config.speed_mode).map_err(|_| Status::ParameterDataError)?;
        let i = e.index().0;
        match (i, v) {
            (0x3001..=0x3005, Value::CyclicObject(o)) => {
                if o.write_indices()
                    .chain(o.read_indices())
                    .any(|x| variants::refuses_in_object(&self.config.variants, x))
                {
                    return Err(Status::ParameterDataError);
                }
                self.cyclic_objects[usize::from(i - 0x3001)] = o
            }
            (0x3011..=0x301A, Value::RemoteSpeed(s)) => {
                let function = (i - 0x3011) as u8;
                self.remote_speed[usize::from(function)] = s;
                // "The speed can be changed during motion": the function's running remote motions follow
                // it along the ramp.
                for k in 0..self.actuators.len() {
                    let a = &self.actuators[k];
                    if a.function == Some(function) && a.origin == Origin::Remote && a.target.is_some() {
                        let (counts_per_s, percent) = self.speed_of(k, s);
                        self.actuators[k].set_speed(counts_per_s, percent);
                    }
                }
            }
            (0x3021..=0x3026, Value::RemotePosition(p)) => self.remote_position[usize::from(i - 0x3021)] = p,
            _ => return Err(Status::ParameterDataError),
        }
        Ok(())
    }

    pub(super) fn write_item(&mut self, it: Item, bytes: &[u8]) -> Result<(), Status> {
        if !it.is_writable() {
            return Err(Status::ParameterDataError);
        }
        if bytes.len() != it.size() {
            return Err(Status::ParameterCountError);
        }
        match it {
            Item::Entry(e) => self.write_entry(e, bytes),
            Item::Group(g) => {
                // Check all first, then write all: a group write is all or nothing.
                let mut at = 0;
                for e in g.members() {
                    let v =
                        Value::decode(e.kind, &bytes[at..at + e.size()]).map_err(|_| Status::ParameterCountError)?;
                    v.check_range(self.config.speed_mode).map_err(|_| Status::ParameterDataError)?;
                    at += e.size();
                }
                let mut at = 0;
                for e in g.members() {
                    self.write_entry(e, &bytes[at..at + e.size()])?;
                    at += e.size();
                }
                Ok(())
            }
        }
    }
}
