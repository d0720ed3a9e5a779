//! Telegrams described for people: what the command line's `decode` and `demo` print, and what a program
//! can put in its logs.
//!
//! ```
//! use motionlink_scu::describe::describe_request;
//! use motionlink_scu::wire::Request;
//! assert_eq!(
//!     describe_request(&Request::Get { index: 0x0011 }),
//!     "RG remote data get: actual_position_a1 (0x0011)"
//! );
//! ```

use crate::model::{item, DataIndex, Function, MotionDirection, SafetyId, StopMode, UNUSED};
use crate::value::decode_item;
use crate::wire::{Command, Incoming, Reply, Request, Status};

fn index_name(index: u16) -> String {
    match item(DataIndex(index)) {
        Some(it) => format!("{} ({})", it.name(), DataIndex(index)),
        None => format!("unknown index {}", DataIndex(index)),
    }
}

fn function_name(id: u8) -> String {
    match Function::from_id(id) {
        Some(f) => f.to_string(),
        None => format!("unknown function id {id}"),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

/// One line about a request.
pub fn describe_request(r: &Request<'_>) -> String {
    let head = format!("{} {}", r.command(), r.command().description());
    let detail = match *r {
        Request::Open { safety_id } => match SafetyId::from_code(safety_id) {
            Some(s) => format!("Safety_ID {safety_id} ({})", s.description()),
            None => format!("Safety_ID {safety_id} (not 0, 1 or 2)"),
        },
        Request::Abort => "back to normal mode".into(),
        Request::Cyclic { object: UNUSED, .. } => "keepalive, no cyclic object".into(),
        Request::Cyclic { object, write } => {
            format!("CyclicObj {} with {} byte(s) of write data [{}]", u16::from(object) + 1, write.len(), hex(write))
        }
        Request::Get { index } => index_name(index),
        Request::Transfer { index, data } => {
            let value = item(DataIndex(index))
                .and_then(|it| decode_item(it, data).ok())
                .map(|v| v.iter().map(|(e, v)| format!("{} = {v}", e.name)).collect::<Vec<_>>().join(", "));
            match value {
                Some(v) => v,
                None => format!("{} <- [{}]", index_name(index), hex(data)),
            }
        }
        Request::Execute { function, params } => {
            let f = function_name(function);
            match Function::from_id(function) {
                Some(Function::Motion(_)) => match MotionDirection::from_code(params[0]) {
                    Some(d) => format!("{f}, direction {}: {}", params[0], d.description()),
                    None => format!("{f}, direction {} (not 0..9)", params[0]),
                },
                _ => format!("{f} on"),
            }
        }
        Request::Stop { function, param } => {
            let f = function_name(function);
            match (Function::from_id(function), StopMode::from_code(param)) {
                (Some(Function::Motion(_)), Some(StopMode::Fast)) => format!("{f}, fast stop"),
                (Some(Function::Motion(_)), Some(StopMode::Soft)) => format!("{f}, soft stop"),
                (Some(Function::Motion(_)), None) => format!("{f}, stop mode {param} (not 0 or 1)"),
                _ => format!("{f} off"),
            }
        }
    };
    format!("{head}: {detail}")
}

/// One line about an incoming telegram (a request or an unknown command).
pub fn describe_incoming(i: &Incoming<'_>) -> String {
    match i {
        Incoming::Request(r) => describe_request(r),
        Incoming::UnknownCommand { code } => {
            format!("{}{}: unknown command (the unit answers ICE)", char::from(code[0]), char::from(code[1]))
        }
    }
}

/// One line about a reply; `request` (the request it answers, if known) lets the data be decoded.
pub fn describe_reply(r: &Reply<'_>, request: Option<&Request<'_>>) -> String {
    let mut s = format!("{} {}", r.command, r.status.abbreviation());
    if r.status != Status::Ack {
        s.push_str(&format!(": {}", r.status.description()));
        return s;
    }
    let Some(data) = r.data else { return s };
    let decoded = match request {
        Some(Request::Get { index }) if r.command == Command::Get => item(DataIndex(*index))
            .and_then(|it| decode_item(it, data).ok())
            .map(|v| v.iter().map(|(e, v)| format!("{} = {v}", e.name)).collect::<Vec<_>>().join(", ")),
        _ => None,
    };
    match decoded {
        Some(d) => s.push_str(&format!(": {d}")),
        None => s.push_str(&format!(": {} data byte(s) [{}]", data.len(), hex(data))),
    }
    s
}
