//! `motionlink probe compax`.

use motionlink_compax::describe::Describer;
use motionlink_compax::model::args::{BaudRate, ReplyTimeout, WholeArg};
use motionlink_compax::probe::{baud_choice, probe, save_profile, CompaxDrive, DriveList};
use motionlink_compax::sim::Variant;
use motionlink_compax::wire::{Address, Mode};
use motionlink_link::describe::Describe;
use motionlink_link::probe::{find_baud, BaudChoice, PortKind};
use motionlink_link::{RealClock, SharedClock};

use super::{finish, setup, Options};
use crate::common::CliError;
use crate::compax::{open, Action};
use crate::tap::{LinkArgs, Tap};

/// `motionlink probe compax` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a device path (/dev/ttyUSB0, COM3), tcp://HOST:PORT, or sim (an emulated drive at address
    /// 1). Default: --device, else MOTIONLINK_PORT.
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// The addresses to look for drives at: a list (1,3), ranges (1-8) or both. Each address without a drive
    /// costs one reply timeout.
    #[arg(long, default_value = "1-31", value_name = "LIST")]
    pub drives: DriveList,
    /// The drives' operating mode P196 (0..=127) the session frames telegrams with: BCC 8, reply end CR only
    /// 32, address prefix 64, parity 2 / 6. A drive in another mode gives no reply this session can read.
    #[arg(long, default_value = "0")]
    pub mode: Mode,
    /// The drives' baud rate P195 (150 .. 115200), or auto to try each (9600 first; not over tcp:// or sim).
    #[arg(long, default_value = "9600", value_name = "BAUD|auto", value_parser = baud_choice)]
    pub baud: BaudChoice,
    /// Time a drive may take to start answering, in ms (1..=60000, on top of the wire time).
    #[arg(long, default_value = "200")]
    pub timeout_ms: ReplyTimeout,
    #[command(flatten)]
    pub sim_variants: crate::common::SimVariants<Variant>,
    #[command(flatten)]
    pub options: Options,
}

/// `motionlink probe compax ...`
pub fn run(args: Args, json: bool) -> Result<(), CliError> {
    let drives: Vec<Address> = args.drives.0.clone();
    let port = args.link.resolve_port("compax", args.port.as_deref())?;
    let (mut setup, _) = setup(&port, args.baud.first(), &args.options)?;
    if setup.kind == PortKind::Can {
        return Err(CliError::usage(format!("{port}: COMPAX drives speak RS485 / RS232, not CAN")));
    }
    let mode = args.mode;
    crate::portlock::claim("compax", &port)?;
    let clock: SharedClock = RealClock::shared();
    let describer = move || Box::new(Describer::new(mode)) as Box<dyn Describe + Send>;
    let tap = Tap::new("compax", &port, &clock, &args.link, "can0", &describer, false)?;
    // The family command's own opening, at each rate tried; at a rate where no drive answers, the next is
    // tried.
    let (opened, baud_check) = find_baud(setup.kind, &args.baud, |baud| {
        let family = crate::compax::Args {
            port: Some(port.clone()),
            link: args.link.clone(),
            drive: drives[0],
            line: crate::compax::LineArgs {
                mode: args.mode,
                baud: BaudRate::from_whole(i64::from(baud)).map_err(|e| CliError::usage(format!("--baud: {e}")))?,
                timeout_ms: args.timeout_ms,
                short: false,
                sim_variants: args.sim_variants.clone(),
            },
            resolved_port: port.clone(),
            action: Action::Scan,
        };
        let bus = open(&family, &tap, |_| {})?;
        if matches!(args.baud, BaudChoice::Auto(_)) && setup.kind == PortKind::Serial {
            let any = drives.iter().any(|a| bus.scan(a.get()..=a.get()).map(|f| !f.is_empty()).unwrap_or(false));
            if !any {
                let _ = bus.close();
                let e = motionlink_link::error::TransportKind::Timeout;
                return Err(CliError::Transport(e, "no drive answered".into()));
            }
        }
        Ok(bus)
    });
    let (bus, baud) = opened.map_err(|e| {
        tap.flush();
        super::not_found(e, &args.baud, &baud_check)
    })?;
    setup.baud = (setup.kind == PortKind::Serial).then_some(baud);
    setup.baud_check = Some(baud_check);
    let ended = (probe(&bus, &setup, &drives), bus.close());
    tap.flush();
    finish(ended, &args.options, save_profile, json, drive_line)
}

fn drive_line(d: &CompaxDrive) -> String {
    let shown = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_else(|| "-".into());
    format!(
        "drive {}: {}; P194 {}, P195 {}, P196 {} (framed as {})",
        d.address,
        d.identity,
        shown(d.p194_address),
        shown(d.p195_baud),
        shown(d.p196_mode),
        d.mode_in_use
    )
}
