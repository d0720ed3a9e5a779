//! The PowerCube part of `motionlink demo`: the manual's chapter 8 (CAN) and 9 (RS232) examples against the
//! emulator, each telegram explained by the library's describer.

use std::io::{IsTerminal, Write};

use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::clock::{Clock, ManualClock, Timestamp};
use motionlink_link::describe::Describe;
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::transcript::{FrameTranscript, TapCanLink, TapLink, Transcript};
use motionlink_powercube::client::{Client, Config, Module, PortLink};
use motionlink_powercube::describe::Describer;
use motionlink_powercube::model::{AckKind, Address, Motion, Param, Position, Value};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::{Emulator, Error};

use crate::common::{self, CliError};
use crate::demo::{DemoOut, DemoTelegram};

/// One example of the demo: a name and what the client does.
type Step = (&'static str, fn(&Module<'_>) -> Result<(), Error>);

/// One telegram of the demo: `shown` (a CAN frame or RS232 bytes in hex) in a column `width` wide, then its
/// meaning.
fn show(
    out: &mut DemoOut<'_>,
    direction: Direction,
    at: Timestamp,
    (shown, width): (&str, usize),
    meaning: &str,
) -> Result<(), CliError> {
    let arrow = direction.arrow();
    let text = format!("    {arrow} {shown:<width$} {meaning}");
    let time_s = Some(at.since_origin().as_secs_f64());
    out.telegram(&text, &DemoTelegram { time_s, direction: arrow, bytes: shown, meaning })
}

fn ramp(m: &Module<'_>, ack: AckKind) -> Result<(), Error> {
    m.motion(Motion::FRamp { pos: Position::native(0.75) }, ack).map(|_| ())
}

/// Runs `steps` on module 17 of `bus`, each named, then the telegrams it sent and received as `shown` prints
/// them (with the library's describer); closes `bus`.
fn run_steps(
    out: &mut DemoOut<'_>,
    bus: Client,
    steps: &[Step],
    mut shown: impl FnMut(&mut DemoOut<'_>, &mut Describer) -> Result<(), CliError>,
) -> Result<(), CliError> {
    let m = bus.module(Address::new(17).map_err(|e| failed(e.into()))?);
    let mut describer = Describer::new();
    for (name, step) in steps {
        step(&m).map_err(failed)?;
        out.step(name)?;
        shown(out, &mut describer)?;
    }
    bus.close().map(|_| ()).map_err(failed)
}

fn failed(e: Error) -> CliError {
    common::classified(&e)
}

/// The manual's chapter 8 (CAN) and 9 (RS232) examples against the emulator (module 17).
pub fn demo(out: &mut DemoOut<'_>) -> Result<(), CliError> {
    let color = std::io::stdout().is_terminal() && !out.is_json();
    let title = |s: &str| if color { format!("\x1b[1m{s}\x1b[0m") } else { s.to_string() };
    let config = SimConfig::with_addresses(&[17]).map_err(CliError::usage)?;
    writeln!(
        out,
        "{}",
        title("== Schunk / Amtec PowerCube: the manual's chapter 8, CAN examples (module 17, emulated at 1 Mbit/s) ==")
    )?;
    {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let can = CanBus::with_emulator(Emulator::new_can(&config), clock.shared(), CanBusConfig::paced(1_000_000));
        let transcript = FrameTranscript::new();
        let link = TapCanLink::new(can.connect(), clock.shared(), transcript.clone());
        let bus = Client::with_link(PortLink::Can(Box::new(link)), clock.shared(), Config::can()).map_err(failed)?;
        let steps: [Step; 9] = [
            ("Home", |m| m.home()),
            ("Reset", |m| m.reset()),
            ("Set ramp motion acceleration", |m| m.set(Param::TargetAcc, Value::F32(0.5))),
            ("Set ramp motion velocity", |m| m.set(Param::TargetVel, Value::F32(0.08))),
            ("Ramp motion command", |m| ramp(m, AckKind::Simple)),
            ("Retrieve module state", |m| m.state().map(|_| ())),
            ("Retrieve module position", |m| m.position().map(|_| ())),
            ("Ramp motion command with extended acknowledge", |m| ramp(m, AckKind::Extended)),
            ("Halt", |m| m.halt()),
        ];
        let mut notes = Vec::new();
        run_steps(out, bus, &steps, |out, describer| {
            for r in transcript.take() {
                describer.describe(Chunk::Frame(&r.frame), r.direction, Some(r.at), &mut notes);
                let frame = r.frame.to_string();
                for a in notes.drain(..) {
                    show(out, r.direction, r.at, (&frame, 24), &a.meaning)?;
                }
            }
            Ok(())
        })?;
    }
    writeln!(out)?;
    writeln!(
        out,
        "{}",
        title(
            "== Schunk / Amtec PowerCube: the manual's chapter 9, RS232 examples (module 17, emulated at 9600 baud) =="
        )
    )?;
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(Emulator::new(&config), clock.shared(), PipeConfig::paced(9_600));
    let transcript = Transcript::new();
    let link = TapLink::new(host.connect().0, clock.shared(), transcript.clone());
    let bus = Client::with_link(PortLink::Rs232(Box::new(link)), clock.shared(), Config::rs232()).map_err(failed)?;
    let steps: [Step; 6] = [
        ("Home", |m| m.home()),
        ("Reset", |m| m.reset()),
        ("Set ramp motion acceleration 0.5", |m| m.set(Param::TargetAcc, Value::F32(0.5))),
        ("Set ramp motion velocity 0.08", |m| m.set(Param::TargetVel, Value::F32(0.08))),
        ("Ramp motion command to 0.75", |m| ramp(m, AckKind::Simple)),
        ("Halt (0x02 escaped as 10 82)", |m| m.halt()),
    ];
    let mut notes = Vec::new();
    run_steps(out, bus, &steps, |out, describer| {
        for r in transcript.take() {
            describer.describe(Chunk::Bytes(&r.bytes), r.direction, Some(r.at), &mut notes);
            let meaning = notes.drain(..).map(|a| a.meaning).collect::<Vec<String>>().join("; ");
            show(out, r.direction, r.at, (&motionlink_link::hex::hex(&r.bytes), 33), &meaning)?;
        }
        Ok(())
    })
}
