//! `motionlink powercube send` and `params`: one telegram, typed or in hex, and the parameter table.

use super::*;
use motionlink_powercube::model::PARAMS;
use motionlink_powercube::report::ParamRow;

/// A row of `params --json`: the family, then the library's row.
#[derive(serde::Serialize)]
struct Listed {
    family: &'static str,
    #[serde(flatten)]
    row: ParamRow,
}

/// A whole RS232 telegram in hex (STX, TELID, data, BCC, ETX, escapes included), checked: exactly one
/// frame, a command (not an answer) to module `module`, its BCC and length right. Returns its payload.
fn telegram_payload(bytes: &[u8], module: u8) -> Result<Payload, CliError> {
    use motionlink_powercube::wire::rs232::{Rs232Decoder, TelKind};
    let hex = motionlink_link::hex::hex(bytes);
    let mut decoder = Rs232Decoder::new();
    let frames: Vec<_> = decoder.feed(bytes).collect();
    let frame = match frames.as_slice() {
        [Ok(f)] => *f,
        [Err(e)] => return Err(CliError::usage(format!("{hex}: not an RS232 telegram ({e})"))),
        [] => return Err(CliError::usage(format!("{hex}: an incomplete RS232 telegram (no ETX 03 at its end)"))),
        _ => return Err(CliError::usage(format!("{hex}: give one telegram, not {}", frames.len()))),
    };
    if !frame.bcc_ok() {
        return Err(CliError::usage(format!(
            "{hex}: wrong BCC 0x{:02X}, the telegram's bytes give 0x{:02X}",
            frame.bcc_received, frame.bcc_computed
        )));
    }
    if !frame.length_ok() {
        return Err(CliError::usage(format!(
            "{hex}: the TELID says {} data bytes, the telegram has {}",
            frame.declared_len,
            frame.payload.len()
        )));
    }
    match (frame.kind, frame.address) {
        (TelKind::Recv, _) => Err(CliError::usage(format!(
            "{hex}: an answer of a module (first TELID byte 0x08..0x0B, TELID_RECVDAT), not a command"
        ))),
        (_, 0) => Err(CliError::usage(format!("{hex}: a broadcast (address 0); send takes a command to one module"))),
        (_, a) if a != module => {
            Err(CliError::usage(format!("{hex}: the telegram is for module {a}, not {module}: give --module {a}")))
        }
        _ => Ok(frame.payload),
    }
}

/// Parses `send`'s words for `module`: a typed command, a payload in hex, or a whole RS232 telegram in hex
/// (`02 ... 03`, BCC checked). Motion commands are refused (`move` watches and stops what it starts; a bare
/// motion command would be left running).
pub(super) fn parse_send(words: &[String], module: u8) -> Result<Request, CliError> {
    let first = words[0].to_ascii_lowercase().replace(['-', '_'], "");
    let rest = &words[1..];
    let none = |r: Request| {
        if rest.is_empty() {
            Ok(r)
        } else {
            Err(CliError::usage(format!("send {}: takes no arguments", words[0])))
        }
    };
    let request = match first.as_str() {
        "get" => match rest {
            [p] => Request::get(parse_param(p)?).map_err(|e| CliError::usage(e.to_string()))?,
            _ => return Err(CliError::usage("send get: give one parameter, such as send get ActPos")),
        },
        "set" => match rest {
            [p, v] => {
                let p = parse_param(p)?;
                let v = Value::parse(p, v).map_err(CliError::usage)?;
                Request::set(p, v).map_err(|e| CliError::usage(e.to_string()))?
            }
            _ => return Err(CliError::usage("send set: give a parameter and a value, such as send set TargetVel 0.5")),
        },
        "reset" => none(Request::Action(PcAction::Reset))?,
        "home" => {
            return Err(CliError::usage(
                "send home starts a motion: use `motionlink powercube home`, which watches and stops it",
            ))
        }
        "halt" => none(Request::Action(PcAction::Halt))?,
        "recalcpid" | "recalcpidparam" => none(Request::Action(PcAction::RecalcPid))?,
        "resettime" => none(Request::Action(PcAction::ResetTime))?,
        "saveparameters" => none(Request::Action(PcAction::SaveParameters))?,
        _ => {
            let bytes = motionlink_link::hex::parse_hex(&words.join(" ")).map_err(|_| {
                // A misspelt command is answered with the nearest one (hlat: did you mean halt?).
                let typed = ["get", "set", "reset", "halt", "recalc-pid", "reset-time", "save-parameters", "home"];
                match motionlink_link::table::did_you_mean(&motionlink_link::table::nearest(&words[0], typed)) {
                    Some(hint) => CliError::usage(format!("{:?} is not a command: {hint}", words[0])),
                    None => CliError::usage(format!(
                        "{:?} is neither a typed command (get, set, reset, halt, recalc-pid, reset-time, \
                         save-parameters) nor hex (a payload, or a whole RS232 telegram 02 ... 03)",
                        words.join(" ")
                    )),
                }
            })?;
            let payload = if bytes.first() == Some(&0x02) && bytes.last() == Some(&0x03) && bytes.len() >= 5 {
                telegram_payload(&bytes, module)?
            } else {
                Payload::new(&bytes).map_err(|e| CliError::usage(e.to_string()))?
            };
            Request::decode(&payload).map_err(|e| {
                // Bytes that start as a telegram does (STX, a TELID) were likely meant as one.
                let telegram = if bytes.first() == Some(&0x02) && bytes.len() >= 3 && bytes.last() != Some(&0x03) {
                    "; as a whole RS232 telegram it lacks its ETX (03) at the end"
                } else {
                    ""
                };
                CliError::usage(format!("not a command: {e}{telegram}"))
            })?
        }
    };
    if request.starts_motion() {
        return Err(CliError::usage(
            "send does not start motions (nothing would watch or stop them): use move or home",
        ));
    }
    request.validate().map_err(|e| CliError::usage(e.to_string()))?;
    Ok(request)
}

/// `send`: one command to the module, and its acknowledge, each explained.
pub(super) fn send(
    args: &Args,
    client: &Client,
    request: &Request,
    tap: &Tap,
    o: &Out<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    // The module's kind first (its Config word), so that values show in rad or m, not "rad|m"; a module that
    // cannot tell still gets the command.
    let kind = client.module(args.module).kind().ok();
    let (result, seen) = tap.seen_during(|| client.request(args.module, request))?;
    let exchange = crate::tap::exchange(&seen, None);
    crate::tap::print_sent(out, o, exchange, &command_text(request, kind), result.is_ok(), ())?;
    result.map(|_| ()).map_err(failed)
}

/// A command as text, a value it sets in the unit of the module's `kind` where known.
fn command_text(request: &Request, kind: Option<ModuleKind>) -> String {
    match request {
        Request::Set(p, v) => format!("SetExtended {p} = {}", v.show_in(*p, kind)),
        other => other.to_string(),
    }
}

pub(super) fn print_params(out: &mut dyn Write, as_json: bool) -> Result<(), CliError> {
    if as_json {
        // A listing: one object per parameter (JSON Lines), as `scu names`.
        for e in PARAMS.iter() {
            common::print_json(out, &common::to_json(&Listed { family: "powercube", row: ParamRow(e) }))?;
        }
        return Ok(());
    }
    writeln!(
        out,
        "{:<4}  {:<22}  {:<17}  {:<9}  {:<6}  {:<7}  description",
        "id", "name", "type", "unit", "access", "class"
    )?;
    for e in PARAMS.iter() {
        writeln!(
            out,
            "0x{:02X}  {:<22}  {:<17}  {:<9}  {:<6}  {:<7}  {}",
            e.id,
            e.name,
            e.kind.data_type.name(),
            e.unit,
            e.access.short(),
            e.kind.class.name(),
            e.title
        )?;
    }
    Ok(())
}
