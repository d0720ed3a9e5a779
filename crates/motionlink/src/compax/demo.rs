//! The COMPAX part of `motionlink demo`.

use std::io::Write;
use std::time::Duration;

use motionlink_compax::client::{Config, MoveOptions};
use motionlink_compax::describe::Describer;
use motionlink_compax::model::{Position, RampMs, S16Flag, S17Flag, SpeedPercent};
use motionlink_compax::sim::SimConfig;
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{Client, Emulator, Error};
use motionlink_link::chunk::Chunk;
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::describe::Describe;
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript};

use super::decode::line;
use crate::common::{self, CliError};
use crate::demo::{DemoOut, DemoTelegram};

fn fail(e: Error) -> CliError {
    common::classified(&e)
}

/// The COMPAX part of `motionlink demo`: the manual's chapter 4.5 example and a move.
pub fn demo(out: &mut DemoOut<'_>) -> Result<(), CliError> {
    writeln!(out, "== Parker COMPAX: the manual's chapter 4.5, S1 of drives 1 and 5 (P194 = 1 and 5, P195 = 9600) ==")?;
    for (p196, title) in
        [(8, "4.5.1 BASIC program with BCC (P196 = 8)"), (0, "4.5.2 BASIC program without BCC (P196 = 0)")]
    {
        writeln!(out, "-- {title}")?;
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let (bus, transcript) = demo_bus(&clock, p196)?;
        let mut describer = Describer::new(Mode::from_p196(p196).map_err(CliError::usage)?);
        for a in [1u8, 5] {
            let addr = Address::drive(a).map_err(CliError::usage)?;
            let p = bus.read_position(addr).map_err(fail)?;
            print_transcript(out, &transcript, &mut describer)?;
            writeln!(out, "   drive {a}: S1 = {p}  (at {})", clock.now())?;
        }
        bus.close().map_err(fail)?;
    }
    writeln!(out, "-- a move: drive 5, SPEED 50, ACCEL 200, POSA 25 with the position-reached message")?;
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (bus, transcript) = demo_bus(&clock, 0)?;
    let mut describer = Describer::new(Mode::default());
    let five = Address::drive(5).map_err(CliError::usage)?;
    let usage = |e: motionlink_compax::model::ModelError| CliError::usage(e);
    bus.set_speed(five, SpeedPercent::new(50.0).map_err(usage)?, false).map_err(fail)?;
    bus.set_accel(five, RampMs::new(200).map_err(usage)?, false).map_err(fail)?;
    let target = Position::new(25.0).map_err(usage)?;
    bus.move_absolute(five, target, MoveOptions { binary: false, message: true }).map_err(fail)?;
    print_transcript(out, &transcript, &mut describer)?;
    let t0 = clock.now();
    bus.wait_reached(&[five], Some(Duration::from_secs(10)), &mut |_, _| {}).map_err(fail)?;
    print_transcript(out, &transcript, &mut describer)?;
    let p = bus.read_position(five).map_err(fail)?;
    let s16 = bus.read_s16(five).map_err(fail)?;
    print_transcript(out, &transcript, &mut describer)?;
    writeln!(
        out,
        "   drive 5 reached {p} after {:.3} s of device time; S16 = {} (position reached: {})",
        (clock.now() - t0).as_secs_f64(),
        s16.pattern(),
        s16.contains(S16Flag::PositionReached)
    )?;
    let s17 = bus.read_s17(five).map_err(fail)?;
    writeln!(out, "   S17 = {} (command active: {})", s17.pattern(), s17.contains(S17Flag::CommandActive))?;
    bus.close().map_err(fail)?;
    Ok(())
}

fn demo_bus(clock: &ManualClock, p196: u32) -> Result<(Client, Transcript), CliError> {
    let sim = Emulator::new(SimConfig::bus(&[1, 5], p196, 9600)).map_err(CliError::usage)?;
    let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(9600));
    let transcript = Transcript::new();
    let link = TapLink::new(host.connect().0, clock.shared(), transcript.clone());
    let mode = Mode::from_p196(p196).map_err(CliError::usage)?;
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(mode, 9600)).map_err(fail)?;
    Ok((bus, transcript))
}

/// Prints what went over the line since the last call, each telegram explained by the library.
fn print_transcript(out: &mut DemoOut<'_>, transcript: &Transcript, describer: &mut Describer) -> Result<(), CliError> {
    for r in transcript.take() {
        let mut found = Vec::new();
        describer.describe(Chunk::Bytes(&r.bytes), r.direction, None, &mut found);
        for a in &found {
            let direction = if a.bad { "!!" } else { a.direction.arrow() };
            let text = format!("   {} {}", a.direction.arrow(), line(a));
            let time_s = Some(r.at.since_origin().as_secs_f64());
            let bytes = motionlink_link::hex::hex(&a.bytes);
            out.telegram(&text, &DemoTelegram { time_s, direction, bytes: &bytes, meaning: &a.meaning })?;
        }
    }
    Ok(())
}
