//! `motionlink probe powercube`.

use motionlink_link::describe::Describe;
use motionlink_link::probe::{find_baud, BaudChoice, PortKind};
use motionlink_link::RealClock;
use motionlink_powercube::args::{Baud, CanBitRate, PollInterval, ReplyTimeout};
use motionlink_powercube::describe::Describer;
use motionlink_powercube::model::Address;
use motionlink_powercube::probe::{baud_choice, probe, save_profile, PowercubeModule};
use motionlink_powercube::sim::Variant;

use super::{finish, setup, Options};
use crate::common::{self, CliError};
use crate::powercube::{open, Action};
use crate::tap::{LinkArgs, Tap};

/// `motionlink probe powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device or tcp://HOST:PORT (RS232), socketcan://IF or slcan://PATH (CAN), or sim (an
    /// emulated module at address 1). Default: --device, else MOTIONLINK_PORT.
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// RS232 baud rate: 1200, 2400, 4800, 9600 (the modules' default), 19200, 38400, 57600, 115200, or auto
    /// to try each (9600 first; not over tcp://, sim or CAN).
    #[arg(long, default_value = "9600", value_name = "BAUD|auto", value_parser = baud_choice)]
    pub baud: BaudChoice,
    /// CAN bit rate of an SLCAN adapter (10000 .. 1000000).
    #[arg(long, default_value = "1000000")]
    pub bitrate: CanBitRate,
    /// Acknowledge timeout in ms, 1 to 60000 (default: 200 on RS232, 50 on CAN).
    #[arg(long, value_name = "MS")]
    pub timeout_ms: Option<ReplyTimeout>,
    #[command(flatten)]
    pub sim_variants: crate::common::SimVariants<Variant>,
    #[command(flatten)]
    pub options: Options,
}

/// `motionlink probe powercube ...`
pub fn run(args: Args, json: bool) -> Result<(), CliError> {
    let port = args.link.resolve_port("powercube", args.port.as_deref())?;
    let (mut setup, url) = setup(&port, args.baud.first(), &args.options)?;
    crate::portlock::claim("powercube", &port)?;
    let clock = RealClock::shared();
    let describer = || Box::new(Describer::new()) as Box<dyn Describe + Send>;
    let can_interface = crate::tap::can_interface(&url);
    let tap = Tap::new("powercube", &port, &clock, &args.link, &can_interface, &describer, false)?;
    // The family command's own opening, at each rate tried; at a rate where no module answers the scan, the
    // next is tried.
    let (opened, baud_check) = find_baud(setup.kind, &args.baud, |baud| {
        let family = crate::powercube::Args {
            port: Some(port.clone()),
            link: args.link.clone(),
            module: Address::new(1).expect("1 is a module address"),
            bus: crate::powercube::BusArgs {
                baud: Baud::new(baud).map_err(|e| CliError::usage(e.to_string()))?,
                bitrate: args.bitrate,
                timeout_ms: args.timeout_ms,
                poll_ms: PollInterval::from_ms(10).map_err(|e| CliError::usage(e.to_string()))?,
                no_watchdog: true,
                sim_variants: args.sim_variants.clone(),
            },
            action: Action::Scan,
        };
        let (client, host) = open(&family, &port, &tap, &clock)?;
        if matches!(args.baud, BaudChoice::Auto(_)) && setup.kind == PortKind::Serial {
            let found = client.scan().map_err(|e| common::classified(&e))?;
            if found.is_empty() {
                let _ = client.close();
                return Err(CliError::Transport(
                    motionlink_link::error::TransportKind::Timeout,
                    "no module answered".into(),
                ));
            }
        }
        Ok((client, host))
    });
    let ((client, host), baud) = opened.map_err(|e| {
        tap.flush();
        super::not_found(e, &args.baud, &baud_check)
    })?;
    setup.baud = (setup.kind == PortKind::Serial).then_some(baud);
    setup.baud_check = Some(baud_check);
    let ended = (probe(&client, &setup), client.close());
    drop(host);
    tap.flush();
    finish(ended, &args.options, save_profile, json, module_line)
}

fn module_line(m: &PowercubeModule) -> String {
    format!(
        "module {}: {} version {}, serial {}; state: {}",
        m.address,
        m.kind.name(),
        m.version,
        m.serial,
        if m.state.is_empty() { "none".into() } else { m.state.join(" ") }
    )
}
