//! What the emulator tests share: a unit on a bench, driven through its sans-IO interface with explicit
//! timestamps.

#![allow(dead_code, unused_imports)]

pub use std::time::Duration;

pub use motionlink_link::emulator::Emulator as _;
pub use motionlink_link::Timestamp;
pub use motionlink_scu::model::{
    Actuator, CyclicObject, DataEntryExt, DataIndex, ErrorCode, Status1Flag, DATA_LIST, GROUPS,
};
pub use motionlink_scu::sim::{Emulator, RemoteMode, SimConfig};
pub use motionlink_scu::wire::*;
pub use proptest::prelude::*;

/// A unit on a bench: send requests at chosen times, read its replies.
pub struct Bench {
    pub unit: Emulator,
    pub now: Timestamp,
}

#[derive(Debug, PartialEq)]
pub struct Answer {
    pub command: Command,
    pub status: Status,
    pub data: Option<Vec<u8>>,
}

impl Bench {
    pub fn new(config: SimConfig) -> Self {
        Bench { unit: Emulator::new(config).unwrap(), now: Timestamp::ZERO }
    }

    pub fn at(&mut self, ms: u64) -> &mut Self {
        self.now = Timestamp::from_millis(ms);
        let mut out = Vec::new();
        self.unit.advance(self.now, &mut out);
        assert!(out.is_empty(), "the unit never speaks unasked");
        self
    }

    pub fn wait(&mut self, ms: u64) -> &mut Self {
        let t = self.now.since_origin().as_millis() as u64 + ms;
        self.at(t)
    }

    pub fn raw(&mut self, bytes: &[u8]) -> Vec<Answer> {
        let mut out = Vec::new();
        self.unit.receive(self.now, bytes, &mut out);
        let mut dec = ReplyDecoder::new();
        let mut answers = Vec::new();
        let mut input = &out[..];
        loop {
            let (n, ev) = dec.decode(input);
            input = &input[n..];
            match ev {
                Some(Ok(r)) => {
                    answers.push(Answer { command: r.command, status: r.status, data: r.data.map(<[u8]>::to_vec) })
                }
                Some(Err(e)) => panic!("the unit sent a bad telegram: {e}"),
                None if input.is_empty() => break,
                None => {}
            }
        }
        answers
    }

    pub fn send(&mut self, r: Request<'_>) -> Answer {
        let mut a = self.raw(&request_to_vec(&r).unwrap());
        assert_eq!(a.len(), 1, "one reply per request: {a:?}");
        a.remove(0)
    }

    pub fn status(&mut self, r: Request<'_>) -> Status {
        self.send(r).status
    }

    pub fn open(&mut self, safety: u8) {
        assert_eq!(self.status(Request::Open { safety_id: safety }), Status::Ack);
        assert_eq!(self.status(Request::Cyclic { object: 0xFF, write: &[] }), Status::Ack);
    }

    pub fn rc(&mut self) -> Status {
        self.status(Request::Cyclic { object: 0xFF, write: &[] })
    }

    pub fn get(&mut self, index: u16) -> Vec<u8> {
        let a = self.send(Request::Get { index });
        assert_eq!(a.status, Status::Ack, "RG 0x{index:04X}");
        a.data.unwrap()
    }

    pub fn position(&mut self, actuator: u8) -> i32 {
        i32::from_le_bytes(self.get(0x0010 + u16::from(actuator)).try_into().unwrap())
    }

    pub fn status1(&mut self, actuator: u8) -> u8 {
        self.get(0x0170 + u16::from(actuator))[0]
    }

    /// Sets actuator `a`'s remote position and starts its SCP11 function towards it (RE direction 9).
    pub fn go(&mut self, a: u8, position_counts: i32) {
        assert_eq!(self.set(0x3020 + u16::from(a), &position_counts.to_le_bytes()), Status::Ack);
        assert_eq!(self.status(Request::Execute { function: a - 1, params: [9, 0xFF] }), Status::Ack);
    }

    pub fn set(&mut self, index: u16, data: &[u8]) -> Status {
        self.status(Request::Transfer { index, data })
    }

    /// Runs for `ms` with an RC every 100 ms.
    pub fn keep_alive(&mut self, ms: u64) {
        for _ in 0..ms / 100 {
            self.wait(100);
            assert_eq!(self.rc(), Status::Ack);
        }
    }
}

pub fn a(n: u8) -> Actuator {
    Actuator::new(n).unwrap()
}

impl Bench {
    pub fn get_after_open(&mut self, index: u16) -> Vec<u8> {
        self.open(1);
        self.get(index)
    }
}

/// The error code the unit reports as Error_Code 1 (0x00D1).
pub fn last_error(b: &mut Bench) -> ErrorCode {
    ErrorCode(u32::from_le_bytes(b.get(0x00D1).try_into().unwrap()))
}
