//! `motionlink probe scu`.

use std::sync::Arc;

use motionlink_link::describe::Describe;
use motionlink_link::probe::{find_baud, PortKind};
use motionlink_link::RealClock;
use motionlink_scu::args::{Baud, Checked};
use motionlink_scu::describe::Describer;
use motionlink_scu::model::SpeedMode;
use motionlink_scu::probe::{baud_choice, probe, save_profile, ScuDevice};
use motionlink_scu::{Client, Config};

use super::{finish, setup, Options};
use crate::common::{self, CliError};
use crate::scu::{connector, InProcess};
use crate::tap::{LinkArgs, Tap};

/// `motionlink probe scu` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device (/dev/ttyUSB0, COM3), tcp://HOST:PORT (a serial gateway or `motionlink sim
    /// scu`), or sim. Default: --device, else MOTIONLINK_PORT.
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// Baud rate of a serial port: 38400 (standard units), 19200 or 9600 (customised ones), or auto to try
    /// each in that order (not over tcp:// or sim, where the gateway or emulator sets the rate).
    #[arg(long, default_value = "38400", value_name = "BAUD|auto", value_parser = baud_choice)]
    pub baud: motionlink_link::probe::BaudChoice,
    #[command(flatten)]
    pub sim_variants: crate::common::SimVariants<motionlink_scu::Variant>,
    /// Before opening the port, hold the unit's RxD at "space" for 150 ms (a break), as `motionlink scu --wake`:
    /// a battery unit in low-power mode answers nothing until woken so.
    #[arg(long)]
    pub wake: bool,
    #[command(flatten)]
    pub options: Options,
}

/// `motionlink probe scu ...`
pub fn run(args: Args, json: bool) -> Result<(), CliError> {
    let port = args.link.resolve_port("scu", args.port.as_deref())?;
    let (mut setup, url) = setup(&port, args.baud.first(), &args.options)?;
    match setup.kind {
        PortKind::Can => return Err(CliError::usage(format!("{port}: the SCU speaks RS232, not CAN"))),
        PortKind::Sim => {}
        _ if !args.sim_variants.list.is_empty() => return Err(CliError::usage("--sim-variant is only for --port sim")),
        _ => {}
    }
    crate::portlock::claim("scu", &port)?;
    // The probe moves nothing, but it opens remote mode: a signal ends it with the session's RA (killed
    // instead, the unit's watchdog would end remote mode and record error bit 22).
    let interrupt = common::interrupt_token();
    let clock = RealClock::shared();
    let describer = || Box::new(Describer::new()) as Box<dyn Describe + Send>;
    let tap = Tap::new("scu", &port, &clock, &args.link, "can0", &describer, false)?;
    let (opened, baud_check) = find_baud(setup.kind, &args.baud, |baud| {
        // The family command's own link: at `--port sim` a unit with the variants asked for, else a serial line.
        let baud = Baud::checked(i64::from(baud)).map_err(|e| CliError::usage(e.to_string()))?;
        let variants = &args.sim_variants.list;
        let unit = InProcess { functions: &[], preset: None, file: None, speed_mode: SpeedMode::Percent, variants };
        let connector = connector(&url, &unit, baud, &tap, &clock)?;
        let config =
            Config { wake_break: args.wake.then_some(motionlink_scu::config::WAKE_BREAK), ..Config::default() };
        Client::with_connector(connector, Arc::clone(&clock), config).map_err(|e| common::classified(&e))
    });
    let (client, baud) = opened.map_err(|e| {
        tap.flush();
        super::not_found(e, &args.baud, &baud_check)
    })?;
    setup.baud = (setup.kind == PortKind::Serial).then_some(baud);
    setup.baud_check = Some(baud_check);
    client.set_cancel(interrupt.clone());
    if interrupt.is_cancelled() {
        let closed = client.close();
        tap.flush();
        closed.map_err(|e| common::classified(&e))?;
        return Err(CliError::Interrupted("interrupted before the probe started".into()));
    }
    let ended = (probe(&client, &setup), client.close());
    tap.flush();
    finish(ended, &args.options, save_profile, json, unit_line)
}

fn unit_line(d: &ScuDevice) -> String {
    let actuators: Vec<String> = d.connected_actuators.iter().map(|a| format!("A{a}")).collect();
    format!(
        "unit: firmware {:?}, configuration {:?} (edition: {}: {}); connected: {}",
        d.firmware,
        d.configuration,
        d.edition,
        d.edition_detail,
        if actuators.is_empty() { "none".into() } else { actuators.join(" ") }
    )
}
