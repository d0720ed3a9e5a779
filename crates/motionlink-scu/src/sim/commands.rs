//! What the emulated unit does with each command: remote mode, cyclic objects, functions.

use super::*;
use crate::model::{Function, Item, MotionDirection, StopMode};
use crate::wire::Reply;

impl Emulator {
    pub(super) fn handle(&mut self, incoming: Incoming<'_>) {
        let request = match incoming {
            Incoming::UnknownCommand { code } => {
                let command_echo = Reply::status_only(Command::Get, Status::InvalidCommand);
                // The reply repeats the unknown letters.
                let start = self.reply.len();
                self.push_reply(&command_echo);
                if self.reply.len() >= start + 5 {
                    self.reply[start..start + 2].copy_from_slice(&code);
                    let crc = crate::wire::crc16(&self.reply[start..start + 3]);
                    self.reply[start + 3..start + 5].copy_from_slice(&crc.to_le_bytes());
                }
                return;
            }
            Incoming::Request(r) => r,
        };
        let command = request.command();
        // Mode rules.
        let allowed = match (self.mode, command) {
            (_, Command::Open | Command::Abort) => true,
            (RemoteMode::Off, _) => false,
            (_, Command::Cyclic) => true,
            (RemoteMode::Active(_), _) => true,
            (RemoteMode::AwaitingRc(_) | RemoteMode::Locked | RemoteMode::TimedOut(_), _) => false,
        };
        if !allowed {
            self.reply_status(command, Status::PermissionError);
            return;
        }
        match request {
            Request::Open { safety_id } => match SafetyId::from_code(safety_id) {
                Some(s) => {
                    self.mode = RemoteMode::AwaitingRc(s);
                    self.last_rc = self.now;
                    self.reply_status(command, Status::Ack);
                    self.push_event(format!("remote mode opened (Safety_ID {safety_id})"));
                }
                None => self.reply_status(command, Status::ParameterDataError),
            },
            Request::Abort => {
                // Leaving remote mode ends remote control: remote motions stop (a decision; the manual is silent).
                if self.mode != RemoteMode::Off {
                    self.actuators.iter_mut().filter(|a| a.origin == Origin::Remote).for_each(ActuatorState::fast_stop);
                    self.push_event("remote mode closed by RA".into());
                }
                self.mode = RemoteMode::Off;
                self.reply_status(command, Status::Ack);
                self.note_rest();
            }
            Request::Cyclic { object, write } => self.handle_cyclic(object, write),
            Request::Get { index }
                if variants::refuses_get(&self.config.variants, DataIndex(index))
                    || self.refused_reads.contains(&DataIndex(index)) =>
            {
                self.reply_status(command, Status::ParameterDataError)
            }
            Request::Get { index } => match item(DataIndex(index)) {
                Some(it) => {
                    let mut data = Vec::with_capacity(it.size());
                    self.read_item(it, &mut data);
                    self.push_reply(&Reply::with_data(command, &data));
                }
                None => self.reply_status(command, Status::ParameterDataError),
            },
            Request::Transfer { index, data } => {
                let status = match item(DataIndex(index)) {
                    Some(Item::Group(_)) if self.config.variants.contains(&Variant::NoGroups) => {
                        Status::ParameterDataError
                    }
                    Some(it) => self.write_item(it, data).err().unwrap_or(Status::Ack),
                    None => Status::ParameterDataError,
                };
                self.reply_status(command, status);
            }
            Request::Execute { function, params } => {
                let status = self.execute(function, params).err().unwrap_or(Status::Ack);
                self.reply_status(command, status);
            }
            Request::Stop { function, param } => {
                let status = self.stop(function, param).err().unwrap_or(Status::Ack);
                self.reply_status(command, status);
            }
        }
    }

    pub(super) fn handle_cyclic(&mut self, object: u8, write: &[u8]) {
        let command = Command::Cyclic;
        self.stats.cyclic += 1;
        // Any RC feeds the watchdog and completes the opening of remote mode.
        self.last_rc = self.now;
        self.mode = match self.mode {
            RemoteMode::AwaitingRc(s) | RemoteMode::TimedOut(s) | RemoteMode::Active(s) => RemoteMode::Active(s),
            m => m,
        };
        if object == UNUSED {
            if !write.is_empty() {
                self.reply_status(command, Status::ParameterCountError);
            } else if self.config.variants.contains(&Variant::RcEmptyData) {
                self.push_reply(&Reply::with_data(command, &[]));
            } else {
                self.reply_status(command, Status::Ack);
            }
            return;
        }
        if self.config.variants.contains(&Variant::NoCyclicObjects) {
            // The RC fed the watchdog; its cyclic object is not known to this firmware.
            self.reply_status(command, Status::ParameterDataError);
            return;
        }
        let Some(obj) = self.cyclic_objects.get(usize::from(object)).copied() else {
            self.reply_status(command, Status::ParameterDataError);
            return;
        };
        if self.mode == RemoteMode::Locked {
            // After a Safety_ID 0 timeout RC is accepted, but no data is exchanged until RO.
            self.reply_status(command, Status::PermissionError);
            return;
        }
        let (Some(write_size), Some(_)) = (obj.write_size(), obj.read_size()) else {
            self.reply_status(command, Status::ParameterDataError);
            return;
        };
        if write.len() != write_size {
            self.reply_status(command, Status::ParameterCountError);
            return;
        }
        let mut at = 0;
        for idx in obj.write_indices() {
            let Some(it) = item(idx) else { break };
            let n = it.size();
            if let Err(status) = self.write_item(it, &write[at..at + n]) {
                self.reply_status(command, status);
                return;
            }
            at += n;
        }
        let mut data = Vec::new();
        for idx in obj.read_indices() {
            if let Some(it) = item(idx) {
                self.read_item(it, &mut data);
            }
        }
        self.push_reply(&Reply::with_data(command, &data));
    }

    pub(super) fn execute(&mut self, function: u8, params: [u8; 2]) -> Result<(), Status> {
        let f = Function::from_id(function).ok_or(Status::ParameterDataError)?;
        match f {
            Function::Motion(m) => {
                let direction = MotionDirection::from_code(params[0]).ok_or(Status::ParameterDataError)?;
                if params[1] != UNUSED {
                    return Err(Status::ParameterDataError);
                }
                let drives = self.config.functions[usize::from(m.id())].clone();
                if drives.is_empty() || self.emergency_stop {
                    return Err(Status::PermissionError);
                }
                if self.standing_errors != 0 {
                    return self.motion_not_performed(m, function);
                }
                if self.config.variants.contains(&Variant::ReNeedsRs) && self.executed[usize::from(function)] {
                    // This firmware takes a new RE of a started function only after its RS.
                    return Err(Status::PermissionError);
                }
                self.executed[usize::from(function)] = true;
                if direction != MotionDirection::Undefined {
                    self.reset_errors_on_motion();
                }
                let speed = self.remote_speed[usize::from(m.id())];
                let mut moves = Vec::new();
                for a in drives {
                    let i = usize::from(a.number()) - 1;
                    let cfg = &self.config.actuators[i];
                    let user = &cfg.user_positions.users[0];
                    let target = match direction {
                        MotionDirection::Undefined => continue,
                        MotionDirection::In => cfg.stroke_min_counts,
                        MotionDirection::Out => cfg.stroke_max_counts,
                        MotionDirection::Memory1 => user.memory_counts[0],
                        MotionDirection::Memory2 => user.memory_counts[1],
                        MotionDirection::Memory3 => user.memory_counts[2],
                        MotionDirection::Memory4 => user.memory_counts[3],
                        MotionDirection::IntermediateIn => user.intermediate_in_counts,
                        MotionDirection::IntermediateOut => user.intermediate_out_counts,
                        MotionDirection::RemotePosition => self.remote_position[i],
                    };
                    let (counts_per_s, percent) = self.speed_of(i, speed);
                    let from_rest = !self.actuators[i].moving();
                    let moves_now =
                        self.actuators[i].start(target, counts_per_s, percent, Origin::Remote, Some(m.id()));
                    if moves_now && from_rest && self.config.variants.contains(&Variant::LateMotionBit) {
                        self.actuators[i].start_delay_s = super::variants::LATE_START.as_secs_f64();
                    }
                    let (lo, hi) = self.actuators[i].travel_range();
                    moves.push(format!(
                        "{a} -> {}{}",
                        target.clamp(lo, hi),
                        if moves_now { "" } else { " (already there)" }
                    ));
                }
                self.push_event(format!(
                    "{} started direction {} ({}): {}",
                    m,
                    direction.code(),
                    direction.description(),
                    if moves.is_empty() { "nothing moves".to_string() } else { moves.join(", ") }
                ));
                self.note_rest();
                Ok(())
            }
            other => {
                if params != [UNUSED, UNUSED] {
                    return Err(Status::ParameterDataError);
                }
                self.executed[usize::from(function)] = true;
                self.switch(other, true);
                Ok(())
            }
        }
    }

    /// An RE of motion function `m` (id `function`) while an error stands after which "motions are not
    /// performed" (E 4.6 Table 7, S 4.5): nothing moves. The unit refuses the command as "not possible with
    /// SCU mode/state" (PE, E 4.2 Table 2, S 4.2), or, on a unit of [`Variant::AckWithoutMotion`],
    /// acknowledges it (the function then counts as started, to be ended with RS).
    fn motion_not_performed(&mut self, m: crate::model::MotionFunction, function: u8) -> Result<(), Status> {
        let bits: Vec<String> =
            (1..=32u8).filter(|&b| ErrorCode(self.standing_errors).has(b)).map(|b| b.to_string()).collect();
        let acked = self.config.variants.contains(&Variant::AckWithoutMotion);
        self.push_event(format!(
            "{m} RE {}: motions are not performed while error bit {} stands",
            if acked { "acknowledged, nothing moves" } else { "refused (PE)" },
            bits.join(", ")
        ));
        if acked {
            self.executed[usize::from(function)] = true;
            Ok(())
        } else {
            Err(Status::PermissionError)
        }
    }

    /// Counts per second and percent of actuator `i` at remote speed `speed` (in the unit's speed mode).
    pub(super) fn speed_of(&self, i: usize, speed: u16) -> (f64, u16) {
        let cfg = &self.config.actuators[i];
        match self.config.speed_mode {
            SpeedMode::Percent => (cfg.counts_per_second_at_full_speed * f64::from(speed) / 100.0, speed),
            SpeedMode::CountsPerSecond => {
                (f64::from(speed), (f64::from(speed) / cfg.counts_per_second_at_full_speed * 100.0).round() as u16)
            }
        }
    }

    pub(super) fn stop(&mut self, function: u8, param: u8) -> Result<(), Status> {
        let f = Function::from_id(function).ok_or(Status::ParameterDataError)?;
        match f {
            Function::Motion(m) => {
                let mode = StopMode::from_code(param).ok_or(Status::ParameterDataError)?;
                self.executed[usize::from(function)] = false;
                for a in self.config.functions[usize::from(m.id())].clone() {
                    let act = &mut self.actuators[usize::from(a.number()) - 1];
                    if act.origin == Origin::Remote {
                        match mode {
                            StopMode::Fast => act.fast_stop(),
                            StopMode::Soft => act.soft_stop(),
                        }
                    }
                }
                let how = match mode {
                    StopMode::Fast => "fast",
                    StopMode::Soft => "soft",
                };
                self.push_event(format!("{m} stopped (RS {how})"));
                self.note_rest();
                Ok(())
            }
            other => {
                if param != UNUSED {
                    return Err(Status::ParameterDataError);
                }
                self.executed[usize::from(function)] = false;
                self.switch(other, false);
                Ok(())
            }
        }
    }

    pub(super) fn switch(&mut self, f: Function, on: bool) {
        if self.config.failed_switches.contains(&f) {
            let (command, state) = if on { ("RE", "on") } else { ("RS", "off") };
            self.push_event(format!(
                "F{} {command} acknowledged, but its output has failed: not switched {state} ({})",
                f.number(),
                f.description()
            ));
            return;
        }
        let set = |bits: &mut u8, bit: u8| {
            if on {
                *bits |= 1 << bit;
            } else {
                *bits &= !(1 << bit);
            }
        };
        match f {
            Function::Buzzer => self.buzzer = on,
            Function::BinaryOutput1 => set(&mut self.binary_outputs, 0),
            Function::BinaryOutput2 => set(&mut self.binary_outputs, 1),
            Function::Led1 => set(&mut self.led_hand_switch, 0),
            Function::Led2 => set(&mut self.led_hand_switch, 1),
            Function::EmergencyStop => {
                self.emergency_stop = on;
                if on {
                    self.actuators.iter_mut().for_each(ActuatorState::fast_stop);
                }
            }
            Function::Motion(_) => {}
        }
        self.push_event(format!("F{} {} ({})", f.number(), if on { "on" } else { "off" }, f.description()));
        self.note_rest();
    }
}
