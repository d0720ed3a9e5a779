//! Opening the port of `motionlink powercube`: the session's settings and the link from the command line's options.

use super::*;

/// Opens the session `args` ask for; the in-process emulator's host with it for `--port sim`.
pub(crate) fn open(
    args: &Args,
    port: &str,
    tap: &Tap,
    clock: &SharedClock,
) -> Result<(Client, Option<EmulatorHost<Emulator>>), CliError> {
    let url: PortUrl = port.parse()?;
    let clock = Arc::clone(clock);
    let options = module_options(args);
    if options.check_port(matches!(url, PortUrl::Sim)).is_err() {
        return Err(CliError::usage(
            "--sim-variant is for --port sim (a served emulator takes `sim powercube --variant`)",
        ));
    }
    let client = match PortLink::open(&url, args.bus.baud, args.bus.bitrate, &clock).map_err(failed)? {
        Some(PortLink::Rs232(link)) => {
            Client::with_link(PortLink::Rs232(tap.link(link, &clock)), clock, options.config(false))
        }
        Some(PortLink::Can(link)) => {
            Client::with_link(PortLink::Can(tap.can_link(link, &clock)), clock, options.config(true))
        }
        None => {
            // The emulated bus has the module the command names, in the firmware variants asked for.
            let bus = options.emulated().map_err(|e| CliError::usage(e.message))?;
            let host =
                EmulatorHost::new(Emulator::new(&bus), Arc::clone(&clock), PipeConfig::paced(args.bus.baud.get()));
            let link = tap.link(Box::new(host.connect().0), &clock);
            let client = Client::with_link(PortLink::Rs232(link), clock, options.config(false)).map_err(failed)?;
            return Ok((client, Some(host)));
        }
    };
    Ok((client.map_err(failed)?, None))
}

/// The module's options from the command line (the same options a device table gives the gateway).
pub(crate) fn module_options(args: &Args) -> ModuleOptions {
    ModuleOptions { module: args.module, ..bus_options(&args.bus) }
}

/// The bus's options from the command line (of `motionlink powercube` and `motionlink console powercube`),
/// for module 1.
pub(crate) fn bus_options(bus: &BusArgs) -> ModuleOptions {
    ModuleOptions {
        baud: bus.baud,
        bitrate: bus.bitrate,
        timeout_ms: bus.timeout_ms,
        poll_ms: bus.poll_ms,
        no_watchdog: bus.no_watchdog,
        sim_variants: bus.sim_variants.list.clone(),
        ..ModuleOptions::default()
    }
}
