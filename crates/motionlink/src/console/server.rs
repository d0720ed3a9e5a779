//! The HTTP side of the console: the page and its assets (embedded in the binary), the capture download,
//! and the WebSocket of each page. Every request needs the token; the WebSocket also needs an `Origin` of
//! this very server.

use std::sync::Arc;
use std::time::Duration;

use axum::body::{Body, Bytes};
use axum::extract::ws::{CloseFrame, Message as WsMessage, WebSocket, WebSocketUpgrade};
use axum::extract::{FromRequestParts, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::Response;
use serde_json::Value;
use tokio::sync::{broadcast, mpsc};
use tokio::time::Instant;

use super::device::{ErrorReport, JogDirection};
use super::hub::{Hub, Notice, Role, Units};
use super::message::{Message, Numbered};
use super::token;
use crate::common::Keyed;

const INDEX_HTML: &str = include_str!("assets/index.html");
const APP_JS: &str = include_str!("assets/app.js");
const APP_CSS: &str = include_str!("assets/app.css");

/// How long a page may stay silent (no message, no answer to a ping) before it counts as gone.
const PAGE_SILENCE: Duration = Duration::from_millis(1500);
/// How often a page is pinged.
const PING_EVERY: Duration = Duration::from_millis(500);
/// At most this many log lines go to a page per sample.
const LOG_BATCH: usize = 300;

/// What the HTTP handlers share.
pub struct App {
    /// The console's state.
    pub hub: Arc<Hub>,
    /// The token every request must carry.
    pub token: String,
    /// The `Host` values a request may name (None: any, when listening on every interface).
    pub hosts: Option<Vec<String>>,
}

fn plain(status: StatusCode, text: &str) -> Response {
    let mut r = Response::new(Body::from(text.to_string()));
    *r.status_mut() = status;
    r.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static("text/plain; charset=utf-8"));
    r
}

fn asset(content_type: &'static str, body: impl Into<Body>) -> Response {
    let mut r = Response::new(body.into());
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    h.insert(header::REFERRER_POLICY, HeaderValue::from_static("no-referrer"));
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'self'; img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'",
        ),
    );
    r
}

fn header_str(headers: &HeaderMap, name: header::HeaderName) -> Option<&str> {
    headers.get(name).and_then(|v| v.to_str().ok())
}

/// Checks the `Host` of a request against the addresses the console serves.
fn host_allowed(app: &App, headers: &HeaderMap) -> bool {
    match (&app.hosts, header_str(headers, header::HOST)) {
        (None, Some(_)) => true,
        (Some(list), Some(h)) => list.iter().any(|a| a.eq_ignore_ascii_case(h)),
        (_, None) => false,
    }
}

/// Every request: the token first, then the route.
pub async fn handle(State(app): State<Arc<App>>, req: Request) -> Response {
    let given = token::query_value(req.uri().query(), "token").unwrap_or("");
    if !token::same(given, &app.token) {
        return plain(
            StatusCode::FORBIDDEN,
            "motionlink console: wrong or missing token. Open the address the console printed \
             (console on http://...?token=...).\n",
        );
    }
    if !host_allowed(&app, req.headers()) {
        return plain(StatusCode::FORBIDDEN, "motionlink console: this Host is not the console's address.\n");
    }
    match req.uri().path() {
        "/" | "/index.html" => asset("text/html; charset=utf-8", INDEX_HTML.replace("{{TOKEN}}", &app.token)),
        "/app.js" => asset("text/javascript; charset=utf-8", APP_JS),
        "/app.css" => asset("text/css; charset=utf-8", APP_CSS),
        "/capture" => {
            let family = app.hub.device().naming().family;
            let mut r = asset("text/plain; charset=utf-8", app.hub.traffic.capture_file());
            let name = format!("attachment; filename=\"motionlink-{family}-capture.log\"");
            if let Ok(v) = HeaderValue::from_str(&name) {
                r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
            }
            r
        }
        "/ws" => {
            // A WebSocket is not bound by the same-origin policy: only a page of this server may open one.
            let origin = header_str(req.headers(), header::ORIGIN);
            let host = header_str(req.headers(), header::HOST).unwrap_or("");
            if origin.is_none_or(|o| !o.eq_ignore_ascii_case(&format!("http://{host}"))) {
                return plain(
                    StatusCode::FORBIDDEN,
                    "motionlink console: the WebSocket's Origin is not this console.\n",
                );
            }
            let (mut parts, _body) = req.into_parts();
            match WebSocketUpgrade::from_request_parts(&mut parts, &()).await {
                Ok(ws) => {
                    let hub = Arc::clone(&app.hub);
                    ws.on_upgrade(move |socket| page(hub, socket))
                }
                Err(rejection) => axum::response::IntoResponse::into_response(rejection),
            }
        }
        _ => plain(StatusCode::NOT_FOUND, "motionlink console: no such page.\n"),
    }
}

/// The units as the page gets them: none while scanning, with the failure if the scan failed.
fn units_message(hub: &Hub, units: &Units) -> Message {
    let key = hub.device().naming().unit_key;
    let (scanning, found, error) = match units {
        Units::Scanning => (true, Vec::new(), None),
        Units::Found(list) => (false, list.clone(), None),
        Units::Failed(e) => (true, Vec::new(), Some(e.clone())),
    };
    let units = found.into_iter().map(|u| Numbered { unit: Keyed(key, u.id), what: u }).collect();
    Message::Units { scanning, units, error }
}

fn role_message(hub: &Hub, page: u64) -> Message {
    let (role, control_free) = hub.role_of(page);
    let message = match role {
        Role::Control => "this page controls the console",
        Role::ReadOnly if control_free => "read-only: no page controls the console now; take control to move",
        Role::ReadOnly => "read-only: another page controls the console (Stop still works here)",
    };
    Message::Role { role: role.name(), control_free, message }
}

fn welcome(hub: &Hub, page: u64) -> Message {
    let d = hub.device();
    Message::Welcome {
        family: d.naming().family,
        port: d.port(),
        unit_key: d.naming().unit_key,
        params: d.params(),
        actions: d.actions(),
        dead_man_ms: super::hub::DEAD_MAN.as_millis() as u64,
        sample_period_ms: super::hub::SAMPLE_PERIOD.as_millis() as u64,
        role: Box::new(role_message(hub, page)),
    }
}

/// One page's WebSocket: what it sends is done (its role allowing); samples, the traffic log and notices
/// go to it until it goes away, which stops the motion it owns.
async fn page(hub: Arc<Hub>, mut socket: WebSocket) {
    let (id, _) = hub.page_opened();
    let (replies, mut replies_rx) = mpsc::channel::<Message>(64);
    let mut notices = hub.notices();
    let mut samples = hub.samples();
    let mut shutdown = hub.shutdown_signal();
    let mut last_seq = hub.traffic.last_seq().saturating_sub(200);
    let mut tick = tokio::time::interval(super::hub::SAMPLE_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut last_heard = Instant::now();
    let mut last_ping = Instant::now();
    let mut outgoing: Vec<Message> = vec![welcome(&hub, id), units_message(&hub, &hub.units().borrow().clone())];
    'page: loop {
        for v in outgoing.drain(..) {
            if socket.send(WsMessage::Text(v.json().to_string().into())).await.is_err() {
                break 'page;
            }
        }
        tokio::select! {
            msg = socket.recv() => match msg {
                Some(Ok(WsMessage::Text(text))) => {
                    last_heard = Instant::now();
                    if let Some(v) = request(&hub, id, text.as_str(), &replies) {
                        outgoing.push(v);
                    }
                }
                Some(Ok(WsMessage::Close(_))) | None | Some(Err(_)) => break 'page,
                Some(Ok(_)) => last_heard = Instant::now(),
            },
            Some(v) = replies_rx.recv() => outgoing.push(v),
            notice = notices.recv() => match notice {
                Ok(Notice::Json(text)) => {
                    if socket.send(WsMessage::Text(text.as_str().into())).await.is_err() {
                        break 'page;
                    }
                }
                Ok(Notice::RoleChanged) => outgoing.push(role_message(&hub, id)),
                Ok(Notice::UnitsChanged) => outgoing.push(units_message(&hub, &hub.units().borrow().clone())),
                Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => break 'page,
            },
            changed = samples.changed() => {
                if changed.is_err() {
                    break 'page;
                }
                // Each sample goes out as soon as it is taken.
                let frame = samples.borrow_and_update().clone();
                if let Some(text) = frame {
                    if socket.send(WsMessage::Text(text.as_str().into())).await.is_err() {
                        break 'page;
                    }
                }
            }
            _ = tick.tick() => {
                let lines = hub.traffic.since(last_seq, LOG_BATCH);
                if let Some(last) = lines.last() {
                    last_seq = last.seq;
                    outgoing.push(Message::Traffic { lines });
                }
                let now = Instant::now();
                if now.duration_since(last_heard) > PAGE_SILENCE {
                    // Neither a message nor an answer to the pings: the page is gone.
                    break 'page;
                }
                if now.duration_since(last_ping) >= PING_EVERY {
                    last_ping = now;
                    if socket.send(WsMessage::Ping(Bytes::from_static(b"ml"))).await.is_err() {
                        break 'page;
                    }
                }
            }
            _ = shutdown.changed() => {
                // What the hub said before (the stop of the motion under way) goes out before the bye.
                while let Ok(notice) = notices.try_recv() {
                    if let Notice::Json(text) = notice {
                        let _ = socket.send(WsMessage::Text(text.as_str().into())).await;
                    }
                }
                let bye = Message::Bye { message: super::hub::ENDING }.json().to_string();
                let _ = socket.send(WsMessage::Text(bye.into())).await;
                // The WebSocket's own end: 1001, going away.
                let close = CloseFrame { code: 1001, reason: super::hub::ENDING.into() };
                let _ = socket.send(WsMessage::Close(Some(close))).await;
                break 'page;
            }
        }
    }
    hub.page_closed(id);
}

/// A number field of a request.
fn number(req: &Value, key: &str) -> Result<Option<f64>, ErrorReport> {
    match req.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => v.as_f64().map(Some).ok_or_else(|| ErrorReport::usage(format!("{key}: {v} is not a number"))),
    }
}

/// `"a", "b", "c"`: keys as a message names them.
fn key_list<'a>(keys: impl IntoIterator<Item = &'a str>) -> String {
    keys.into_iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", ")
}

/// Refuses the keys of `req` that `what` (a request and its kind, "a move of actuator 1") does not take
/// besides `type`, naming them and the keys it takes: a key misnamed is not ignored (a move's speed under
/// the jog's `speed` would otherwise leave the move at its default speed).
fn takes_only(req: &Value, what: &str, takes: &[&str]) -> Result<(), ErrorReport> {
    let unknown: Vec<&str> = req
        .as_object()
        .into_iter()
        .flat_map(|o| o.keys())
        .map(String::as_str)
        .filter(|k| *k != "type" && !takes.contains(k))
        .collect();
    if unknown.is_empty() {
        return Ok(());
    }
    let keys = if unknown.len() == 1 { "key" } else { "keys" };
    let taken = key_list(std::iter::once("type").chain(takes.iter().copied()));
    Err(ErrorReport::usage(format!("unknown {keys} {}: {what} takes {taken} only", key_list(unknown))))
}

/// The unit a request names with the family's key (`actuator`, `module`, `drive`): a number the family's
/// units can have (not yet whether the console found that unit: [`found_unit`]).
fn unit_of(hub: &Hub, req: &Value) -> Result<u8, ErrorReport> {
    let key = hub.device().naming().unit_key;
    let range = hub.device().naming().unit_numbers;
    let (first, last) = (range.start(), range.end());
    match req.get(key) {
        None | Some(Value::Null) => {
            Err(ErrorReport::usage(format!("the request names no {key}: give \"{key}\", a number {first}..{last}")))
        }
        Some(v) => v.as_u64().and_then(|n| u8::try_from(n).ok()).filter(|n| range.contains(n)).ok_or_else(|| {
            ErrorReport::usage(format!("{key} {v} is not a {key} number: give a whole number {first}..{last}"))
        }),
    }
}

/// The unit `unit` of those the console found (a panel acts on a unit of the units table): a unit not
/// found is refused before anything is sent to it, naming the units found.
fn found_unit(hub: &Hub, unit: u8) -> Result<crate::console::device::Unit, ErrorReport> {
    let key = hub.device().naming().unit_key;
    let Units::Found(list) = hub.units().borrow().clone() else {
        return Err(ErrorReport::usage(format!("{key} {unit}: the console has found no {key} yet (it is scanning)")));
    };
    let found = list.iter().map(|u| u.id.to_string()).collect::<Vec<_>>().join(", ");
    list.into_iter()
        .find(|u| u.id == unit)
        .ok_or_else(|| ErrorReport::usage(format!("{key} {unit} was not found: the console found {key} {found}")))
}

/// The request types a page may send.
const REQUESTS: [&str; 10] =
    ["stop", "move", "jog", "jog_hold", "jog_release", "take_control", "action", "read_param", "write_param", "errors"];

/// Handles one message of page `page`: an answer to send at once, or none (an answer comes later through
/// `replies`).
fn request(hub: &Arc<Hub>, page: u64, text: &str, replies: &mpsc::Sender<Message>) -> Option<Message> {
    let req: Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => return Some(Message::failure("?", false, ErrorReport::usage(format!("not JSON: {e}")))),
    };
    let kind = req.get("type").and_then(Value::as_str).unwrap_or("").to_string();
    if hub.ending() && !matches!(kind.as_str(), "stop" | "jog_release" | "jog_hold") {
        return Some(Message::failure(&kind, false, ErrorReport::usage(super::hub::ENDING)));
    }
    let result = match motionlink_link::result::each_key_once(text.as_bytes()) {
        // Which of two types is meant is not known: such a request is answered as "?".
        Err(e) if e.to_string().starts_with("key \"type\"") => {
            let e = ErrorReport::usage(format!("{e}: give each key of a request once"));
            return Some(Message::failure("?", false, e));
        }
        Err(e) => Err(ErrorReport::usage(format!("{e}: give each key of a request once"))),
        Ok(()) => handle_request(hub, page, &kind, &req, replies),
    };
    match result {
        Ok(answer) => answer,
        Err(e) => Some(Message::failure(&kind, false, refused(hub, page, &kind, e))),
    }
}

/// The refusal `e` of a request of `kind`: a request that stops (Stop, the release of a jog) still stops
/// what it can without the rest of it (the console's motion under way, the page's jog), and says so; what it
/// named wrongly gets nothing.
fn refused(hub: &Hub, page: u64, kind: &str, e: ErrorReport) -> ErrorReport {
    let also = match kind {
        "stop" => match hub.stop_motion() {
            Some((unit, what)) => format!(
                "; the motion under way ({what} of {} {unit}) is stopped all the same (its motion message reports \
                 the stop)",
                hub.device().naming().unit_key
            ),
            None => "; no motion of the console was under way".into(),
        },
        "jog_release" if hub.release_jog(page) => "; this page's jog is released all the same".into(),
        "jog_hold" => "; the jog is not renewed".into(),
        _ => return e,
    };
    ErrorReport { message: format!("{}{also}", e.message), ..e }
}

fn spawn_reply(
    replies: &mpsc::Sender<Message>,
    request: &str,
    work: impl std::future::Future<Output = Result<Message, ErrorReport>> + Send + 'static,
) {
    let replies = replies.clone();
    let request = request.to_string();
    tokio::spawn(async move {
        // A usage error is found before anything reaches the device: the request was not made (refused).
        let answer = work.await.unwrap_or_else(|e| {
            let made = e.kind != motionlink_link::error::ErrorClass::Usage.name();
            Message::failure(&request, made, e)
        });
        let _ = replies.send(answer).await;
    });
}

fn handle_request(
    hub: &Arc<Hub>,
    page: u64,
    kind: &str,
    req: &Value,
    replies: &mpsc::Sender<Message>,
) -> Result<Option<Message>, ErrorReport> {
    if !req.is_object() {
        return Err(ErrorReport::usage(format!("a request is a JSON object with its \"type\", not {req}")));
    }
    let key = hub.device().naming().unit_key;
    let a = format!("a {kind} request");
    match kind {
        "jog_hold" => {
            takes_only(req, &a, &[])?;
            // Renewals are frequent and need no answer; a jog that ended is said by its notice.
            hub.renew_jog(page);
            Ok(None)
        }
        "jog_release" => {
            takes_only(req, &a, &[])?;
            hub.release_jog(page);
            Ok(None)
        }
        "stop" => {
            takes_only(req, &a, &[key])?;
            // No unit: the console's motion and what it set in motion. A unit: one the console found (one it
            // did not find cannot have been set in motion by it).
            let unit = match req.get(key) {
                None | Some(Value::Null) => None,
                Some(_) => Some(found_unit(hub, unit_of(hub, req)?)?.id),
            };
            let hub2 = Arc::clone(hub);
            spawn_reply(replies, kind, async move { hub2.stop(unit).await });
            Ok(None)
        }
        "take_control" => {
            takes_only(req, &a, &[])?;
            if hub.take_control(page) {
                Ok(None)
            } else {
                Err(ErrorReport::usage("another page controls the console"))
            }
        }
        "move" => {
            let unit = unit_of(hub, req)?;
            let u = found_unit(hub, unit)?;
            // The keys of this unit's move (its target's and its speed's name with their units).
            takes_only(req, &format!("a move of {key} {unit}"), &[key, u.target_key, u.command_speed_key])?;
            let target = number(req, u.target_key)?
                .ok_or_else(|| ErrorReport::usage(format!("a move needs {}", u.target_key)))?;
            let speed = number(req, u.command_speed_key)?;
            hub.check_control(page)?;
            let device = Arc::clone(hub.device());
            let motion = device.move_to(unit, target, speed)?;
            hub.start_motion(page, unit, "move", false, motion)?;
            Ok(None)
        }
        "jog" => {
            takes_only(req, &a, &[key, "direction", "speed"])?;
            let unit = unit_of(hub, req)?;
            found_unit(hub, unit)?;
            let direction = match req.get("direction") {
                Some(Value::String(s)) if s == "positive" => JogDirection::Positive,
                Some(Value::String(s)) if s == "negative" => JogDirection::Negative,
                Some(other) => {
                    return Err(ErrorReport::usage(format!("direction {other}: give \"positive\" or \"negative\"")))
                }
                None => return Err(ErrorReport::usage("a jog needs its direction: \"positive\" or \"negative\"")),
            };
            let speed = number(req, "speed")?;
            hub.check_control(page)?;
            let device = Arc::clone(hub.device());
            let motion = device.jog(unit, direction, speed)?;
            hub.start_motion(page, unit, "jog", true, motion)?;
            Ok(None)
        }
        "action" => {
            takes_only(req, &a, &[key, "name"])?;
            let unit = unit_of(hub, req)?;
            found_unit(hub, unit)?;
            let actions = hub.device().actions();
            let name = req.get("name").and_then(Value::as_str).unwrap_or("").to_string();
            let action = actions.iter().find(|a| a.name == name).copied().ok_or_else(|| {
                let names = key_list(actions.iter().map(|a| a.name));
                let names = if actions.is_empty() { "none".to_string() } else { names };
                ErrorReport::usage(format!("no action {name:?}: the actions of this device are {names}"))
            })?;
            hub.check_control(page)?;
            let device = Arc::clone(hub.device());
            let work = device.action(unit, &name)?;
            if action.moves {
                hub.start_motion(page, unit, action.name, false, work)?;
            } else {
                let label = action.label;
                spawn_reply(replies, kind, async move {
                    work.await.map(|report| Message::Action { name, label, ok: true, report })
                });
            }
            Ok(None)
        }
        "read_param" | "write_param" => {
            let write = kind == "write_param";
            let takes = [key, "name", "value"];
            takes_only(req, &a, if write { &takes } else { &takes[..2] })?;
            let unit = unit_of(hub, req)?;
            found_unit(hub, unit)?;
            let name = req.get("name").and_then(Value::as_str).unwrap_or("").trim().to_string();
            if name.is_empty() {
                return Err(ErrorReport::usage("give the name or number of the entry"));
            }
            let device = Arc::clone(hub.device());
            let unit_key = Keyed(device.naming().unit_key, unit);
            if write {
                hub.check_control(page)?;
                let value = match req.get("value") {
                    Some(Value::String(s)) => s.clone(),
                    Some(Value::Number(n)) => n.to_string(),
                    _ => return Err(ErrorReport::usage("give the value to write")),
                };
                spawn_reply(replies, kind, async move {
                    let v = device.write_param(unit, name, value).await?;
                    Ok(Message::Param { written: true, unit: unit_key, report: v })
                });
            } else {
                spawn_reply(replies, kind, async move {
                    let v = device.read_param(unit, name).await?;
                    Ok(Message::Param { written: false, unit: unit_key, report: v })
                });
            }
            Ok(None)
        }
        "errors" => {
            takes_only(req, &a, &[key])?;
            let unit = unit_of(hub, req)?;
            found_unit(hub, unit)?;
            let device = Arc::clone(hub.device());
            let unit_key = Keyed(device.naming().unit_key, unit);
            let work = device.errors(unit);
            spawn_reply(replies, kind, async move { Ok(Message::Errors { unit: unit_key, report: work.await? }) });
            Ok(None)
        }
        "" => Err(ErrorReport::usage(format!("the request names no \"type\": give one of {}", key_list(REQUESTS)))),
        other => Err(ErrorReport::usage(format!("unknown request {other:?}: give one of {}", key_list(REQUESTS)))),
    }
}
