//! Opening the port of `motionlink compax`.

use super::*;

/// Opens the port, its link watched by `tap` (the bus arguments were checked by their types).
pub(crate) fn open(args: &Args, tap: &Tap, configure: impl FnOnce(&mut Config)) -> Result<Client, CliError> {
    let options = drive_options(args);
    let url: PortUrl = args.resolved_port.parse()?;
    let clock: SharedClock = RealClock::shared();
    // Installed before the port opens: a signal from here on stops what the command starts.
    let token = common::interrupt_token();
    let link = link(&options, url, &[options.drive.get()], tap, &clock)?;
    let mut cfg = options.config();
    configure(&mut cfg);
    let bus = Client::with_link(link, clock, cfg).map_err(|e| common::classified(&e))?;
    bus.set_cancel(token);
    Ok(bus)
}

/// The link `options` name on `url`, watched by `tap`: an emulator in this process of the drives
/// `sim_drives` (in the options' mode, baud rate and firmware variants), paced to the baud rate, or the
/// serial line (gateway) in the options' baud rate and parity. The console opens its bus by it too.
pub(crate) fn link(
    options: &DriveOptions,
    url: PortUrl,
    sim_drives: &[u8],
    tap: &Tap,
    clock: &SharedClock,
) -> Result<Box<dyn Link>, CliError> {
    if options.check_port(matches!(url, PortUrl::Sim)).is_err() {
        return Err(CliError::usage(
            "--sim-variant is for --port sim (a served emulator takes `sim compax --variant`)",
        ));
    }
    let baud = options.baud.bits_per_s();
    let link: Box<dyn Link> = match url {
        PortUrl::Sim => {
            let mut config = options.emulated();
            config.drives = motionlink_compax::sim::SimConfig::bus(sim_drives, options.mode.to_p196(), baud).drives;
            let bus = Emulator::new(config).map_err(CliError::usage)?;
            let host = EmulatorHost::new(bus, clock.clone(), PipeConfig::paced(baud));
            Box::new(host.connect().0)
        }
        other => motionlink_compax::client::open_line(&other, &options.config()).map_err(|e| common::classified(&e))?,
    };
    Ok(tap.link(link, clock))
}

/// The drive's options from the command line (the same options a device table gives the gateway; a move's
/// tolerance and poll interval are given to the session by the action: `configure` of [`open`](fn@open)).
pub(crate) fn drive_options(args: &Args) -> DriveOptions {
    DriveOptions { drive: args.drive, ..line_options(&args.line) }
}

/// The line's options from the command line (of `motionlink compax` and `motionlink console compax`), for
/// drive 1.
pub(crate) fn line_options(line: &LineArgs) -> DriveOptions {
    DriveOptions {
        mode: line.mode,
        baud: line.baud,
        timeout_ms: line.timeout_ms,
        short: line.short,
        poll_ms: None,
        tolerance: None,
        sim_variants: line.sim_variants.list.clone(),
        ..DriveOptions::default()
    }
}
