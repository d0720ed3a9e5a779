//! Opening the port of `motionlink scu`: the session's settings and the link from the command line's options.

use super::*;

/// The unit's options from the command line (the same options a device table gives the gateway).
pub(super) fn unit_options(args: &UnitArgs) -> UnitOptions {
    UnitOptions {
        baud: args.baud,
        safety: args.safety,
        timeout_ms: args.timeout_ms,
        functions: args.functions.clone(),
        stroke: args.stroke.clone(),
        tolerance: args.tolerance,
        poll_ms: args.poll_ms,
        speed_mode: args.speed_mode,
        sim_preset: args.sim_preset.clone(),
        sim_variants: args.sim_variants.list.clone(),
        wake: args.wake,
    }
}

/// The session's settings from the command line, checked before anything is sent (the library's rule:
/// [`UnitOptions::config`]; a message names the option as the command line spells it).
pub(crate) fn client_config(args: &UnitArgs) -> Result<Config, CliError> {
    unit_options(args).config().map_err(|e| match e.key {
        Some(key) => CliError::usage(format!("--{} {}", key.replace('_', "-"), e.message)),
        None => CliError::usage(e.message),
    })
}

/// Opens the session on `port`, its link watched by `tap`.
pub(super) fn connect(
    args: &UnitArgs,
    port: &str,
    tap: &Tap,
    clock: &SharedClock,
    config: Config,
) -> Result<Client, CliError> {
    let port: PortUrl = port.parse()?;
    let connector = connector(&port, &in_process(args, &port)?, args.baud, tap, clock)?;
    Client::with_connector(connector, Arc::clone(clock), config).map_err(|e| common::classified(&e))
}

/// The unit emulated with `--port sim`: the one the options name (its functions, its speed mode, the
/// firmware variants asked for); the emulator's options on another port are refused.
pub(crate) fn in_process<'a>(args: &'a UnitArgs, port: &PortUrl) -> Result<InProcess<'a>, CliError> {
    let sim_options = args.sim_config.is_some() || args.sim_preset.is_some() || !args.sim_variants.list.is_empty();
    if sim_options && !matches!(port, PortUrl::Sim) && !port.is_can() {
        return Err(CliError::usage("--sim-config, --sim-preset and --sim-variant are only for --port sim"));
    }
    Ok(InProcess {
        functions: &args.functions,
        preset: args.sim_preset.as_deref(),
        file: args.sim_config.as_ref(),
        speed_mode: args.speed_mode,
        variants: &args.sim_variants.list,
    })
}

/// The links of an SCU on `port` (the console's and the command's): a serial line at `baud`, or with
/// `sim` the unit `unit` describes emulated in this process on a line paced to `baud`; watched by `tap`.
pub(crate) fn connector(
    port: &PortUrl,
    unit: &InProcess<'_>,
    baud: Baud,
    tap: &Tap,
    clock: &SharedClock,
) -> Result<Connector, CliError> {
    let (tap, clock) = (tap.clone(), Arc::clone(clock));
    Ok(match port {
        PortUrl::Sim => {
            let sim = Emulator::new(in_process_config(unit)?).map_err(|e| CliError::usage(e.to_string()))?;
            let host = EmulatorHost::new(sim, Arc::clone(&clock), PipeConfig::paced(baud.get()));
            Box::new(move || Ok(tap.link(Box::new(host.connect().0), &clock)))
        }
        p => {
            let mut line = motionlink_scu::port_connector(p, &Config { baud, ..Config::default() })
                .map_err(|e| common::classified(&e))?;
            Box::new(move || Ok(tap.link(line()?, &clock)))
        }
    })
}
