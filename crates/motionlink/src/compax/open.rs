//! Checking the arguments of `motionlink compax` before anything is sent, and opening the port.

use super::*;

/// The arguments of `move`, checked before anything is sent.
pub(super) struct MovePlan {
    pub(super) request: MoveRequest,
    pub(super) tolerance: Position,
    pub(super) poll: Duration,
}

#[allow(clippy::too_many_arguments)]
pub(super) fn plan_move(
    abs: Option<f64>,
    rel: Option<f64>,
    speed: Option<f64>,
    accel: Option<u32>,
    binary: bool,
    timeout_s: f64,
    tolerance: f64,
    (min_pos, max_pos): (Option<f64>, Option<f64>),
    poll_ms: u64,
) -> Result<MovePlan, CliError> {
    let target = match (abs, rel) {
        (Some(a), None) => MoveTarget::Absolute(Position::new(a).map_err(|e| CliError::usage(format!("--abs: {e}")))?),
        (None, Some(r)) => MoveTarget::Relative(Position::new(r).map_err(|e| CliError::usage(format!("--rel: {e}")))?),
        _ => return Err(CliError::usage("give the target: POSITION (the same as --abs POSITION) or --rel DISTANCE")),
    };
    let speed = speed.map(SpeedPercent::new).transpose().map_err(|e| CliError::usage(format!("--speed: {e}")))?;
    if accel == Some(0) {
        // A ramp of no time asks for an infinite acceleration: the drive would clamp it to whatever it can.
        return Err(CliError::usage(
            "--accel 0: give the ramp time in ms, 1..=32767 (0 would ask for an infinite acceleration)",
        ));
    }
    let accel = accel.map(RampMs::new).transpose().map_err(|e| CliError::usage(format!("--accel: {e}")))?;
    let timeout = checked_s("--timeout-s", timeout_s)?;
    if !(tolerance.is_finite() && tolerance > 0.0 && tolerance <= 1e6) {
        return Err(CliError::usage(format!("--tolerance {tolerance}: give a distance above 0 (at most 1000000)")));
    }
    let tolerance = Position::new(tolerance).map_err(|e| CliError::usage(format!("--tolerance: {e}")))?;
    let limit = |name: &str, v: Option<f64>| {
        v.map(Position::new).transpose().map_err(|e| CliError::usage(format!("{name}: {e}")))
    };
    let limits = TravelLimits::new(limit("--min-pos", min_pos)?, limit("--max-pos", max_pos)?)
        .map_err(|e| CliError::usage(format!("--min-pos / --max-pos: {e}")))?;
    let poll = checked_ms("--poll-ms", poll_ms, 1, 10_000)?;
    let request = MoveRequest { target, speed, accel, binary, limits, timeout: Some(timeout) };
    Ok(MovePlan { request, tolerance, poll })
}

pub(super) fn parse_mode(p196: u32) -> Result<Mode, CliError> {
    Mode::from_p196(p196).map_err(|e| CliError::usage(format!("--mode: {e}")))
}

/// Checks the bus arguments: P196, the drive's address, the baud rate and the reply timeout.
pub(super) fn check_bus(args: &Args) -> Result<(Mode, Duration), CliError> {
    let mode = parse_mode(args.mode)?;
    Address::drive(args.drive).map_err(|e| CliError::usage(format!("--drive {}: {e}", args.drive)))?;
    if !BAUD_RATES.contains(&args.baud) {
        return Err(CliError::usage(format!("--baud {}: not a rate P195 accepts ({BAUD_RATES:?})", args.baud)));
    }
    let reply_timeout = checked_ms("--timeout-ms", args.timeout_ms, 1, 60_000)?;
    Ok((mode, reply_timeout))
}

/// Checks the bus arguments (before anything is opened or sent) and opens the port, its link watched by
/// `tap`.
pub(crate) fn open(args: &Args, tap: &Tap, configure: impl FnOnce(&mut BusConfig)) -> Result<Client, CliError> {
    let (mode, reply_timeout) = check_bus(args)?;
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
            let mut cfg = SimConfig::bus(&[args.drive], args.mode, args.baud);
            cfg.variants = args.sim_variants.clone();
            let bus = Emulator::new(cfg).map_err(CliError::usage)?;
            let host = EmulatorHost::new(bus, clock.clone(), PipeConfig::paced(args.baud));
            tap.link(Box::new(host.connect().0), &clock)
        }
        other => {
            let mut settings = SerialSettings::new(args.baud);
            settings.parity = mode.parity;
            tap.link(other.open_byte_link(settings)?, &clock)
        }
    };
    let mut cfg = BusConfig::new(mode, args.baud);
    cfg.reply_timeout = reply_timeout;
    cfg.style = if args.short { CommandStyle::Short } else { CommandStyle::Long };
    configure(&mut cfg);
    let bus = Client::new(link, clock, cfg).map_err(|e| common::classified(&e))?;
    bus.set_cancel(token);
    Ok(bus)
}
