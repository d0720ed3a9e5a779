//! Requests on a device's `cmd` topic and the replies to them: `{"id", "op", "args", "reply_to",
//! "lease_ms"}` in, `{"id", "ok": true, "result"}` or `{"id", "ok": false, "error"}` out.

use std::time::Duration;

use serde_json::{Map, Value};

use crate::error::ErrorReport;

/// The lease of a motion unless the request gives one.
pub const DEFAULT_LEASE: Duration = Duration::from_millis(1000);
/// The longest lease a request may ask for.
pub const MAX_LEASE: Duration = Duration::from_millis(10_000);

/// The keys a request may have.
const KEYS: [&str; 5] = ["id", "op", "args", "reply_to", "lease_ms"];

/// A request's id as the request gave it: a string, or a whole number, which the replies and events give
/// back the same (a number as a number). Compared and keyed by its text (`42` and `"42"` name one motion).
#[derive(Clone, PartialEq, Eq)]
pub struct RequestId {
    text: String,
    number: bool,
}

impl RequestId {
    /// A string id.
    pub fn text(text: impl Into<String>) -> RequestId {
        RequestId { text: text.into(), number: false }
    }
}

impl std::ops::Deref for RequestId {
    type Target = str;
    fn deref(&self) -> &str {
        &self.text
    }
}

/// As the request gave it: `"m1"`, `7` (what messages quote).
impl std::fmt::Debug for RequestId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.number {
            f.write_str(&self.text)
        } else {
            write!(f, "{:?}", self.text)
        }
    }
}

impl std::fmt::Display for RequestId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text)
    }
}

impl serde::Serialize for RequestId {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.text.parse::<serde_json::Number>() {
            Ok(n) if self.number => n.serialize(s),
            _ => s.serialize_str(&self.text),
        }
    }
}

/// One request, checked as far as it can be without knowing the device.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    /// The request's id (a string, or a whole number); a keepalive names its motion's id.
    pub id: RequestId,
    /// The action (`move`, `stop`...) or `keepalive`.
    pub op: String,
    /// The action's arguments, named as its options and arguments are.
    pub args: Map<String, Value>,
    /// Where the reply goes.
    pub reply_to: Option<String>,
    /// The lease of a motion this request starts.
    pub lease: Duration,
}

/// A request that cannot be read: the error, and the id and reply topic if they could be read.
#[derive(Debug, Clone, PartialEq)]
pub struct BadRequest {
    /// The request's id, if it had one.
    pub id: Option<RequestId>,
    /// Where the reply goes, if the request said it.
    pub reply_to: Option<String>,
    /// What is wrong.
    pub error: ErrorReport,
}

/// Reads a request from a `cmd` payload.
pub fn parse(payload: &[u8]) -> Result<Request, BadRequest> {
    let bad = |id: Option<RequestId>, reply_to: Option<String>, m: String| BadRequest {
        id,
        reply_to,
        error: ErrorReport::usage(m),
    };
    let value: Value = serde_json::from_slice(payload)
        .map_err(|e| bad(None, None, format!("a request must be a JSON object: {e}")))?;
    let Value::Object(mut map) = value else {
        return Err(bad(None, None, format!("a request must be a JSON object, not {}", kind_of(&value))));
    };
    // The reply topic and the id first: every later error can be answered.
    let reply_to = match map.remove("reply_to") {
        None | Some(Value::Null) => None,
        Some(Value::String(t)) if valid_topic(&t) => Some(t),
        Some(other) => {
            return Err(bad(None, None, format!("reply_to must be a topic without + or #, not {other}")));
        }
    };
    let id = match map.remove("id") {
        Some(Value::String(s)) if !s.is_empty() => RequestId::text(s),
        Some(Value::Number(n)) if n.is_u64() || n.is_i64() => RequestId { text: n.to_string(), number: true },
        None | Some(Value::Null) => return Err(bad(None, reply_to, "a request needs an \"id\"".into())),
        Some(Value::String(_)) => {
            return Err(bad(None, reply_to, "\"id\" must not be empty: give a string or a whole number".into()));
        }
        // A whole number serde_json could not hold in 64 bits (it came as a float): not `7.0`, which is a float.
        Some(Value::Number(n)) if n.as_f64().is_some_and(|f| f.fract() == 0.0 && f.abs() >= 9.2e18) => {
            let m = format!("\"id\" {n} is a whole number too large for 64 bits: give a smaller one, or a string");
            return Err(bad(None, reply_to, m));
        }
        Some(other) => {
            return Err(bad(None, reply_to, format!("\"id\" must be a string or a whole number, not {other}")));
        }
    };
    if let Err(e) = motionlink_link::result::each_key_once(payload) {
        // Which of two ids or reply topics is meant is not known: such a request is answered as an event.
        let (id, reply_to) = if e.to_string().starts_with("key \"id\"") || e.to_string().starts_with("key \"reply_to\"")
        {
            (None, None)
        } else {
            (Some(id), reply_to)
        };
        return Err(bad(id, reply_to, format!("{e}: give each key of a request once")));
    }
    let fail = |m: String| bad(Some(id.clone()), reply_to.clone(), m);
    if let Some(key) = map.keys().find(|k| !KEYS.contains(&k.as_str())) {
        return Err(fail(format!("unknown key {key:?} in a request; a request has {}", KEYS.join(", "))));
    }
    let op = match map.remove("op") {
        Some(Value::String(s)) if !s.is_empty() => s,
        None => return Err(fail("a request needs an \"op\" (move, stop, keepalive...)".into())),
        Some(other) => return Err(fail(format!("\"op\" must be the name of an action, not {other}"))),
    };
    let args = match map.remove("args") {
        None | Some(Value::Null) => Map::new(),
        Some(Value::Object(a)) => a,
        Some(other) => return Err(fail(format!("\"args\" must be an object of named arguments, not {other}"))),
    };
    let lease = match map.remove("lease_ms") {
        None | Some(Value::Null) => DEFAULT_LEASE,
        Some(Value::Number(n)) => match n.as_u64() {
            Some(ms @ 1..=10_000) => Duration::from_millis(ms),
            _ => return Err(fail(format!("lease_ms {n}: give a whole number of ms from 1 to 10000"))),
        },
        Some(other) => return Err(fail(format!("lease_ms must be a whole number of ms, not {other}"))),
    };
    Ok(Request { id, op, args, reply_to, lease })
}

/// True for a topic a reply may be published to (no wildcard, not empty).
fn valid_topic(t: &str) -> bool {
    !t.is_empty() && !t.contains(['+', '#', '\0'])
}

/// The kind of a JSON value, for messages.
pub fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "an object",
    }
}

/// A reply: `{"id", "ok": true, "result"}` or `{"id", "ok": false, "error"}`.
#[derive(Debug, serde::Serialize)]
struct Reply<'a> {
    id: Option<&'a RequestId>,
    ok: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    result: Option<&'a Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<&'a ErrorReport>,
}

/// The reply to request `id`: its result, or its error.
pub fn reply(id: Option<&RequestId>, outcome: &Result<Value, ErrorReport>) -> Value {
    let reply = match outcome {
        Ok(result) => Reply { id, ok: true, result: Some(result), error: None },
        Err(error) => Reply { id, ok: false, result: None, error: Some(error) },
    };
    serde_json::to_value(reply).unwrap_or(Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> BadRequest {
        parse(text.as_bytes()).unwrap_err()
    }

    #[test]
    fn a_request_has_an_id_an_op_args_a_reply_topic_and_a_lease() {
        let r = parse(br#"{"id": "m1", "op": "move", "args": {"actuator": 1, "position": 300}, "reply_to": "me/r", "lease_ms": 500}"#)
            .unwrap();
        assert_eq!((&*r.id, r.op.as_str(), r.reply_to.as_deref()), ("m1", "move", Some("me/r")));
        assert_eq!((r.args["position"].clone(), r.lease), (Value::from(300), Duration::from_millis(500)));
        let r = parse(br#"{"id": 7, "op": "keepalive"}"#).unwrap();
        assert_eq!((&*r.id, r.lease, r.args.len()), ("7", DEFAULT_LEASE, 0));
        // A number is given back as a number (a client matches its replies by the id it sent).
        assert_eq!(reply(Some(&r.id), &Ok(Value::Null))["id"], serde_json::json!(7));
        let e = parse(br#"{"id": 123456789012345678901234567890, "op": "keepalive"}"#).unwrap_err();
        assert!(e.error.message.contains("too large for 64 bits"), "{}", e.error.message);
        for float in ["7.0", "-0.0", "1e3"] {
            let e = parse(format!(r#"{{"id": {float}, "op": "keepalive"}}"#).as_bytes()).unwrap_err();
            assert!(e.error.message.contains("must be a string or a whole number"), "{float}: {}", e.error.message);
        }
        let r = parse(br#"{"id": -12345678901234567, "op": "keepalive"}"#).unwrap();
        assert_eq!(reply(Some(&r.id), &Ok(Value::Null))["id"], serde_json::json!(-12345678901234567i64));
    }

    #[test]
    fn a_key_given_twice_is_refused_not_taken_at_its_last_value() {
        let e = err(
            r#"{"id": "d1", "op": "move", "args": {"actuator": 1, "position": 10, "position": 300}, "reply_to": "me/r"}"#,
        );
        assert_eq!((e.id.as_deref(), e.reply_to.as_deref()), (Some("d1"), Some("me/r")));
        assert!(e.error.message.contains("key \"args.position\" given twice"), "{}", e.error.message);
        assert_eq!(e.error.kind, "usage");
        let e = err(r#"{"id": "d2", "op": "info", "op": "stop", "reply_to": "me/r"}"#);
        assert!(e.error.message.contains("key \"op\" given twice") && e.id.is_some(), "{}", e.error.message);
        // Two ids: which one the client matches is not known, so no reply names either.
        let e = err(r#"{"id": "m1", "op": "move", "id": "m2", "reply_to": "me/r"}"#);
        assert_eq!((e.id, e.reply_to), (None, None));
        assert!(e.error.message.contains("key \"id\" given twice"), "{}", e.error.message);
        // In a list too; the same key in two objects is fine.
        assert!(err(r#"{"id": "d3", "op": "get", "args": {"items": [{"a": 1, "a": 2}]}}"#)
            .error
            .message
            .contains("args.items[0].a"));
        parse(br#"{"id": "d4", "op": "get", "args": {"items": [{"a": 1}, {"a": 2}]}}"#).unwrap();
    }

    #[test]
    fn a_bad_request_is_answered_where_it_can_be() {
        let e = err("not json");
        assert!(e.id.is_none() && e.reply_to.is_none() && e.error.kind == "usage");
        let e = err(r#"[1, 2]"#);
        assert!(e.error.message.contains("not a list"), "{}", e.error.message);
        let e = err(r#"{"op": "move", "reply_to": "me/r"}"#);
        assert_eq!((e.id, e.reply_to.as_deref()), (None, Some("me/r")));
        let e = err(r#"{"id": "a", "op": "move", "reply_to": "me/r", "lease": 5}"#);
        assert_eq!(e.id.as_deref(), Some("a"));
        assert!(e.error.message.contains("\"lease\"") && e.error.message.contains("lease_ms"), "{}", e.error.message);
        let e = err(r#"{"id": "", "op": "move"}"#);
        assert!(e.error.message.contains("must not be empty"), "{}", e.error.message);
        for (text, said) in [
            (r#"{"id": "a", "op": "move", "lease_ms": 10001}"#, "10000"),
            (r#"{"id": "a", "op": "move", "lease_ms": 0}"#, "from 1"),
            (r#"{"id": "a", "op": "move", "lease_ms": 1.5}"#, "whole number"),
            (r#"{"id": "a", "op": 3}"#, "\"op\""),
            (r#"{"id": "a", "op": "move", "args": [1]}"#, "\"args\""),
            (r#"{"id": 1.5, "op": "move"}"#, "\"id\""),
            (r#"{"id": "a", "op": "move", "reply_to": "x/#"}"#, "reply_to"),
        ] {
            assert!(err(text).error.message.contains(said), "{text}: {}", err(text).error.message);
        }
    }

    #[test]
    fn replies_carry_the_result_or_the_error() {
        let ok = reply(Some(&RequestId::text("m1")), &Ok(serde_json::json!({"reached": 1})));
        assert_eq!(ok, serde_json::json!({"id": "m1", "ok": true, "result": {"reached": 1}}));
        let e = reply(None, &Err(ErrorReport::usage("no")));
        assert_eq!(
            e,
            serde_json::json!({"id": null, "ok": false, "error": {"kind": "usage", "message": "no", "exit_code": 2}})
        );
    }
}
