//! `motionlink scu send` (one telegram, typed or as hex, and its reply, each explained) and
//! `motionlink scu names` (the data list).

use std::io::Write;

use motionlink_scu::model::{DataEntryExt, Function, MotionDirection, SpeedMode, StopMode, DATA_LIST, GROUPS};
use motionlink_scu::results::data_items;
use motionlink_scu::value::shown_unit;
use motionlink_scu::wire::{Incoming, Request, RequestDecoder};

use crate::common::Out;
use crate::common::{self, CliError, Row};
use crate::tap::{exchange, print_sent, Tap};

/// A request of `send`, owned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum SendRequest {
    /// RG index.
    Get(u16),
    /// RT index data.
    Transfer(u16, Vec<u8>),
    /// RE function-id params.
    Execute(u8, [u8; 2]),
    /// RS function-id param.
    Stop(u8, u8),
}

impl SendRequest {
    /// The request, as the wire module takes it.
    fn request(&self) -> Request<'_> {
        match self {
            SendRequest::Get(index) => Request::Get { index: *index },
            SendRequest::Transfer(index, data) => Request::Transfer { index: *index, data },
            SendRequest::Execute(function, params) => Request::Execute { function: *function, params: *params },
            SendRequest::Stop(function, param) => Request::Stop { function: *function, param: *param },
        }
    }
}

const UNUSED: u8 = 0xFF;

fn session_owned(command: &str) -> CliError {
    CliError::usage(format!(
        "{command} belongs to the session (motionlink sends RO when it opens, RC to keep the unit's watchdog fed and \
         RA when it ends); send RG, RT, RE or RS"
    ))
}

fn param(text: &str) -> Result<u8, CliError> {
    let t = text.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => u8::from_str_radix(h, 16).ok(),
        None if t == "-1" => Some(UNUSED),
        None => t.parse().ok(),
    };
    parsed.ok_or_else(|| CliError::usage(format!("{text:?} is not a parameter byte (0..255, 0xFF or -1 for unused)")))
}

/// Parses `send`'s words: a typed request (`RG ITEM`, `RT ITEM VALUE`, `RE FUNCTION [DIRECTION | P0 [P1]]`,
/// `RS FUNCTION [fast|soft]`) or the bytes of one telegram in hex (checked: the CRC must be right).
pub(super) fn parse(words: &[String]) -> Result<SendRequest, CliError> {
    let first = words[0].to_ascii_uppercase();
    let rest = &words[1..];
    let arity = |min: usize, max: usize, usage: &str| {
        if rest.len() < min || rest.len() > max {
            Err(CliError::usage(format!("send {first}: give {usage}")))
        } else {
            Ok(())
        }
    };
    match first.as_str() {
        "RO" | "RA" | "RC" => Err(session_owned(&first)),
        "RG" => {
            arity(1, 1, "one data-list name or index, such as RG actual_position_a1")?;
            Ok(SendRequest::Get(super::parse_item(&rest[0])?.index().0))
        }
        "RT" => {
            arity(2, 2, "a remote data name and a value, such as RT remote_speed_f1 80")?;
            let (e, v) =
                motionlink_scu::args::parse_write(super::parse_item(&rest[0])?, &rest[1]).map_err(CliError::usage)?;
            Ok(SendRequest::Transfer(e.index().0, v.to_bytes()))
        }
        "RE" => {
            arity(1, 3, "a function and its parameters, such as RE F1 out, RE F11 or RE 1 9 -1")?;
            let f = rest[0].parse::<Function>().map_err(CliError::usage)?;
            let params = match (f, &rest[1..]) {
                (_, []) if !matches!(f, Function::Motion(_)) => [UNUSED, UNUSED],
                (Function::Motion(_), []) => {
                    return Err(CliError::usage(format!("RE {f}: a motion function needs a direction (in, out, ...)")))
                }
                (_, [p0]) => match MotionDirection::parse(p0) {
                    Some(d) if matches!(f, Function::Motion(_)) && p0.parse::<u8>().is_err() => [d.code(), UNUSED],
                    _ => [param(p0)?, UNUSED],
                },
                (_, [p0, p1]) => [param(p0)?, param(p1)?],
                _ => unreachable!("arity checked"),
            };
            Ok(SendRequest::Execute(f.id(), params))
        }
        "RS" => {
            arity(1, 2, "a function and, for F1..F10, fast or soft, such as RS F1 soft")?;
            let f = rest[0].parse::<Function>().map_err(CliError::usage)?;
            let p = match (f, rest.get(1).map(|s| s.to_ascii_lowercase())) {
                (Function::Motion(_), None) => StopMode::Fast.code(),
                (Function::Motion(_), Some(m)) if m == "fast" => StopMode::Fast.code(),
                (Function::Motion(_), Some(m)) if m == "soft" => StopMode::Soft.code(),
                (_, None) => UNUSED,
                (_, Some(p)) => param(&p)?,
            };
            Ok(SendRequest::Stop(f.id(), p))
        }
        _ => telegram_in_hex(&words.join(" ")).map_err(|e| {
            // Not hex either: a misspelt request is answered with the nearest one (GR: did you mean RG?).
            let typed = ["RG", "RT", "RE", "RS"];
            match motionlink_link::table::did_you_mean(&motionlink_link::table::nearest(&first, typed)) {
                Some(hint) if motionlink_link::hex::parse_hex(&words.join(" ")).is_err() => {
                    CliError::usage(format!("{:?} is not a request: {hint}", words[0]))
                }
                _ => e,
            }
        }),
    }
}

/// One whole request telegram in hex, checked by the unit's own decoder.
fn telegram_in_hex(text: &str) -> Result<SendRequest, CliError> {
    let bytes = motionlink_link::hex::parse_hex(text).map_err(|_| {
        CliError::usage(format!(
            "{text:?} is neither a typed request (RG, RT, RE, RS) nor the bytes of a telegram in hex"
        ))
    })?;
    let mut decoder = RequestDecoder::new();
    let (used, event) = decoder.decode(&bytes);
    let request = match event {
        Some(Ok(Incoming::Request(r))) if used == bytes.len() => r,
        Some(Ok(Incoming::Request(_))) => {
            return Err(CliError::usage(format!(
                "{} byte(s) after the telegram: send one telegram",
                bytes.len() - used
            )))
        }
        Some(Ok(Incoming::UnknownCommand { code })) => {
            return Err(CliError::usage(format!(
                "{:02X} {:02X} is not a command of the SCU protocol",
                code[0], code[1]
            )))
        }
        Some(Err(e)) => return Err(CliError::usage(format!("not a telegram: {e}"))),
        None => return Err(CliError::usage("an incomplete telegram (too short for its command)")),
    };
    Ok(match request {
        Request::Get { index } => SendRequest::Get(index),
        Request::Transfer { index, data } => SendRequest::Transfer(index, data.to_vec()),
        Request::Execute { function, params } => SendRequest::Execute(function, params),
        Request::Stop { function, param } => SendRequest::Stop(function, param),
        Request::Open { .. } => return Err(session_owned("RO")),
        Request::Abort => return Err(session_owned("RA")),
        Request::Cyclic { .. } => return Err(session_owned("RC")),
    })
}

/// Sends `request` on the open session and prints it and the unit's reply, each explained.
pub(super) fn send(
    client: &motionlink_scu::Client,
    request: &SendRequest,
    tap: &Tap,
    report: &Out<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let r = request.request();
    let wire = motionlink_scu::wire::request_to_vec(&r).map_err(|e| CliError::usage(e.to_string()))?;
    let (result, seen) = tap.seen_during(|| client.request(&r))?;
    // The JSON object has the reply's data besides the exchange.
    let data = result.as_ref().ok().and_then(|d| d.as_deref()).map(motionlink_link::hex::hex);
    let command = String::from_utf8_lossy(&wire[..2]);
    let data = common::Keyed("data", data);
    print_sent(out, report, exchange(&seen, Some(&wire)), &command, result.is_ok(), data)?;
    result.map(|_| ()).map_err(|e| common::classified(&e))
}

/// `names`: the data list's entries and groups.
/// Units as `get` gives its values: amperes and volts for the converted entries, a remote speed in the unit
/// of `speed_mode`.
pub(super) fn names(json: bool, speed_mode: SpeedMode, out: &mut dyn Write) -> Result<(), CliError> {
    if json {
        /// One line of `names --json`: the family, then the entry or group.
        #[derive(serde::Serialize)]
        struct Named<T> {
            family: &'static str,
            #[serde(flatten)]
            item: T,
        }
        for item in data_items(speed_mode) {
            common::print_json(out, &common::to_json(&Named { family: "scu", item }))?;
        }
        return Ok(());
    }
    let mut rows: Vec<Row> = DATA_LIST
        .iter()
        .map(|e| {
            let unit = shown_unit(e, speed_mode);
            let unit = if unit.is_empty() { String::new() } else { format!(" [{unit}]") };
            (e.name.to_string(), format!("{} {}{unit} {}", e.index(), e.access.short(), e.title))
        })
        .collect();
    rows.extend(
        GROUPS
            .iter()
            .map(|g| (g.name.to_string(), format!("{} r group of 0x{:04X}..0x{:04X}", g.index, g.first, g.last))),
    );
    common::print_table(out, &rows)
}
