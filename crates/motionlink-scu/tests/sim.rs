//! The emulator, driven through its sans-IO interface with explicit timestamps.

use std::time::Duration;

use motionlink_link::emulator::Emulator as _;
use motionlink_link::Timestamp;
use motionlink_scu::model::{status1, Actuator, CyclicObject, DataEntryExt, DataIndex, ErrorCode, DATA_LIST, GROUPS};
use motionlink_scu::sim::{Emulator, RemoteMode, SimConfig};
use motionlink_scu::wire::*;
use proptest::prelude::*;

/// A unit on a bench: send requests at chosen times, read its replies.
struct Bench {
    unit: Emulator,
    now: Timestamp,
}

#[derive(Debug, PartialEq)]
struct Answer {
    command: Command,
    status: Status,
    data: Option<Vec<u8>>,
}

impl Bench {
    fn new(config: SimConfig) -> Self {
        Bench { unit: Emulator::new(config).unwrap(), now: Timestamp::ZERO }
    }

    fn at(&mut self, ms: u64) -> &mut Self {
        self.now = Timestamp::from_millis(ms);
        let mut out = Vec::new();
        self.unit.advance(self.now, &mut out);
        assert!(out.is_empty(), "the unit never speaks unasked");
        self
    }

    fn wait(&mut self, ms: u64) -> &mut Self {
        let t = self.now.since_origin().as_millis() as u64 + ms;
        self.at(t)
    }

    fn raw(&mut self, bytes: &[u8]) -> Vec<Answer> {
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

    fn send(&mut self, r: Request<'_>) -> Answer {
        let mut a = self.raw(&request_to_vec(&r).unwrap());
        assert_eq!(a.len(), 1, "one reply per request: {a:?}");
        a.remove(0)
    }

    fn status(&mut self, r: Request<'_>) -> Status {
        self.send(r).status
    }

    fn open(&mut self, safety: u8) {
        assert_eq!(self.status(Request::Open { safety_id: safety }), Status::Ack);
        assert_eq!(self.status(Request::Cyclic { object: 0xFF, write: &[] }), Status::Ack);
    }

    fn rc(&mut self) -> Status {
        self.status(Request::Cyclic { object: 0xFF, write: &[] })
    }

    fn get(&mut self, index: u16) -> Vec<u8> {
        let a = self.send(Request::Get { index });
        assert_eq!(a.status, Status::Ack, "RG 0x{index:04X}");
        a.data.unwrap()
    }

    fn position(&mut self, actuator: u8) -> i32 {
        i32::from_le_bytes(self.get(0x0010 + u16::from(actuator)).try_into().unwrap())
    }

    fn status1(&mut self, actuator: u8) -> u8 {
        self.get(0x0170 + u16::from(actuator))[0]
    }

    /// Sets actuator `a`'s remote position and starts its SCP11 function towards it (RE direction 9).
    fn go(&mut self, a: u8, position_counts: i32) {
        assert_eq!(self.set(0x3020 + u16::from(a), &position_counts.to_le_bytes()), Status::Ack);
        assert_eq!(self.status(Request::Execute { function: a - 1, params: [9, 0xFF] }), Status::Ack);
    }

    fn set(&mut self, index: u16, data: &[u8]) -> Status {
        self.status(Request::Transfer { index, data })
    }

    /// Runs for `ms` with an RC every 100 ms.
    fn keep_alive(&mut self, ms: u64) {
        for _ in 0..ms / 100 {
            self.wait(100);
            assert_eq!(self.rc(), Status::Ack);
        }
    }
}

fn a(n: u8) -> Actuator {
    Actuator::new(n).unwrap()
}

#[test]
fn remote_commands_are_refused_outside_remote_mode() {
    let mut b = Bench::new(SimConfig::default());
    for r in [
        Request::Get { index: 0x0011 },
        Request::Cyclic { object: 0xFF, write: &[] },
        Request::Transfer { index: 0x3011, data: &[50, 0] },
        Request::Execute { function: 0, params: [9, 0xFF] },
        Request::Stop { function: 0, param: 1 },
    ] {
        assert_eq!(b.status(r), Status::PermissionError, "{r:?}");
    }
    assert_eq!(b.status(Request::Abort), Status::Ack, "RA is harmless outside remote mode");
}

#[test]
fn an_rc_must_come_before_any_other_command() {
    let mut b = Bench::new(SimConfig::default());
    assert_eq!(b.status(Request::Open { safety_id: 0 }), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError);
    assert_eq!(b.rc(), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::Ack);
    assert_eq!(b.unit.mode(), RemoteMode::Active(motionlink_scu::model::SafetyId::StopAllAndLock));
}

#[test]
fn ro_with_an_unknown_safety_id_is_a_data_error() {
    let mut b = Bench::new(SimConfig::default());
    assert_eq!(b.status(Request::Open { safety_id: 3 }), Status::ParameterDataError);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
}

#[test]
fn chapter5_routine_moves_actuator_1_and_reports_its_position() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    assert_eq!(b.set(0x3011, &100u16.to_le_bytes()), Status::Ack);
    assert_eq!(b.set(0x3021, &400i32.to_le_bytes()), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
    b.wait(100);
    assert_ne!(b.status1(1) & status1::MOTION, 0, "status bit 4 is set while the motion is active");
    let mut t = 0;
    while b.status1(1) & status1::MOTION != 0 {
        b.keep_alive(100);
        t += 100;
        assert!(t < 10_000, "the move never ended");
    }
    assert_eq!(b.position(1), 400);
    // 400 counts at 110 counts/s is 3.6 s plus the ramps.
    assert!((3_600..=4_300).contains(&t), "took {t} ms");
    assert_eq!(b.status(Request::Stop { function: 0, param: 1 }), Status::Ack);
    assert!(b.unit.executed_functions().is_empty());
    assert_eq!(b.status(Request::Abort), Status::Ack);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
    assert_eq!(b.get_after_open(0x0091), 400u32.to_le_bytes(), "cumulated stroke");
}

impl Bench {
    fn get_after_open(&mut self, index: u16) -> Vec<u8> {
        self.open(1);
        self.get(index)
    }
}

#[test]
fn speed_scales_the_motion() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.set(0x3012, &50u16.to_le_bytes());
    b.go(2, 300);
    b.keep_alive(2000);
    let p = b.position(2);
    // 55 counts/s at 50 %: about 100 counts in 2 s after the ramp.
    assert!((95..=112).contains(&p), "position {p}");
    assert_eq!(u16::from_le_bytes(b.get(0x00F2).try_into().unwrap()), 50, "speed A2 in percent");
    assert!(u16::from_le_bytes(b.get(0x00A2).try_into().unwrap()) > 0, "a moving actuator draws current");
    assert_eq!(b.position(1), 0, "actuator 1 is on another function");
}

#[test]
fn rs_fast_stops_at_once_and_soft_stops_along_the_ramp() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(1000);
    let (p1, p2) = (b.position(1), b.position(2));
    assert_eq!(b.status(Request::Stop { function: 0, param: 0 }), Status::Ack);
    assert_eq!(b.status(Request::Stop { function: 1, param: 1 }), Status::Ack);
    b.keep_alive(500);
    assert_eq!(b.position(1), p1, "fast stop: no further travel");
    let travel = b.position(2) - p2;
    // Soft stop from 110 counts/s over a 300 ms ramp: about 16 counts.
    assert!((10..=25).contains(&travel), "soft stop travelled {travel}");
    assert!(!b.unit.any_moving());
}

#[test]
fn motion_directions_go_to_the_stroke_ends_and_stored_positions() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.status(Request::Execute { function: 0, params: [2, 0xFF] }); // Out
    b.keep_alive(9_000);
    assert_eq!(b.position(1), 865);
    let s = b.status1(1);
    assert_ne!(s & status1::OUT_POSITION, 0);
    assert_ne!(s & status1::LIMIT_IN_OUT, 0);
    assert_eq!(s & (status1::IN_POSITION | status1::MOTION), 0);
    b.status(Request::Stop { function: 0, param: 1 });
    b.status(Request::Execute { function: 0, params: [4, 0xFF] }); // Mem2
    b.keep_alive(9_000);
    assert_eq!(b.position(1), 300);
    b.status(Request::Execute { function: 0, params: [1, 0xFF] }); // In
    b.keep_alive(9_000);
    assert_eq!(b.position(1), 0);
    assert_ne!(b.status1(1) & status1::IN_POSITION, 0);
    assert_eq!(u32::from_le_bytes(b.get(0x0071).try_into().unwrap()), 1, "relay out cycles: Out");
    assert_eq!(u32::from_le_bytes(b.get(0x0061).try_into().unwrap()), 2, "relay in cycles: Mem2 (865 -> 300), In");
}

#[test]
fn targets_beyond_the_stroke_stop_at_its_end() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 5000);
    b.keep_alive(10_000);
    assert_eq!(b.position(1), 865);
}

#[test]
fn watchdog_with_safety_id_0_stops_and_locks_until_ro() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    b.go(1, 800);
    b.keep_alive(1000);
    let p = b.position(1);
    assert!(b.unit.is_moving(a(1)));
    // Last RC at 1000 ms. At 1499 ms all is well; the watchdog fires at 1500 ms.
    b.at(1499);
    assert!(b.unit.is_moving(a(1)));
    assert_eq!(b.unit.stats().watchdog_expiries, 0);
    b.at(1500);
    assert!(!b.unit.is_moving(a(1)), "all motions stop on the watchdog");
    assert_eq!(b.unit.mode(), RemoteMode::Locked);
    assert_eq!(b.unit.last_error(), ErrorCode::from_bit(22));
    // Only RC, RA and RO are accepted now.
    assert_eq!(b.rc(), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
    b.wait(2000);
    assert!(!b.unit.is_moving(a(1)));
    assert!(b.unit.position(a(1)).unwrap() - p < 60, "stopped where the watchdog fired");
    b.open(0);
    assert_eq!(b.get(0x00D1), (1u32 << 21).to_le_bytes(), "error code 1 has bit 22 (mask 1 << 21) set");
}

#[test]
fn watchdog_with_safety_id_1_stops_and_the_next_rc_rearms() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.wait(600);
    assert!(!b.unit.is_moving(a(1)));
    assert!(matches!(b.unit.mode(), RemoteMode::TimedOut(_)));
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError, "an RC first");
    assert_eq!(b.rc(), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
    b.keep_alive(300);
    assert!(b.unit.is_moving(a(1)), "motion can start again");
}

#[test]
fn watchdog_with_safety_id_2_stops_only_remote_motions() {
    let mut b = Bench::new(SimConfig::default());
    b.open(2);
    b.go(1, 800);
    b.unit.press_hand_switch(2, true);
    assert_ne!(b.get(0x0040)[0] & 0b1000, 0, "key K4 (F2 out) shows as pressed");
    b.wait(600);
    assert!(!b.unit.is_moving(a(1)), "the remote motion stopped");
    assert!(b.unit.is_moving(a(2)), "the hand-switch motion goes on");
    b.unit.release_hand_switch();
    b.wait(1000);
    assert!(!b.unit.is_moving(a(2)));
}

#[test]
fn watchdog_runs_from_ro_even_without_an_rc() {
    let mut b = Bench::new(SimConfig::default());
    assert_eq!(b.status(Request::Open { safety_id: 1 }), Status::Ack);
    b.wait(501);
    assert_eq!(b.unit.stats().watchdog_expiries, 1);
}

#[test]
fn a_session_with_rc_every_400_ms_never_times_out() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    for _ in 0..1500 {
        b.wait(400);
        assert_eq!(b.rc(), Status::Ack);
    }
    assert_eq!(b.unit.stats().watchdog_expiries, 0);
}

#[test]
fn rt_is_checked() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    assert_eq!(b.set(0x0011, &[1, 0, 0, 0]), Status::ParameterDataError, "not remote data");
    assert_eq!(b.set(0x3017, &[1, 0, 0]), Status::ParameterCountError, "wrong size");
    assert_eq!(b.set(0x3011, &101u16.to_le_bytes()), Status::ParameterDataError, "speed above 100 %");
    assert_eq!(b.set(0x3099, &[1, 0]), Status::ParameterDataError, "no such entry");
    assert_eq!(b.set(0x3011, &100u16.to_le_bytes()), Status::Ack);
    // A whole group, all or nothing.
    let mut speeds = Vec::new();
    for s in [10u16, 20, 30, 40, 50, 60, 70, 80, 90, 101] {
        speeds.extend_from_slice(&s.to_le_bytes());
    }
    assert_eq!(b.set(0x3010, &speeds), Status::ParameterDataError);
    assert_eq!(b.get(0x3011), 100u16.to_le_bytes(), "nothing of the refused group was written");
    speeds[18] = 100;
    assert_eq!(b.set(0x3010, &speeds), Status::Ack);
    assert_eq!(b.get(0x3013), 30u16.to_le_bytes());
}

#[test]
fn re_and_rs_parameters_are_checked() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    assert_eq!(b.status(Request::Execute { function: 0, params: [10, 0xFF] }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0] }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Execute { function: 12, params: [0xFF, 0xFF] }), Status::ParameterDataError, "F13");
    assert_eq!(
        b.status(Request::Execute { function: 5, params: [9, 0xFF] }),
        Status::PermissionError,
        "F6 drives nothing"
    );
    assert_eq!(b.status(Request::Stop { function: 0, param: 2 }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Stop { function: 10, param: 0 }), Status::ParameterDataError, "buzzer: -1");
    assert_eq!(b.status(Request::Execute { function: 0, params: [0, 0xFF] }), Status::Ack, "direction 0: no motion");
    assert!(!b.unit.any_moving());
}

#[test]
fn wrong_crc_gets_cse_and_unknown_command_gets_ice() {
    let mut b = Bench::new(SimConfig::default());
    let mut t = request_to_vec(&Request::Open { safety_id: 0 }).unwrap();
    t[4] ^= 0xFF;
    let answers = b.raw(&t);
    assert_eq!(answers, [Answer { command: Command::Open, status: Status::ChecksumError, data: None }]);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
    let mut unknown = b"RQ".to_vec();
    unknown.extend_from_slice(&crc16(b"RQ").to_le_bytes());
    let out = {
        let mut out = Vec::new();
        b.unit.receive(b.now, &unknown, &mut out);
        out
    };
    assert_eq!(&out[..3], &[b'R', b'Q', 0x83], "ICE, with the unknown letters repeated");
    assert_eq!(crc16(&out[..3]).to_le_bytes(), [out[3], out[4]]);
}

#[test]
fn a_telegram_left_incomplete_for_1000_ms_is_dropped() {
    let mut b = Bench::new(SimConfig::default());
    let t = request_to_vec(&Request::Open { safety_id: 0 }).unwrap();
    assert!(b.raw(&t[..2]).is_empty());
    b.wait(1001);
    // The rest arrives too late: the start was dropped, so these bytes are garbage and get no reply.
    assert!(b.raw(&t[2..]).is_empty());
    assert_eq!(b.unit.stats().dropped_partial, 1);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
    // Within the limit, bytes may trickle in.
    assert!(b.raw(&t[..2]).is_empty());
    b.wait(999);
    assert_eq!(b.raw(&t[2..]).len(), 1);
    assert!(matches!(b.unit.mode(), RemoteMode::AwaitingRc(_)));
}

#[test]
fn rc_exchanges_the_data_of_a_cyclic_object() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let obj = CyclicObject::new(
        &[DataIndex(0x3021), DataIndex(0x3011)],
        &[DataIndex(0x0011), DataIndex(0x0171), DataIndex(0x0010)],
    )
    .unwrap();
    assert_eq!(b.set(0x3001, &obj.to_bytes()), Status::Ack);
    assert_eq!(b.get(0x3001), obj.to_bytes());
    let mut write = 250i32.to_le_bytes().to_vec();
    write.extend_from_slice(&80u16.to_le_bytes());
    let answer = b.send(Request::Cyclic { object: 0, write: &write });
    assert_eq!(answer.status, Status::Ack);
    let data = answer.data.unwrap();
    assert_eq!(data.len(), 4 + 1 + 24, "position, status, all six positions");
    assert_eq!(&data[..4], &0i32.to_le_bytes());
    assert_eq!(data[4] & status1::AVAILABLE, status1::AVAILABLE);
    assert_eq!(b.get(0x3021), 250i32.to_le_bytes(), "the write data landed");
    assert_eq!(b.get(0x3011), 80u16.to_le_bytes());
    // Wrong write length, unknown object, data without object.
    assert_eq!(b.status(Request::Cyclic { object: 0, write: &write[..3] }), Status::ParameterCountError);
    assert_eq!(b.status(Request::Cyclic { object: 5, write: &[] }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Cyclic { object: 0xFF, write: &[1] }), Status::ParameterCountError);
    // An empty object answers with ctp 0.
    let empty = b.send(Request::Cyclic { object: 1, write: &[] });
    assert_eq!((empty.status, empty.data), (Status::Ack, Some(vec![])));
}

#[test]
fn a_cyclic_object_may_not_write_read_only_data() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let bad = CyclicObject::new(&[DataIndex(0x0011)], &[]).unwrap();
    assert_eq!(b.set(0x3002, &bad.to_bytes()), Status::ParameterDataError);
}

#[test]
fn a_cyclic_object_whose_data_would_not_fit_one_reply_is_refused() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    // Six times all UserPositionData (624 bytes each): more than one reply carries.
    let huge = CyclicObject::new(&[], &[DataIndex(0x2000); 6]).unwrap();
    assert_eq!(b.set(0x3001, &huge.to_bytes()), Status::ParameterDataError);
    // The largest that fits still works: one group of 624 bytes, answered with every RC.
    let big = CyclicObject::new(&[], &[DataIndex(0x2000)]).unwrap();
    assert_eq!(b.set(0x3001, &big.to_bytes()), Status::Ack);
    let answer = b.send(Request::Cyclic { object: 0, write: &[] });
    assert_eq!(answer.status, Status::Ack);
    assert_eq!(answer.data.map(|d| d.len()), Some(624));
}

#[test]
fn every_index_of_the_data_list_answers_with_its_size() {
    let mut b = Bench::new(SimConfig::scp11(6));
    b.open(1);
    for e in DATA_LIST {
        assert_eq!(b.get(e.index().0).len(), e.size(), "{}", e.name);
    }
    for g in GROUPS {
        assert_eq!(b.get(g.index.0).len(), g.size(), "{}", g.name);
    }
    assert_eq!(b.status(Request::Get { index: 0x0017 }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Get { index: 0x4000 }), Status::ParameterDataError);
    let fw = b.get(0x0001);
    assert!(fw.starts_with(b"SCU V2B3"));
    assert_eq!(b.get(0x3021), 100i32.to_le_bytes(), "remote position defaults to memory 1 of user 1");
    assert_eq!(b.get(0x3011), 100u16.to_le_bytes(), "remote speed defaults to the function speed");
    assert_eq!(b.get(0x0100)[0] & 1, 1, "mains connected");
    // The collection indices of the manual's first column.
    assert_eq!(b.get(0x1000), b.get(0x1010), "the 1000 collection is the conversion factors");
    assert_eq!(b.get(0x1000).len(), 6 * 4);
    assert_eq!(b.get(0x3000).len(), 5 * 24 + 10 * 2 + 6 * 4, "cyclic objects, remote speeds, remote positions");
}

#[test]
fn the_3000_collection_is_written_whole_or_not_at_all() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let mut block = b.get(0x3000);
    // Remote speed F2 (after the five 24-byte cyclic objects and F1's speed) and remote position A1.
    block[5 * 24 + 2..5 * 24 + 4].copy_from_slice(&40u16.to_le_bytes());
    block[5 * 24 + 20..5 * 24 + 24].copy_from_slice(&321i32.to_le_bytes());
    assert_eq!(b.set(0x3000, &block), Status::Ack);
    assert_eq!(b.get(0x3012), 40u16.to_le_bytes());
    assert_eq!(b.get(0x3021), 321i32.to_le_bytes());
    // A speed out of range anywhere refuses the whole block.
    block[5 * 24..5 * 24 + 2].copy_from_slice(&101u16.to_le_bytes());
    block[5 * 24 + 20..5 * 24 + 24].copy_from_slice(&5i32.to_le_bytes());
    assert_eq!(b.set(0x3000, &block), Status::ParameterDataError);
    assert_eq!(b.get(0x3021), 321i32.to_le_bytes(), "nothing written");
    assert_eq!(b.set(0x3000, &block[1..]), Status::ParameterCountError);
}

#[test]
fn switching_functions_show_in_the_data_list() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let on = |f: u8| Request::Execute { function: f, params: [0xFF, 0xFF] };
    let off = |f: u8| Request::Stop { function: f, param: 0xFF };
    for (f, index, bit) in [(10u8, 0x0140u16, 0u8), (16, 0x0110, 0), (17, 0x0110, 1), (20, 0x0120, 0), (21, 0x0120, 1)]
    {
        assert_eq!(b.status(on(f)), Status::Ack);
        assert_ne!(b.get(index)[0] & (1 << bit), 0, "F{} on", f + 1);
        assert_eq!(b.status(off(f)), Status::Ack);
        assert_eq!(b.get(index)[0] & (1 << bit), 0, "F{} off", f + 1);
    }
}

#[test]
fn emergency_stop_stops_everything_and_blocks_motion_until_released() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(500);
    assert!(b.unit.is_moving(a(1)));
    assert_eq!(b.status(Request::Execute { function: 19, params: [0xFF, 0xFF] }), Status::Ack);
    assert!(!b.unit.any_moving());
    assert_eq!(b.get(0x0162), 0x03FFu16.to_le_bytes(), "all functions locked");
    assert_eq!(b.get(0x00E1)[0] & 0b110, 0, "no release flags");
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
    assert_eq!(b.status(Request::Stop { function: 19, param: 0xFF }), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
}

#[test]
fn a_drive_error_fast_stops_its_drive_and_enters_the_history() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(500);
    b.unit.inject_error(ErrorCode::from_bit(15));
    assert!(!b.unit.is_moving(a(1)));
    assert!(b.unit.is_moving(a(2)));
    b.unit.inject_error(ErrorCode::from_bit(12));
    let codes = b.get(0x00D0);
    assert_eq!(&codes[..4], &(1u32 << 11).to_le_bytes(), "last recent: bit 12");
    assert_eq!(&codes[4..8], &(1u32 << 14).to_le_bytes(), "history 1: bit 15");
    assert_eq!(u32::from_le_bytes(b.get(0x0081).try_into().unwrap()), 1, "actuator error counter");
}

#[test]
fn total_current_is_counted_and_its_maximum_is_of_the_sum_at_one_time() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(1500);
    let current = |b: &mut Bench, index: u16| u16::from_le_bytes(b.get(index).try_into().unwrap());
    let max_a1 = current(&mut b, 0x00B1);
    assert!(max_a1 > 0);
    // Only actuator 1 has moved: the highest total is its own highest current.
    assert_eq!(current(&mut b, 0x00BF), max_a1);
    b.go(2, 800);
    b.keep_alive(500);
    let total_now = current(&mut b, 0x00A1) + current(&mut b, 0x00A2);
    assert!(current(&mut b, 0x00BF) >= total_now);
    assert_eq!(u16::from_le_bytes(b.get(0x008F)[..2].try_into().unwrap()), 0);
    b.unit.inject_error(ErrorCode::from_bit(14));
    assert!(!b.unit.any_moving(), "a total over-current fast-stops every drive");
    assert_eq!(u16::from_le_bytes(b.get(0x008F)[..2].try_into().unwrap()), 1, "Number_Total_Over_Current");
}

#[test]
fn ra_ends_remote_mode_and_stops_remote_motions() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(300);
    assert_eq!(b.status(Request::Abort), Status::Ack);
    assert!(!b.unit.any_moving());
    b.wait(2000);
    assert_eq!(b.unit.stats().watchdog_expiries, 0, "no watchdog outside remote mode");
}

#[test]
fn tlt_preset_drives_two_columns_on_f1_stalls_below_30_percent_and_reads_below_zero_at_the_in_end() {
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.set(0x3021, &300i32.to_le_bytes());
    b.set(0x3022, &300i32.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [9, 0xFF] });
    b.keep_alive(5_000);
    assert_eq!((b.position(1), b.position(2)), (300, 300));
    b.status(Request::Stop { function: 0, param: 1 });
    b.set(0x3011, &20u16.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [1, 0xFF] });
    b.keep_alive(3_000);
    assert_eq!(b.position(1), 300, "stalled at 20 %");
    assert_ne!(b.status1(1) & status1::MOTION, 0, "the motion bit stays set while stalled");
    b.status(Request::Stop { function: 0, param: 0 });
    b.set(0x3011, &100u16.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [1, 0xFF] });
    b.keep_alive(5_000);
    assert_eq!(b.position(1), -3, "a few counts below zero at the In end");
}

#[test]
fn config_from_toml() {
    let c = SimConfig::from_toml(
        r#"
        actuators = 3
        speed_mode = "counts_per_second"
        default_speed = 200
        [functions]
        F1 = [1, 3]
        [[actuator]]
        stroke_max_counts = 1000
        "#,
    )
    .unwrap();
    assert_eq!(c.actuators.len(), 3);
    assert_eq!(c.actuators[0].stroke_max_counts, 1000);
    assert_eq!(c.functions[0], vec![a(1), a(3)]);
    assert_eq!(c.functions[1], vec![a(2)], "the rest stays SCP11");
    let mut b = Bench::new(c);
    b.open(1);
    assert_eq!(b.set(0x3011, &1000u16.to_le_bytes()), Status::Ack, "counts/s allow up to 1000");
    assert_eq!(SimConfig::from_toml("preset = \"tlt\"").unwrap(), SimConfig::tlt());
    for bad in [
        "actuators = 7",
        "preset = \"nope\"",
        "[functions]\nF11 = [1]",
        "[functions]\nF1 = [5]",
        "colour = 1",
        "[[actuator]]\nstroke_min_counts = 900",
    ] {
        let err = SimConfig::from_toml(bad).unwrap_err();
        assert!(!err.0.is_empty(), "{bad}");
    }
}

/// One step of a random session: a well-formed request (with arbitrary, often wrong, parameters) after a pause.
#[derive(Debug, Clone)]
enum Step {
    Open(u8),
    Cyclic(u8, Vec<u8>),
    Get(u16),
    Transfer(u16, Vec<u8>),
    Execute(u8, [u8; 2]),
    Stop(u8, u8),
    Abort,
}

fn known_index() -> impl Strategy<Value = u16> {
    let indices: Vec<u16> = DATA_LIST.iter().map(|e| e.index().0).chain(GROUPS.iter().map(|g| g.index.0)).collect();
    prop_oneof![proptest::sample::select(indices), any::<u16>()]
}

fn step() -> impl Strategy<Value = Step> {
    let bytes = || proptest::collection::vec(any::<u8>(), 0..40);
    prop_oneof![
        (0..4u8).prop_map(Step::Open),
        (prop_oneof![Just(0xFFu8), 0..6u8], bytes()).prop_map(|(o, w)| Step::Cyclic(o, w)),
        known_index().prop_map(Step::Get),
        (known_index(), bytes()).prop_map(|(i, d)| Step::Transfer(i, d)),
        // Motion functions, directions 0..9 and a remote position above all: the unit moves.
        (0..23u8, prop_oneof![0..10u8, any::<u8>()], any::<u8>()).prop_map(|(f, d, p)| Step::Execute(f, [d, p])),
        (0..23u8, any::<u8>()).prop_map(|(f, p)| Step::Stop(f, p)),
        Just(Step::Abort),
    ]
}

proptest! {
    /// Well-formed requests with arbitrary parameters, at arbitrary times: the unit never panics, answers
    /// every request with exactly one well-formed reply of the same command, keeps its actuators inside
    /// their strokes, and opens again at the end.
    #[test]
    fn random_sessions_of_valid_telegrams(steps in proptest::collection::vec((0..700u64, step()), 1..60)) {
        let mut b = Bench::new(SimConfig::default());
        let mut t = 0;
        for (pause, s) in &steps {
            t += pause;
            b.at(t);
            let request = match s {
                Step::Open(id) => Request::Open { safety_id: *id },
                Step::Cyclic(o, w) => Request::Cyclic { object: *o, write: w },
                Step::Get(i) => Request::Get { index: *i },
                Step::Transfer(i, d) => Request::Transfer { index: *i, data: d },
                Step::Execute(f, p) => Request::Execute { function: *f, params: *p },
                Step::Stop(f, p) => Request::Stop { function: *f, param: *p },
                Step::Abort => Request::Abort,
            };
            let answers = b.raw(&request_to_vec(&request).unwrap());
            prop_assert_eq!(answers.len(), 1, "{:?} got {:?}", s, answers);
            prop_assert_eq!(answers[0].command, request.command());
            for n in 1..=2 {
                let p = b.unit.position(a(n)).unwrap();
                prop_assert!((0..=865).contains(&p), "A{} at {}", n, p);
            }
        }
        b.wait(2000);
        b.open(1);
    }

    /// Arbitrary bytes never panic the emulator; after a pause the unit answers a good telegram again.
    #[test]
    fn arbitrary_bytes_never_panic_and_the_unit_recovers(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..80), 0..20)) {
        let mut unit = Emulator::new(SimConfig::default()).unwrap();
        let mut out = Vec::new();
        let mut t = 0;
        for c in &chunks {
            t += 3;
            unit.receive(Timestamp::from_millis(t), c, &mut out);
        }
        // Every reply the unit made is a well-formed telegram.
        let mut dec = ReplyDecoder::new();
        let mut input = &out[..];
        loop {
            let (n, ev) = dec.decode(input);
            input = &input[n..];
            match ev {
                Some(ev) => prop_assert!(ev.is_ok(), "{:?}", ev),
                None if input.is_empty() => break,
                None => {}
            }
        }
        out.clear();
        let later = Timestamp::from_millis(t) + Duration::from_millis(1500);
        unit.receive(later, &request_to_vec(&Request::Open { safety_id: 1 }).unwrap(), &mut out);
        prop_assert_eq!(&out[..3], b"RO\x06");
    }
}

// ---------------------------------------------------------------------------------------------------------
// Events, error bits, presets, and the bytes the public drivers send

/// The error code the unit reports as Error_Code 1 (0x00D1).
fn last_error(b: &mut Bench) -> ErrorCode {
    ErrorCode(u32::from_le_bytes(b.get(0x00D1).try_into().unwrap()))
}

#[test]
fn events_tell_what_the_unit_did() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    b.go(1, 100);
    b.keep_alive(2_000);
    b.wait(600); // no RC: the watchdog expires
    let events = b.unit.take_events();
    let expected = [
        "remote mode opened (Safety_ID 0)",
        "F1 started direction 9 (move to remote position): A1 -> 100",
        "A1 at rest 100 counts",
        "error bit 22 set (remote communication time out)",
        "remote mode ended by watchdog (Safety_ID 0): all motions stopped; remote motion locked until RO",
    ];
    assert_eq!(events, expected);
    assert!(b.unit.take_events().is_empty(), "each event is taken once");
}

#[test]
fn events_name_a_stop_and_where_each_actuator_came_to_rest() {
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.unit.take_events();
    b.set(0x3021, &400i32.to_le_bytes());
    b.set(0x3022, &400i32.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [9, 0xFF] });
    b.keep_alive(1_000);
    b.status(Request::Stop { function: 0, param: 0 });
    let events = b.unit.take_events();
    assert_eq!(events[0], "F1 started direction 9 (move to remote position): A1 -> 400, A2 -> 400");
    assert_eq!(events[1], "F1 stopped (RS fast)");
    let p1 = b.position(1);
    let p2 = b.position(2);
    assert!(p1 > 50 && p1 < 400, "{p1}");
    assert_eq!(&events[2..], [format!("A1 at rest {p1} counts"), format!("A2 at rest {p2} counts")]);
}

#[test]
fn the_bits_the_manual_resets_on_the_next_motion_are_reset_when_it_starts_and_only_those() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    // Bits 12 (over-temperature), 14 (total current), 15 and 16 (drives 1 and 2), 21 (synchronisation), 22.
    let bits = [12u8, 14, 15, 16, 21, 22];
    let code = ErrorCode(bits.iter().map(|&n| ErrorCode::from_bit(n).0).sum());
    b.unit.inject_error(code);
    b.unit.inject_error(ErrorCode::from_bit(15)); // now Error_Code 1; the first code is history 1
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    b.unit.take_events();
    b.go(1, 50);
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "bit 15 of Error_Code 1 cleared when the motion started");
    assert_eq!(b.unit.take_events()[0], "error bit 15 reset by the next motion");
    let history = u32::from_le_bytes(b.get(0x00D2).try_into().unwrap());
    assert_eq!(history, code.0, "the history keeps what happened");
    // A code with bits of both kinds loses only 14..21.
    b.keep_alive(1_000);
    b.unit.inject_error(code);
    b.go(1, 10);
    assert_eq!(last_error(&mut b), ErrorCode(ErrorCode::from_bit(12).0 | ErrorCode::from_bit(22).0));
    // RE with direction 0 ("no motion") is no motion: nothing is reset.
    b.unit.inject_error(ErrorCode::from_bit(16));
    assert_eq!(b.status(Request::Execute { function: 1, params: [0, 0xFF] }), Status::Ack);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(16));
    assert_eq!(b.status(Request::Execute { function: 1, params: [2, 0xFF] }), Status::Ack);
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
}

#[test]
fn a_stalled_tlt_column_stops_with_its_drive_error_within_10_s_and_the_next_motion_clears_it() {
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.set(0x3012, &20u16.to_le_bytes()); // F2 (column 1 alone) at 20 %: below the 30 % a TLT needs
    b.set(0x3021, &400i32.to_le_bytes());
    b.status(Request::Execute { function: 1, params: [9, 0xFF] });
    b.keep_alive(4_000);
    assert_ne!(b.status1(1) & status1::MOTION, 0, "stalled, the motion is still on");
    b.unit.take_events();
    b.keep_alive(6_000);
    assert_eq!(b.status1(1) & status1::MOTION, 0, "the drive time-out stopped it");
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    assert_eq!(u32::from_le_bytes(b.get(0x0081).try_into().unwrap()), 1, "actuator error counter");
    let events = b.unit.take_events();
    assert!(events.contains(&"error bit 15 set (error with drive 1)".to_string()), "{events:?}");
    assert!(
        events.contains(&"A1 at rest 0 counts".to_string()) || events.contains(&"A1 at rest -3 counts".to_string()),
        "{events:?}"
    );
    b.status(Request::Stop { function: 1, param: 0 });
    b.set(0x3012, &100u16.to_le_bytes());
    b.status(Request::Execute { function: 1, params: [9, 0xFF] });
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "reset on the next motion");
    b.keep_alive(5_000);
    assert_eq!(b.position(1), 400);
}

#[test]
fn a_drive_blocked_by_a_configured_obstacle_stops_there_with_its_drive_error() {
    let config = SimConfig::from_toml("[[actuator]]\nobstacle_counts = 300\nstall_error_after_ms = 2000\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 600);
    b.keep_alive(4_000);
    assert_eq!(b.position(1), 300, "it cannot pass the obstacle");
    assert_ne!(b.status1(1) & status1::MOTION, 0, "pushing");
    let current = u16::from_le_bytes(b.get(0x00A1).try_into().unwrap());
    assert_eq!(current, 60, "twice its full-speed current while blocked");
    b.keep_alive(2_000);
    assert_eq!(b.status1(1) & status1::MOTION, 0);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    // Away from the obstacle it moves again, and the bit is gone.
    b.go(1, 100);
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
    b.keep_alive(3_000);
    assert_eq!(b.position(1), 100);
}

#[test]
fn a_total_current_above_the_configured_limit_sets_bit_14_and_stops_every_drive() {
    // Each drive takes 3.0 A at full speed: one alone stays under 5.0 A, two together do not.
    let config = SimConfig::from_toml("total_current_limit_deci_amps = 50\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.keep_alive(1_000);
    assert!(b.unit.is_moving(a(1)));
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
    b.go(2, 800);
    b.keep_alive(1_000);
    assert!(!b.unit.any_moving(), "bit 14 fast-stops every motion");
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(14));
    assert_eq!(u32::from_le_bytes(b.get(0x008F).try_into().unwrap()), 1, "Number_Total_Over_Current");
    b.go(1, 0);
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "reset on the next motion");
}

#[test]
fn an_error_scheduled_in_the_configuration_is_raised_at_its_time() {
    let config =
        SimConfig::from_toml("[[error]]\nbit = 12\nat_ms = 3000\n[[error]]\nbit = 16\nat_ms = 1000\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(900);
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
    b.keep_alive(200);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(16), "drive 2's error at 1 s");
    assert!(b.unit.is_moving(a(1)) && !b.unit.is_moving(a(2)), "it stops its own drive only");
    b.keep_alive(2_000);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(12), "over-temperature at 3 s");
    assert!(!b.unit.any_moving(), "bit 12 stops every motion");
    for bad in ["[[error]]\nbit = 33\nat_ms = 1", "[[error]]\nbit = 3", "[[error]]\nbit = 3\nat_ms = 1\ncolour = 2"] {
        assert!(SimConfig::from_toml(bad).is_err(), "{bad}");
    }
}

#[test]
fn a_new_remote_speed_changes_a_running_motion_along_the_ramp() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(1_000);
    let speed = |b: &mut Bench| u16::from_le_bytes(b.get(0x00F1).try_into().unwrap());
    assert_eq!(speed(&mut b), 100);
    b.set(0x3011, &40u16.to_le_bytes());
    b.wait(100);
    let during = speed(&mut b);
    assert!(during < 100 && during > 40, "slowing along the ramp: {during} %");
    b.keep_alive(500);
    assert_eq!(speed(&mut b), 40);
    // A function's speed does not touch the motions of another.
    b.go(2, 800);
    b.keep_alive(500);
    b.set(0x3011, &60u16.to_le_bytes());
    b.keep_alive(500);
    assert_eq!(u16::from_le_bytes(b.get(0x00F2).try_into().unwrap()), 100);
}

#[test]
fn virtual_limits_bound_every_motion() {
    let config = SimConfig::from_toml(
        "[[actuator]]\n[actuator.user_positions]\nvirtual_limit_in_counts = 50\nvirtual_limit_out_counts = 500\n\
         users = [{memory_counts = [100, 300, 500, 700], intermediate_in_counts = 200, intermediate_out_counts = 600}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}]\n\
         start_position_counts = 100\n",
    )
    .unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.keep_alive(6_000);
    assert_eq!(b.position(1), 500);
    b.go(1, -100);
    b.keep_alive(6_000);
    assert_eq!(b.position(1), 50);
    let upd = b.get(0x2001);
    assert_eq!(&upd[96..104], [50i32.to_le_bytes(), 500i32.to_le_bytes()].concat(), "readable in UserPositionData");
}

#[test]
fn liftkit_preset_maps_f1_f2_and_f8_as_the_public_drivers_assume() {
    let c = SimConfig::liftkit();
    assert_eq!(c.functions[0], vec![a(1)]);
    assert_eq!(c.functions[1], vec![a(2)]);
    assert_eq!(c.functions[7], vec![a(1), a(2)]);
    assert!(c.functions.iter().enumerate().all(|(i, f)| [0, 1, 7].contains(&i) || f.is_empty()));
    assert_eq!(SimConfig::from_toml("preset = \"liftkit\"").unwrap(), c);
    assert_eq!(SimConfig::preset("liftkit"), Some(c));
}

/// The exact telegrams of the public Ewellix ROS drivers (field notes, "What the public drivers send"), and the
/// exact replies a unit gives them.
#[test]
fn the_bytes_the_public_ros_drivers_send_are_understood() {
    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace().map(|h| u8::from_str_radix(h, 16).unwrap()).collect()
    }
    let mut b = Bench::new(SimConfig::liftkit());
    let exchange = |b: &mut Bench, request: &str| -> Vec<u8> {
        let mut out = Vec::new();
        b.unit.receive(b.now, &hex(request), &mut out);
        out
    };
    let ack = |c: &[u8; 2]| {
        let mut r = vec![c[0], c[1], 0x06];
        let crc = crc16(&r);
        r.extend_from_slice(&crc.to_le_bytes());
        r
    };
    // RO with one Safety_ID byte, sent twice to wake the unit; the keepalive RC without a cyclic object.
    assert_eq!(exchange(&mut b, "52 4F 01 7D 3D"), ack(b"RO"));
    assert_eq!(exchange(&mut b, "52 4F 01 7D 3D"), ack(b"RO"));
    assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    // RS to every function they use "to clear flags" before an RE; F1 fast is 52 53 00 00 CD 9F.
    for rs in ["52 53 00 00 CD 9F", "52 53 01 00 FC AC", "52 53 07 00 5A 06"] {
        assert_eq!(exchange(&mut b, rs), ack(b"RS"));
    }
    // Remote speed of F1 = 100 %, remote position of A1 = 500 counts as INT32, RE F1 direction 9.
    assert_eq!(exchange(&mut b, "52 54 04 00 11 30 64 00 6A 06"), ack(b"RT"));
    assert_eq!(exchange(&mut b, "52 54 06 00 21 30 F4 01 00 00 CF 36"), ack(b"RT"));
    assert_eq!(exchange(&mut b, "52 45 00 09 FF 00 27"), ack(b"RE"));
    for _ in 0..60 {
        b.wait(100);
        assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    }
    // RG 0x0011 (A1's position) and 0x0171 (A1's status 1), as they poll them.
    let reply = |bytes: Vec<u8>| -> (Status, Vec<u8>) {
        let mut dec = ReplyDecoder::new();
        dec.expect(Command::Get, ReplyShape::WithData);
        match dec.decode(&bytes) {
            (n, Some(Ok(r))) if n == bytes.len() => (r.status, r.data.unwrap_or_default().to_vec()),
            other => panic!("{bytes:02X?}: {other:?}"),
        }
    };
    let (status, data) = reply(exchange(&mut b, "52 47 11 00 2C 30"));
    assert_eq!((status, data), (Status::Ack, 500i32.to_le_bytes().to_vec()));
    let (status, data) = reply(exchange(&mut b, "52 47 71 01 27 2B"));
    assert_eq!(status, Status::Ack);
    assert_eq!(data[0] & status1::MOTION, 0, "at rest");
    // Drive 2 has an error; the drivers expect the next motion to clear it. RS everything, then RE F8
    // (function index 7) direction 2: both columns out.
    b.unit.inject_error(ErrorCode::from_bit(16));
    for rs in ["52 53 00 00 CD 9F", "52 53 01 00 FC AC", "52 53 07 00 5A 06"] {
        assert_eq!(exchange(&mut b, rs), ack(b"RS"));
    }
    assert_eq!(exchange(&mut b, "52 45 07 02 FF 6A 7E"), ack(b"RE"));
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "the drive error bit was reset by the next motion");
    b.wait(50);
    assert!(b.unit.is_moving(a(1)) && b.unit.is_moving(a(2)), "F8 drives both columns");
    assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    // RS of F8 fast stops both.
    assert_eq!(exchange(&mut b, "52 53 07 00 5A 06"), ack(b"RS"));
    assert!(!b.unit.any_moving());
    // Column 1 to its In end (RE F1 direction 1): a TLT reads a few counts below zero there. The manual's
    // INT32 is -3; drivers that decode 16 bits read 65533.
    assert_eq!(exchange(&mut b, "52 45 00 01 FF A9 AE"), ack(b"RE"));
    for _ in 0..80 {
        b.wait(100);
        assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    }
    let (_, data) = reply(exchange(&mut b, "52 47 11 00 2C 30"));
    assert_eq!(data, (-3i32).to_le_bytes());
    assert_eq!(u16::from_le_bytes([data[0], data[1]]), 65533);
    assert_eq!(exchange(&mut b, "52 53 00 00 CD 9F"), ack(b"RS"));
    assert_eq!(exchange(&mut b, "52 41 38 30"), ack(b"RA"));
    assert_eq!(b.unit.mode(), RemoteMode::Off);
}
