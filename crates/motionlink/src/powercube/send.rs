//! `motionlink powercube send` and `params`: one telegram, typed or in hex, and the parameter table.

use super::*;

/// Parses `send`'s words: a typed command or a payload in hex. Motion commands are refused (`move` watches
/// and stops what it starts; a bare motion command would be left running).
pub(super) fn parse_send(words: &[String]) -> Result<Request, CliError> {
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
        "home" => return Err(CliError::usage("send home starts a motion: use `motionlink powercube home`")),
        "halt" => none(Request::Action(PcAction::Halt))?,
        "recalcpid" | "recalcpidparam" => none(Request::Action(PcAction::RecalcPid))?,
        "resettime" => none(Request::Action(PcAction::ResetTime))?,
        "saveparameters" => none(Request::Action(PcAction::SaveParameters))?,
        _ => {
            let bytes = common::parse_hex(&words.join(" ")).map_err(|_| {
                CliError::usage(format!(
                    "{:?} is neither a typed command (get, set, reset, halt, recalc-pid, reset-time, \
                     save-parameters) nor a payload in hex",
                    words.join(" ")
                ))
            })?;
            let payload = Payload::new(&bytes).map_err(|e| CliError::usage(format!("{} bytes: {e:?}", e.0)))?;
            Request::decode(&payload).map_err(|e| CliError::usage(format!("not a command: {e}")))?
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
    port: &str,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let telegrams = tap.telegrams().ok_or_else(|| CliError::usage("send: no tap on the link"))?;
    telegrams.clear();
    let result = client.request(args.module, request);
    let seen = telegrams.take();
    let (sent, reply) = crate::tap::exchange(&seen, None);
    let (sent_json, reply_json) = crate::tap::print_exchange(out, args.json, sent.as_ref(), reply.as_ref())?;
    if args.json {
        let v = common::identified(
            "powercube",
            port,
            json!({"module": args.module.get(), "command": format!("{request:?}"), "request": sent_json,
                   "reply": reply_json, "ok": result.is_ok()}),
        );
        common::print_json(out, &v)?;
    }
    result.map(|_| ()).map_err(failed)
}

pub(super) fn print_params(out: &mut dyn Write, as_json: bool) -> Result<(), CliError> {
    if as_json {
        let list: Vec<_> = PARAMS
            .iter()
            .map(|e| {
                json!({"id": e.id, "name": e.name, "type": e.kind.data_type.name(), "unit": e.unit,
                       "access": e.access.short(), "class": e.kind.class.name(), "description": e.title})
            })
            .collect();
        return common::print_json(out, &json!(list));
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
