//! The SCU part of `motionlink demo`.

use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

use motionlink_link::clock::Clock;
use motionlink_link::link::{Connector, Link};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript};
use motionlink_link::{ManualClock, SharedClock};
use motionlink_scu::describe::{describe_request, fold_transcript, TranscriptLine};
use motionlink_scu::model::{Actuator, DataIndex, MotionDirection, MotionFunction, PositionCounts, StopMode};
use motionlink_scu::value::Value;
use motionlink_scu::wire::{request_to_vec, Request};
use motionlink_scu::{Client, Config, Emulator, SimConfig};

use crate::common::{self, CliError};
use crate::demo::{DemoOut, DemoTelegram};

// ---------------------------------------------------------------------------------------------------------
// Demo

/// Prints a session transcript as the library folds it.
fn print_transcript(out: &mut DemoOut<'_>, transcript: &Transcript) -> Result<(), CliError> {
    for line in fold_transcript(&transcript.take()) {
        match line {
            TranscriptLine::Telegram(a) => {
                let t = a.at.unwrap_or_default().since_origin().as_secs_f64();
                let direction = if a.bad { "!!" } else { a.direction.arrow() };
                let bytes = motionlink_link::hex::hex(&a.bytes);
                let text = format!("  {t:>8.3}  {direction} {bytes:<38} {}", a.meaning);
                out.telegram(&text, &DemoTelegram { time_s: Some(t), direction, bytes: &bytes, meaning: &a.meaning })?;
            }
            TranscriptLine::Folded(text) => writeln!(out, "  {:>8}     {text}", "")?,
        }
    }
    Ok(())
}

/// The SCU part of `motionlink demo`: the manual's chapter 5 routine against the emulator.
pub fn demo(out: &mut DemoOut<'_>) -> Result<(), CliError> {
    writeln!(out, "== Ewellix / Schaeffler SCU: the manual's chapter 5 routine (SCP11, actuator 1) ==")?;
    writeln!(out, "The manual's example telegrams, as motionlink-scu encodes them (CRC-16/XMODEM, low byte first):")?;
    let examples: [(&str, Request<'_>); 7] = [
        ("RO 00", Request::Open { safety_id: 0 }),
        ("RC 01 00 -1", Request::Cyclic { object: 0xFF, write: &[] }),
        ("RT 04 00 11 30 01 00", Request::Transfer { index: 0x3011, data: &[0x01, 0x00] }),
        ("RE 00 09 -1", Request::Execute { function: 0, params: [9, 0xFF] }),
        ("RG 71 01", Request::Get { index: 0x0171 }),
        ("RG 11 00", Request::Get { index: 0x0011 }),
        ("RA", Request::Abort),
    ];
    for (manual, r) in examples {
        let bytes = motionlink_link::hex::hex(&request_to_vec(&r).map_err(|e| CliError::usage(e.to_string()))?);
        let meaning = describe_request(&r);
        out.set_step(Some(manual));
        let text = format!("  {manual:<22} {bytes:<38} {meaning}");
        out.telegram(&text, &DemoTelegram { time_s: None, direction: "->", bytes: &bytes, meaning: &meaning })?;
    }
    out.set_step(None);
    writeln!(out, "  (The manual captions its RT example \"100h\"; its bytes 01 00 are little-endian 1. The bytes are the truth.)")?;
    writeln!(out)?;
    writeln!(
        out,
        "The routine against the built-in emulator (2 actuators, stroke 0..865 counts, 110 counts/s at 100 %),"
    )?;
    writeln!(out, "on a virtual clock: times are device seconds. RC keepalives run every 200 ms throughout.")?;
    writeln!(out, "  {:>8}  dir telegram{:<30} meaning", "t [s]", "")?;

    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let shared: SharedClock = clock.shared();
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::default()).map_err(|e| CliError::usage(e.to_string()))?,
        Arc::clone(&shared),
        PipeConfig::paced(38_400),
    );
    let transcript = Transcript::new();
    let (tap_transcript, tap_clock, tap_host) = (transcript.clone(), Arc::clone(&shared), host.clone());
    let connector: Connector = Box::new(move || {
        Ok(Box::new(TapLink::new(tap_host.connect().0, Arc::clone(&tap_clock), tap_transcript.clone()))
            as Box<dyn Link>)
    });
    let client = Client::with_connector(connector, Arc::clone(&shared), Config::default())
        .map_err(|e| common::classified(&e))?;
    let a1 = Actuator::new(1).ok_or_else(|| CliError::usage("actuator 1"))?;
    let f1 = MotionFunction::new(1).ok_or_else(|| CliError::usage("F1"))?;
    let target = PositionCounts(400);
    let steps = || -> Result<(PositionCounts, Duration), motionlink_scu::Error> {
        client.set(DataIndex(0x3011), &Value::RemoteSpeed(80))?;
        client.set(a1.remote_position_index(), &Value::RemotePosition(target.get()))?;
        let started = shared.now();
        client.start_motion(f1, MotionDirection::RemotePosition)?;
        let pause = shared.signal();
        loop {
            let until = shared.now() + Duration::from_millis(250);
            while pause.wait_until(Some(until)) == motionlink_link::clock::Wake::Raised {}
            if !client.status1(a1)?.moving() {
                break;
            }
        }
        let took = shared.now() - started;
        let position = client.position(a1)?;
        client.stop_motion(f1, StopMode::Soft)?;
        Ok((position, took))
    };
    let result = steps();
    let keepalives = client.stats().keepalives;
    let closed = client.close();
    print_transcript(out, &transcript)?;
    let (position, took) = result.map_err(|e| common::classified(&e))?;
    closed.map_err(|e| common::classified(&e))?;
    writeln!(out)?;
    writeln!(
        out,
        "Result: actuator 1 reached {position} (target {}) in {:.1} s at 80 %; {keepalives} RC keepalives kept the 500 ms watchdog fed; RS and RA closed the session.",
        target.get(),
        took.as_secs_f64()
    )?;
    let idle_error = host.with_device(|u| u.last_error());
    writeln!(out, "The unit's last error code: {idle_error}")?;
    writeln!(out)?;
    Ok(())
}
