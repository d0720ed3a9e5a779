// motionlink console: the page. Plain JavaScript, no build step. The server keeps every safety rule
// (who controls, the jog's dead-man deadline, the stop of a lost page); this page only asks.
"use strict";

const token = new URLSearchParams(location.search).get("token") || "";
const $ = (id) => document.getElementById(id);
const PLOT_SECONDS = 30;

let ws = null;
let info = null;          // the welcome message
let units = [];           // the units found
let selected = null;      // the selected unit's number
let role = "read_only";
let history = new Map();  // unit number -> [{t, p, v, c}]
let frames = [];          // arrival times of the last samples, for the rate shown
let jogTimer = null;
let jogButton = null;

function send(msg) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(msg));
}

function unitOf(n) { return units.find((u) => u[info.unit_key] === n); }

function withUnit(msg) {
  msg[info.unit_key] = selected;
  return msg;
}

function fmt(x, digits) {
  if (x === undefined || x === null) return "—";
  return Number(x).toFixed(digits);
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  ws = new WebSocket(`${scheme}//${location.host}/ws?token=${encodeURIComponent(token)}`);
  ws.onopen = () => { $("link-state").textContent = "connected"; };
  ws.onclose = () => {
    $("link-state").textContent =
      "disconnected: the console stops any motion this page started when it loses the page (reload to reconnect)";
    stopJogTimer();
    document.body.dataset.connected = "false";
  };
  ws.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    const handler = handlers[msg.type];
    if (handler) handler(msg);
  };
}

const handlers = {
  welcome(msg) {
    info = msg;
    $("device-name").textContent = `— ${msg.family} on ${msg.port}`;
    document.body.dataset.connected = "true";
    handlers.role(msg.role);
    const tbody = $("params").tBodies[0];
    tbody.replaceChildren();
    for (const p of msg.params) {
      const tr = document.createElement("tr");
      tr.dataset.name = p.name;
      for (const text of [p.name, p.id, p.unit, p.access, p.title]) {
        const td = document.createElement("td");
        td.textContent = text;
        tr.append(td);
      }
      const value = document.createElement("td");
      value.className = "value";
      const button = document.createElement("button");
      button.type = "button";
      button.textContent = "Read";
      button.setAttribute("aria-label", `Read ${p.name}`);
      button.onclick = () => { $("param-name").value = p.name; readParam(); };
      const cell = document.createElement("td");
      cell.append(button);
      tr.append(value, cell);
      tbody.append(tr);
    }
    const actions = $("actions");
    actions.replaceChildren();
    for (const a of msg.actions) {
      const b = document.createElement("button");
      b.type = "button";
      b.id = `action-${a.name}`;
      b.textContent = a.label;
      b.onclick = () => send(withUnit({ type: "action", name: a.name }));
      actions.append(b);
    }
  },
  role(msg) {
    role = msg.role;
    const p = $("role");
    p.textContent = msg.message;
    p.className = msg.role;
    document.body.dataset.role = msg.role;
    $("take-control").hidden = !(msg.role === "read_only" && msg.control_free);
    for (const el of document.querySelectorAll("#move, .jog, #param-write, #actions button")) {
      el.disabled = msg.role !== "control";
    }
  },
  units(msg) {
    units = msg.units;
    const tbody = $("units").tBodies[0];
    tbody.replaceChildren();
    if (msg.scanning) {
      const tr = tbody.insertRow();
      const td = tr.insertCell();
      td.colSpan = 7;
      td.textContent = msg.error ? `no unit found yet: ${msg.error.message} (trying again)` : "scanning…";
      return;
    }
    if (!units.some((u) => u[info.unit_key] === selected)) selected = units.length ? units[0][info.unit_key] : null;
    for (const u of units) {
      const n = u[info.unit_key];
      const tr = tbody.insertRow();
      tr.id = `unit-${n}`;
      const pick = document.createElement("input");
      pick.type = "radio";
      pick.name = "unit";
      pick.id = `pick-${n}`;
      pick.checked = n === selected;
      pick.setAttribute("aria-label", `Select ${u.label}`);
      pick.onchange = () => { selected = n; showUnit(); };
      tr.insertCell().append(pick);
      const name = tr.insertCell();
      name.innerHTML = "";
      const label = document.createElement("label");
      label.htmlFor = pick.id;
      label.textContent = u.label;
      label.title = u.detail;
      name.append(label);
      for (const cls of ["position", "speed", "current", "moving", "flags"]) {
        const td = tr.insertCell();
        td.className = cls + (cls === "flags" || cls === "moving" ? "" : " num");
        td.textContent = "—";
      }
    }
    showUnit();
  },
  sample(msg) {
    const now = performance.now();
    frames.push(now);
    while (frames.length && now - frames[0] > 2000) frames.shift();
    for (const s of msg.units) {
      const n = s[info.unit_key];
      const u = unitOf(n);
      const tr = $(`unit-${n}`);
      if (!u || !tr) continue;
      if (s.error) {
        tr.querySelector(".flags").textContent = `no answer: ${s.error.message}`;
        continue;
      }
      const p = s[u.position_key];
      const v = s[u.speed_key];
      const c = s.current_amps;
      tr.querySelector(".position").textContent = `${fmt(p, 3)} ${u.position_unit}`;
      tr.querySelector(".speed").textContent = v === undefined ? "—" : `${fmt(v, 3)} ${u.speed_unit}`;
      tr.querySelector(".current").textContent = c === undefined ? "—" : `${fmt(c, 2)} A`;
      tr.querySelector(".moving").textContent = s.moving ? "moving" : "at rest";
      const flags = tr.querySelector(".flags");
      flags.textContent = s.flags.join(" ") + (s.unknown_bits ? ` unknown bits 0x${s.unknown_bits.toString(16)}` : "");
      flags.classList.toggle("fault", s.faults.length > 0);
      if (s.faults.length) flags.textContent += ` — FAULT: ${s.faults.join(", ")}`;
      let h = history.get(n);
      if (!h) history.set(n, (h = []));
      h.push({ t: msg.t_s, p, v, c });
      while (h.length && msg.t_s - h[0].t > PLOT_SECONDS) h.shift();
    }
    $("rate").textContent = `${(frames.length / 2).toFixed(0)} samples/s`;
  },
  traffic(msg) {
    if ($("traffic-pause").checked) return;
    const box = $("traffic");
    const atEnd = box.scrollTop + box.clientHeight >= box.scrollHeight - 4;
    for (const l of msg.lines) {
      const line = document.createElement("div");
      line.textContent = `${l.t_s.toFixed(3)} ${l.direction === "to_device" ? "→" : "←"} ${l.hex}  ${l.meaning}`;
      if (l.bad) line.className = "bad";
      box.append(line);
    }
    while (box.childElementCount > 1000) box.firstElementChild.remove();
    if (atEnd) box.scrollTop = box.scrollHeight;
  },
  motion(msg) {
    const p = $("motion");
    const who = `${info.unit_key} ${msg[info.unit_key]}`;
    p.dataset.state = msg.state;
    p.className = msg.ok === false ? "failed" : "";
    if (msg.state === "running") p.textContent = `${msg.what} of ${who} running`;
    else p.textContent = reported(msg.message || `${msg.what} of ${who} ${msg.state}`, msg.report);
    if (msg.state !== "running" && jogButton) stopJogTimer();
  },
  stopped(msg) { status(reported(msg.message, msg.report), !msg.ok); },
  action(msg) { status(reported(msg.label, msg.report), !msg.ok); },
  refused(msg) { status(`refused (${msg.request}): ${msg.message}`, true); },
  failed(msg) {
    if (msg.request === "read_param" || msg.request === "write_param") {
      $("param-result").textContent = `${msg.request === "write_param" ? "write" : "read"} failed: ${msg.message}`;
    }
    status(`${msg.request} failed (${msg.error.kind}): ${msg.message}`, true);
  },
  // A report is the object `motionlink <family> ... --json` prints: shown field by field, as it is.
  param(msg) {
    const r = msg.report;
    // The report's unit, else the one the parameter list gives (a write's report names none); where that
    // list gives a rotary and a linear unit ("rad|m/s"), the one of the selected module's kind.
    const listed = (info.params || []).find((p) => p.name === r.name);
    const kind = (unitOf(selected) || {}).position_unit;
    let u = r.unit || (listed && listed.unit) || "";
    if (kind === "rad" || kind === "m") u = u.replace("rad|m", kind);
    const unit = u ? ` ${u}` : "";
    let text = `${r.name} (${r.id}) ${msg.written ? "written" : "="} ${show(r.value)}${unit}`;
    if (msg.written) {
      text += r.read_back === null || r.read_back === undefined
        ? `; not read back: ${(r.not_verifiable || []).join("; ")}`
        : `, read back ${show(r.read_back)}${unit}`;
    }
    const out = $("param-result");
    out.textContent = text;
    out.title = fields(r);
    out.dataset.readBack = r.read_back === null || r.read_back === undefined ? "" : show(r.read_back);
    const row = document.querySelector(`#params tr[data-name="${CSS.escape(r.name)}"] .value`);
    if (row) row.textContent = `${show(r.value)}${unit}`;
  },
  // One row per entry of the report's `errors` (a history), else one row for the report (a state word).
  errors(msg) {
    const r = msg.report;
    const tbody = $("errors").tBodies[0];
    tbody.replaceChildren();
    const history = Array.isArray(r.errors);
    $("errors-caption").textContent = history ? "the error history, newest first" : "no error history: the state now";
    (history ? r.errors : [r]).forEach((e, i) => {
      const tr = tbody.insertRow();
      tr.insertCell().textContent = !history ? "now" : i === 0 ? "newest" : String(i + 1);
      const code = e.code !== undefined ? e.code : e.word;
      tr.insertCell().textContent = e.text !== undefined ? e.text : `0x${code.toString(16).padStart(8, "0")}`;
      const rest = Object.fromEntries(Object.entries(e).filter(([k]) => !["code", "text", "word"].includes(k)));
      const clean = code === 0 && (!e.bits || e.bits.length === 0);
      tr.insertCell().textContent = e.meaning !== undefined ? e.meaning : clean ? "no error" : fields(rest);
    });
  },
  bye(msg) { $("link-state").textContent = msg.message; },
};

// A value of a report as text: a number to the digits it has, a list joined, an object field by field.
function show(v) {
  if (Array.isArray(v)) return v.map(show).join(", ");
  if (v !== null && typeof v === "object") return `{${fields(v)}}`;
  // A device's single-precision float (0.800000011920929) to the 7 digits it has (0.8).
  if (typeof v === "number" && !Number.isInteger(v)) return String(Number(v.toPrecision(7)));
  return String(v);
}

// The fields of a report, `name: value` each (the identity fields the page knows left out).
function fields(r) {
  const known = ["family", "port", "profile"];
  return Object.entries(r).filter(([k, v]) => !known.includes(k) && !(Array.isArray(v) && v.length === 0))
    .map(([k, v]) => `${k}: ${show(v)}`).join("; ");
}

// `text`, then the library's report (of a motion, a stop, an action) field by field.
function reported(text, r) {
  if (!r) return text;
  // A COMPAX drive switched off by its stop (O0 = 0) takes no move until it is switched on again.
  const off = r.o0 === 0 ? "; switch the drive on before the next move" : "";
  return `${text} — ${fields(r)}${off}`;
}

function status(text, bad) {
  const p = $("motion");
  p.textContent = text;
  p.className = bad ? "failed" : "";
}

// The unit as the panels that act on it name it: "module 2", "drive 1", "actuator A1".
function unitName(u) {
  return u.label.startsWith(info.unit_key) ? u.label : `${info.unit_key} ${u.label}`;
}

function showUnit() {
  const u = unitOf(selected);
  const name = u ? unitName(u) : "no unit selected";
  for (const id of ["control-unit", "params-unit", "errors-unit"]) $(id).textContent = name;
  $("move-form").dataset.unit = u ? String(selected) : "";
  if (!u) return;
  $("target-unit").textContent = u.position_unit;
  // What an empty speed does is the unit's: the server says it for its family (an SCU move: 100 %).
  $("speed-unit").textContent = u.command_speed_unit;
  $("move-speed-empty").textContent = u.move_speed_when_empty;
  $("jog-speed-unit").textContent = u.command_speed_unit;
  $("jog-speed-empty").textContent = u.jog_speed_when_empty;
  $("move").textContent = `Move ${name} to target`;
}

// Stop: always there, and Escape anywhere on the page. A read-only page may stop too.
function stop() {
  stopJogTimer();
  const msg = { type: "stop" };
  if (selected !== null && info) msg[info.unit_key] = selected;
  send(msg);
}

// The number in input `id`: { value } (null when the field is empty), or { error } saying why it is
// refused. Text a number input cannot read (`1e`) makes its `value` "" as an empty field does: its validity
// tells them apart, so such text is never taken for an empty field.
function number(id, what) {
  const el = $(id);
  if (el.validity.badInput) return { error: `${what}: what is typed is not a number` };
  if (el.value.trim() === "") return { value: null };
  if (!el.validity.valid || !Number.isFinite(el.valueAsNumber)) {
    return { error: `${what}: ${el.value} is not taken (${el.validationMessage || "not a number"})` };
  }
  return { value: el.valueAsNumber };
}

// A request refused here, before anything is sent.
function refusedHere(request, why) {
  status(`refused (${request}): ${why}; nothing was sent`, true);
}

function move(ev) {
  ev.preventDefault();
  const u = unitOf(selected);
  if (!u) return;
  const target = number("target", "target");
  const speed = number("move-speed", "speed");
  const bad = target.error || speed.error || (target.value === null ? "target: give the target" : null);
  if (bad) { refusedHere("move", bad); return; }
  const msg = withUnit({ type: "move" });
  msg[u.target_key] = target.value;
  if (speed.value !== null) msg[u.command_speed_key] = speed.value;
  send(msg);
}

// Jog: runs only while held. The page renews it every 50 ms; the server stops it when the renewals stop
// for its dead-man time (200 ms), when the button is let go, and when this page goes away.
function startJog(button, direction) {
  if (role !== "control" || jogButton || selected === null) return;
  const speed = number("jog-speed", "jog speed");
  if (speed.error) { refusedHere("jog", speed.error); return; }
  jogButton = button;
  button.classList.add("held");
  const msg = withUnit({ type: "jog", direction });
  if (speed.value !== null) msg.speed = speed.value;
  send(msg);
  jogTimer = setInterval(() => send({ type: "jog_hold" }), 50);
}

function stopJogTimer() {
  if (jogTimer !== null) clearInterval(jogTimer);
  jogTimer = null;
  if (jogButton) jogButton.classList.remove("held");
  jogButton = null;
}

function releaseJog() {
  if (!jogButton) return;
  stopJogTimer();
  send({ type: "jog_release" });
}

function bindJog(button, direction) {
  button.addEventListener("pointerdown", (e) => { button.setPointerCapture(e.pointerId); startJog(button, direction); });
  for (const ev of ["pointerup", "pointercancel", "lostpointercapture"]) button.addEventListener(ev, releaseJog);
  button.addEventListener("keydown", (e) => {
    if ((e.key === " " || e.key === "Enter") && !e.repeat) { e.preventDefault(); startJog(button, direction); }
  });
  button.addEventListener("keyup", (e) => { if (e.key === " " || e.key === "Enter") releaseJog(); });
  button.addEventListener("blur", releaseJog);
}

function readParam() {
  if (selected === null) return;
  send(withUnit({ type: "read_param", name: $("param-name").value }));
}

function writeParam() {
  if (selected === null) return;
  send(withUnit({ type: "write_param", name: $("param-name").value, value: $("param-value").value }));
}

// The plot: position, speed and (where reported) current of the selected unit, each in its own band.
function draw() {
  const canvas = $("plot");
  const g = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  g.clearRect(0, 0, W, H);
  const u = unitOf(selected);
  const h = u ? history.get(selected) || [] : [];
  const bands = u ? [
    { key: "p", name: `position (${u.position_unit})`, color: "#1f5fa8" },
    { key: "v", name: `speed (${u.speed_unit})`, color: "#2d8a3e" },
  ] : [];
  if (u && u.current_key) bands.push({ key: "c", name: "current (A)", color: "#b5540b" });
  const left = 70, right = W - 10;
  const tEnd = h.length ? h[h.length - 1].t : 0;
  const bandH = bands.length ? H / bands.length : H;
  g.font = "12px sans-serif";
  bands.forEach((b, i) => {
    const top = i * bandH + 16, bottom = (i + 1) * bandH - 6;
    const vals = h.map((s) => s[b.key]).filter((x) => x !== undefined && x !== null);
    let lo = Math.min(...vals), hi = Math.max(...vals);
    if (!vals.length) { lo = 0; hi = 1; }
    if (hi - lo < 1e-9) { lo -= 1; hi += 1; }
    const y = (x) => bottom - ((x - lo) / (hi - lo)) * (bottom - top);
    const x = (t) => right - ((tEnd - t) / PLOT_SECONDS) * (right - left);
    g.strokeStyle = "#ddd";
    g.strokeRect(left, top, right - left, bottom - top);
    g.fillStyle = "#333";
    g.fillText(b.name, left + 4, top - 3);
    g.fillText(hi.toPrecision(5), 2, top + 10);
    g.fillText(lo.toPrecision(5), 2, bottom);
    g.strokeStyle = b.color;
    g.lineWidth = 1.5;
    g.beginPath();
    let first = true;
    for (const s of h) {
      const v = s[b.key];
      if (v === undefined || v === null) { first = true; continue; }
      if (first) g.moveTo(x(s.t), y(v)); else g.lineTo(x(s.t), y(v));
      first = false;
    }
    g.stroke();
  });
  if (bands.length) {
    g.fillStyle = "#666";
    g.fillText(`−${PLOT_SECONDS} s`, left, H - 2);
    g.fillText("now", right - 24, H - 2);
  }
  requestAnimationFrame(draw);
}

document.addEventListener("DOMContentLoaded", () => {
  $("stop").addEventListener("click", stop);
  document.addEventListener("keydown", (e) => { if (e.key === "Escape") { e.preventDefault(); stop(); } });
  $("take-control").addEventListener("click", () => send({ type: "take_control" }));
  $("move-form").addEventListener("submit", move);
  bindJog($("jog-negative"), "negative");
  bindJog($("jog-positive"), "positive");
  $("param-read").addEventListener("click", readParam);
  $("param-write").addEventListener("click", writeParam);
  $("param-form").addEventListener("submit", (e) => { e.preventDefault(); readParam(); });
  $("errors-read").addEventListener("click", () => { if (selected !== null) send(withUnit({ type: "errors" })); });
  window.addEventListener("blur", releaseJog);
  connect();
  requestAnimationFrame(draw);
});
