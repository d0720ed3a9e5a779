//! Opening the port of `motionlink compax`.

use super::*;

/// Opens the port, its link watched by `tap` (the bus arguments were checked by their types).
pub(crate) fn open(args: &Args, tap: &Tap, configure: impl FnOnce(&mut BusConfig)) -> Result<Client, CliError> {
    let (mode, baud) = (args.mode, args.baud.bits_per_s());
    let url: PortUrl = args.resolved_port.parse()?;
    let clock: SharedClock = RealClock::shared();
    // Installed before the port opens: a signal from here on stops what the command starts.
    let token = common::interrupt_token();
    if !args.sim_variants.is_empty() && !matches!(url, PortUrl::Sim) {
        return Err(CliError::usage(
            "--sim-variant is for --port sim (a served emulator takes `sim compax --variant`)",
        ));
    }
    let link: Box<dyn Link> = match url {
        PortUrl::Sim => {
            let mut cfg = SimConfig::bus(&[args.drive.get()], mode.to_p196(), baud);
            cfg.variants = args.sim_variants.clone();
            let bus = Emulator::new(cfg).map_err(CliError::usage)?;
            let host = EmulatorHost::new(bus, clock.clone(), PipeConfig::paced(baud));
            tap.link(Box::new(host.connect().0), &clock)
        }
        other => {
            let mut settings = SerialSettings::new(baud);
            settings.parity = mode.parity;
            tap.link(other.open_byte_link(settings)?, &clock)
        }
    };
    let mut cfg = BusConfig::new(mode, baud);
    cfg.reply_timeout = args.timeout_ms.duration();
    cfg.style = if args.short { CommandStyle::Short } else { CommandStyle::Long };
    configure(&mut cfg);
    let bus = Client::new(link, clock, cfg).map_err(|e| common::classified(&e))?;
    bus.set_cancel(token);
    Ok(bus)
}
