//! What a drive does with the bytes it hears: framing them with its P196, checking parity, BCC, length and
//! timing, executing the telegram addressed to it (or to all), and answering.

use std::fmt::Write as _;

use motionlink_link::clock::Timestamp;

use super::drive::{Comparator, Drive, Motion, Stored};
use super::{Variant, QUEUE_DEPTH, REFUSED};
use crate::model::{write_param_reply, Command, ErrorCode, ParamId, Position};
use crate::wire::reply::encode_reply;
use crate::wire::request::{Body, ParsedRequest, RequestDecoder, RequestError, RequestEvent, RequestFrame};
use crate::wire::{Mode, TextBuf, BROADCAST};

impl Drive {
    pub(super) fn reply(&mut self, out: &mut Vec<u8>, text: &[u8]) {
        let mut buf = Vec::with_capacity(text.len() + 8);
        encode_reply(&mut buf, &self.mode, self.address, text);
        self.send(out, &buf);
    }

    pub(super) fn send(&mut self, out: &mut Vec<u8>, bytes: &[u8]) {
        if self.xoff {
            self.held.extend_from_slice(bytes);
        } else {
            out.extend_from_slice(bytes);
        }
    }

    pub(super) fn flush_pending(&mut self, out: &mut Vec<u8>) {
        if !self.rx.is_idle() || self.pending.is_empty() {
            return;
        }
        for t in std::mem::take(&mut self.pending) {
            self.reply(out, t.as_bytes());
        }
    }

    pub(super) fn error(&mut self, out: &mut Vec<u8>, code: ErrorCode) {
        self.record(code);
        let mut t = TextBuf::<4>::new();
        let _ = write!(t, "E{:02}", code.0);
        self.reply(out, t.as_bytes());
    }

    /// Checks the telegram timeout at `now`; answers E73 if it expired.
    pub(super) fn check_timeout(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        if let Some(deadline) = self.rx_deadline() {
            if now >= deadline {
                let mine = self.rx.partial_address() == self.address;
                self.rx.reset();
                self.rx_parity_error = false;
                if mine {
                    self.error(out, ErrorCode::TIMEOUT);
                }
                self.flush_pending(out);
            }
        }
    }

    pub(super) fn on_byte(&mut self, now: Timestamp, b: u8, parity_error: bool, line_baud: u32, out: &mut Vec<u8>) {
        // A drive powered on with P196 = 164/165 speaks the COMTAC fieldbus protocol: no ASCII telegram is its.
        if self.baud_rate != line_baud || self.fieldbus {
            return;
        }
        self.check_timeout(now, out);
        self.rx_last = now;
        if parity_error && self.mode.parity != motionlink_link::link::Parity::None {
            self.rx_parity_error = true;
        }
        match self.rx.push(b) {
            None | Some(RequestEvent::Garbage(_)) => {}
            Some(RequestEvent::Flow(xoff)) => {
                self.xoff = xoff;
                if !xoff {
                    let held = std::mem::take(&mut self.held);
                    out.extend_from_slice(&held);
                    self.flush_pending(out);
                }
            }
            Some(RequestEvent::Frame(f)) => {
                let parity = std::mem::take(&mut self.rx_parity_error);
                self.on_frame(now, &f, parity, out);
                self.flush_pending(out);
            }
        }
        if self.rx.is_idle() {
            self.rx_parity_error = false;
        }
    }

    pub(super) fn on_frame(&mut self, now: Timestamp, f: &RequestFrame, parity_error: bool, out: &mut Vec<u8>) {
        let addr = f.address();
        let broadcast = addr == BROADCAST && f.bytes().len() >= 2 && f.bytes()[..2] == *b"32";
        let mine = self.address != 0 && addr == self.address;
        if !mine && !broadcast {
            return;
        }
        self.telegrams += 1;
        let answer = mine;
        if parity_error {
            if answer {
                self.error(out, ErrorCode::PARITY);
            }
            return;
        }
        let p = match f.parse() {
            Ok(p) => p,
            Err(e) => {
                if answer {
                    let code = match e {
                        RequestError::Bcc { .. } => ErrorCode::BCC,
                        RequestError::Overflow(_) => ErrorCode::BUFFER_OVERFLOW,
                        RequestError::Address(_) | RequestError::AddressTooLong(_) => return,
                        RequestError::Empty | RequestError::Binary(_) => REFUSED,
                    };
                    self.error(out, code);
                }
                return;
            }
        };
        if std::mem::take(&mut self.auto_ack) {
            // An error-free transmission acknowledges the RS485 error (E70..E73) before it.
            self.history.rotate_right(1);
            self.history[0] = 99;
        }
        let answer = answer && !p.flags.no_reply;
        if p.flags.echo && self.variants.contains(&Variant::NoEcho) {
            // A firmware that does not know '?': a syntax it cannot read, refused; nothing is stored.
            if answer {
                self.error(out, REFUSED);
            } else {
                self.record(REFUSED);
            }
            return;
        }
        if p.flags.echo {
            if p.flags.buffer && !self.variants.contains(&Variant::EchoWithoutStore) {
                // `,?`: stored as with `,` alone (a command the drive cannot read is not), and echoed, so the
                // host sees what the buffer holds before it sends `!`.
                if let Body::Command(text) = p.body {
                    // A queue that is full stores nothing; the echo goes back all the same.
                    let _ = self.store(text, p.flags.position_message);
                }
            }
            if !p.flags.buffer && self.variants.contains(&Variant::EchoExecutes) {
                // Carried out as well; an error it meets is answered instead of the echo.
                if let Err(code) = self.execute(now, &p) {
                    if answer {
                        self.error(out, code);
                    } else {
                        self.record(code);
                    }
                    return;
                }
            }
            if answer {
                let received = f.bytes();
                let echo = super::variant::echo_of(&self.variants, received, received.len() - f.command_bytes().len())
                    .to_vec();
                self.reply(out, &echo);
            }
            return;
        }
        let result = self.execute(now, &p);
        match result {
            Ok(text) if answer => self.reply(out, text.as_bytes()),
            Ok(_) => {}
            Err(code) if answer => self.error(out, code),
            // Unanswered (a broadcast, `/`): the error still happened.
            Err(code) => self.record(code),
        }
    }

    pub(super) fn execute(&mut self, now: Timestamp, p: &ParsedRequest<'_>) -> Result<TextBuf<48>, ErrorCode> {
        self.update(now);
        match p.body {
            Body::Execute => match self.buffer.pop_front() {
                None => Err(REFUSED),
                Some(Stored::Text(t, dollar)) => {
                    let c = Command::parse(t.as_bytes()).map_err(|_| REFUSED)?;
                    self.run(now, c, dollar)
                }
            },
            Body::Command(text) => {
                let c = Command::parse(text).map_err(|_| REFUSED)?;
                if p.flags.position_message && !c.is_move() {
                    return Err(REFUSED);
                }
                if p.flags.buffer {
                    self.store(text, p.flags.position_message)?;
                    return Ok(TextBuf::new());
                }
                self.run(now, c, p.flags.position_message)
            }
            Body::Binary(b) => {
                let c = Command::from_binary(&b).map_err(|_| REFUSED)?;
                self.run(now, c, false)
            }
        }
    }

    /// Stores command `text` in the buffer (`,`), replacing what it held: the buffer holds one command. With
    /// [`Variant::BufferQueues`] it is appended instead, and refused ([`REFUSED`], nothing stored) when the
    /// queue already holds [`QUEUE_DEPTH`] commands. A command the drive cannot read, or a `$` on one that
    /// is not a move, is not stored (and refused).
    pub(super) fn store(&mut self, text: &[u8], position_message: bool) -> Result<(), ErrorCode> {
        let c = Command::parse(text).map_err(|_| REFUSED)?;
        if position_message && !c.is_move() {
            return Err(REFUSED);
        }
        let mut t = TextBuf::new();
        let _ = t.write_str(std::str::from_utf8(text).unwrap_or(""));
        if !self.variants.contains(&Variant::BufferQueues) {
            self.buffer.clear();
        } else if self.buffer.len() >= QUEUE_DEPTH {
            return Err(REFUSED);
        }
        self.buffer.push_back(Stored::Text(t, position_message));
        Ok(())
    }

    pub(super) fn run(&mut self, now: Timestamp, c: Command, position_message: bool) -> Result<TextBuf<48>, ErrorCode> {
        let ack = TextBuf::new();
        match c {
            Command::PosA(_) | Command::PosR(_) | Command::PosAHome => {
                if self.motion.is_some() {
                    return Err(ErrorCode::COMMAND_ACTIVE);
                }
                if self.o0 != 1 {
                    return Err(REFUSED);
                }
                let target = match c {
                    Command::PosA(p) => p.units(),
                    Command::PosR(d) => self.target + d.units(),
                    _ => 0.0,
                };
                Position::new(target).map_err(|_| REFUSED)?;
                self.target = target;
                self.reached = false;
                self.idle_after_stop = false;
                let mut settings = self.next.clone();
                // Comparators and speed steps belong to this positioning only.
                self.next.comparators.clear();
                self.next.speed_step = None;
                settings.comparators.sort_by(|a, b| a.distance.total_cmp(&b.distance));
                if c == Command::PosAHome {
                    // Machine zero is approached by this homing, once it ends: until then S16 does not show it.
                    self.homed = false;
                    self.event(format!("homing started from {:.3}", self.position));
                } else {
                    self.event(format!("motion started to {target:.3} from {:.3}", self.position));
                }
                self.motion = Some(Motion {
                    target,
                    start: self.position,
                    speed: 0.0,
                    last_tick: now,
                    settings,
                    position_message,
                    homing: c == Command::PosAHome,
                });
                Ok(ack)
            }
            Command::Speed(s) => {
                self.next.speed_percent = s.percent();
                Ok(ack)
            }
            Command::Accel(ms) => {
                self.next.accel_ms = ms.ms();
                self.next.brake_ms = ms.ms();
                Ok(ack)
            }
            Command::AccelBrake(ms) => {
                self.next.brake_ms = ms.ms();
                Ok(ack)
            }
            Command::Output { output: 0, state } => {
                let was = std::mem::replace(&mut self.o0, state.get());
                if self.o0 != was {
                    self.event(if self.o0 == 1 {
                        "switched on (O0=1)".to_string()
                    } else {
                        format!("switched off (O0={})", self.o0)
                    });
                }
                if self.o0 != 1 && self.motion.take().is_some() {
                    // Switched off: the positioning ends where the axis is.
                    self.target = self.position;
                    self.idle_after_stop = true;
                    self.event(format!("at rest {:.3}", self.position));
                }
                Ok(ack)
            }
            Command::Output { output, state } => {
                *self.outputs.get_mut(usize::from(output)).ok_or(REFUSED)? = state.get();
                Ok(ack)
            }
            Command::PosROutput { distance, output, state } => {
                if usize::from(output) >= self.outputs.len() || output == 0 || self.next.comparators.len() >= 16 {
                    return Err(REFUSED);
                }
                let number = self.next.comparators.len() as u8 + 1;
                self.next.comparators.push(Comparator {
                    distance: distance.units().abs(),
                    output,
                    state: state.get(),
                    number,
                });
                Ok(ack)
            }
            Command::PosRSpeed { distance, speed } => {
                self.next.speed_step = Some((distance.units().abs(), speed.percent()));
                Ok(ack)
            }
            Command::ReadStatus(id) => {
                let mut t = TextBuf::new();
                let _ = self.status(id, now)?.write_reply(id, &mut t);
                if self.variants.contains(&Variant::StatusValueOnly) {
                    // `S001: 12.500` without its name.
                    let mut value = TextBuf::new();
                    let _ = value.write_str(t.as_str().split_once(": ").map_or(t.as_str(), |(_, v)| v));
                    return Ok(value);
                }
                Ok(t)
            }
            Command::ReadParam(id) => {
                let mut t = TextBuf::new();
                let _ = write_param_reply(id, self.param(id).ok_or(REFUSED)?, &mut t);
                Ok(t)
            }
            Command::WriteParam(id, v) => {
                id.check(v).map_err(|_| REFUSED)?;
                *self.params.get_mut(&id.get()).ok_or(REFUSED)? = v;
                Ok(ack)
            }
        }
    }

    pub(super) fn power_cycle(&mut self, now: Timestamp) {
        let p = |id: ParamId| self.params.get(&id.get()).copied().unwrap_or(0.0);
        self.address = p(ParamId::DEVICE_ADDRESS) as u8;
        self.baud_rate = p(ParamId::BAUD_RATE) as u32;
        let p196 = p(ParamId::OPERATING_MODE) as u32;
        self.fieldbus = crate::model::FIELDBUS_MODES.contains(&p196);
        self.mode = Mode::from_p196(p196).unwrap_or_default();
        self.rx = RequestDecoder::for_drive(&self.mode);
        self.rx_parity_error = false;
        self.buffer.clear();
        if self.motion.take().is_some() {
            self.event(format!("at rest {:.3}", self.position));
        }
        self.target = self.position;
        self.o0 = 1;
        self.event("powered on (switched on, O0=1)".to_string());
        if self.fieldbus {
            self.event(format!("speaks the COMTAC fieldbus protocol (P196={p196}): no ASCII telegram is answered"));
        }
        self.pending.clear();
        self.xoff = false;
        self.held.clear();
        self.powered_at = now;
    }
}
