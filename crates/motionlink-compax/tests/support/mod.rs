//! What the client tests share: the bus on the workspace's one rig (`motionlink_testkit::rig`: the emulated
//! drives on the manual clock, with the transcript), scripted drives, and a link that cancels a token.

#![allow(dead_code)]

use std::time::Duration;

use motionlink_compax::client::{Client, Config};
use motionlink_compax::model::{ParamId, Position};
use motionlink_compax::sim::{Emulator, SimConfig};
use motionlink_compax::wire::{Address, Mode};
use motionlink_link::cancel::CancelToken;
use motionlink_link::chunk;
use motionlink_link::pipe::PipeConfig;
use motionlink_link::transcript::Transcript;

/// The drives behind an in-memory link paced at the bus's baud rate, on the manual clock (the shared rig).
pub type Rig = motionlink_testkit::rig::Rig<Emulator>;

/// Drives at `addrs` with P196 = `p196` at `baud`, with the parameters the tests write, and a client.
pub fn rig(addrs: &[u8], p196: u32, baud: u32) -> (Rig, Client) {
    // The parameters the tests write besides P194..P196 (the emulator refuses the others).
    let mut cfg = SimConfig::bus(addrs, p196, baud);
    for n in [3, 10, 12, 20] {
        cfg = cfg.with_param(ParamId::new(n).unwrap(), 0.0);
    }
    rig_on(cfg, p196, baud, |_| {})
}

/// The bus `sim` at `baud`, and a client for mode `p196` with its settings changed by `configure`.
pub fn rig_on(sim: SimConfig, p196: u32, baud: u32, configure: impl FnOnce(&mut Config)) -> (Rig, Client) {
    let rig = Rig::new(Emulator::new(sim).unwrap(), PipeConfig::paced(baud));
    let mut bus_cfg = Config::new(Mode::from_p196(p196).unwrap(), baud);
    configure(&mut bus_cfg);
    let bus = Client::with_link(rig.link().unwrap(), rig.clock.shared(), bus_cfg).unwrap();
    (rig, bus)
}

pub fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

pub fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

pub fn sent(t: &Transcript) -> Vec<Vec<u8>> {
    t.records().into_iter().filter(|r| r.direction == chunk::Direction::ToDevice).map(|r| r.bytes).collect()
}

/// Sends `telegram` over a second connection to the emulator (another program on the bus) and reads the
/// drive's answer.
pub fn someone_else_sends(r: &Rig, telegram: &[u8]) -> Vec<u8> {
    use motionlink_link::link::Link;
    let (mut other, _) = r.host.connect();
    other.send(telegram).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 32];
    while !got.ends_with(b">") {
        let n = other.recv(&mut buf, Duration::from_secs(1)).unwrap();
        assert!(n > 0, "no answer to {telegram:?}");
        got.extend_from_slice(&buf[..n]);
    }
    got
}

/// Counts telegrams sent and cancels a token when the `n`th goes out (Ctrl-C in the middle of a long action).
pub struct CancelAfter<L> {
    pub inner: L,
    pub token: CancelToken,
    pub sends: usize,
    pub n: usize,
}

impl<L: motionlink_link::link::Link> motionlink_link::link::Link for CancelAfter<L> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), motionlink_link::link::LinkError> {
        self.sends += 1;
        if self.sends == self.n {
            self.token.cancel();
        }
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, motionlink_link::link::LinkError> {
        self.inner.recv(buf, timeout)
    }
    fn discard_input(&mut self) -> Result<(), motionlink_link::link::LinkError> {
        self.inner.discard_input()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

/// What a scripted drive answers to each telegram.
pub type Script = Box<dyn FnMut(&[u8]) -> Vec<u8> + Send>;

/// A link whose drive is a script: each telegram sent gets the bytes `answer` returns (a drive that answers
/// in ways the emulator does not, such as a bare parameter value).
pub struct Scripted {
    pub clock: motionlink_link::clock::SharedClock,
    pub answer: Script,
    pub pending: std::collections::VecDeque<u8>,
}

impl motionlink_link::link::Link for Scripted {
    fn send(&mut self, bytes: &[u8]) -> Result<(), motionlink_link::link::LinkError> {
        let reply = (self.answer)(bytes);
        self.pending.extend(reply);
        Ok(())
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, motionlink_link::link::LinkError> {
        if self.pending.is_empty() {
            self.clock.sleep(timeout);
            return Ok(0);
        }
        let n = buf.len().min(self.pending.len());
        for (slot, b) in buf.iter_mut().zip(self.pending.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
    fn discard_input(&mut self) -> Result<(), motionlink_link::link::LinkError> {
        self.pending.clear();
        Ok(())
    }
    fn describe(&self) -> String {
        "scripted drive".into()
    }
}
