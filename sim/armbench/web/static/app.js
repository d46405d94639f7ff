// armbench live view: state over a WebSocket, the arm drawn with a small perspective
// projection on a 2-D canvas (no third-party code), commands built from the server's table,
// the program's located variables in a table. trace.js adds the trace panel.
"use strict";

const $ = (id) => document.getElementById(id);
const fmt = (v, d = 2) => (v === null || v === undefined) ? "-" :
  (typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toFixed(d)) : String(v));
// a variable's value: whole numbers as they are, others to 7 significant digits (a REAL's)
const num = (v) => (v === null || v === undefined) ? "-" : typeof v === "boolean" ? (v ? "TRUE" : "FALSE") :
  Number.isInteger(v) ? String(v) : String(Number(v.toPrecision(7)));
const esc = (s) => String(s).replace(/[&<>"']/g, (c) => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", "\"": "&quot;", "'": "&#39;"}[c]));

// What the tests and the bench read: frames drawn, messages received, the last drawn pose.
const armbench = window.armbench = {
  messages: 0, frames: 0, busyMs: 0, drawn: null, state: null, lastResult: null, history: [],
  info: null, trace: null,
};

// ---- views (tabs of the page) ------------------------------------------------------------
function showView(name) {
  const buttons = [...document.querySelectorAll("#views button")].filter((b) => !b.hidden);
  if (!buttons.some((b) => b.dataset.view === name)) name = buttons[0].dataset.view;
  for (const b of buttons) b.setAttribute("aria-selected", String(b.dataset.view === name));
  for (const v of document.querySelectorAll(".view")) v.hidden = v.id !== "view-" + name;
  if (location.hash !== "#" + name) history.replaceState(null, "", "#" + name);
  if (name === "variables") renderRegisters();
}
for (const b of document.querySelectorAll("#views button")) {
  b.addEventListener("click", () => showView(b.dataset.view));
}
const isController = () => armbench.info && armbench.info.mode === "controller";

// ---- camera and projection -------------------------------------------------------------
const cam = { yaw: -0.9, pitch: 0.42, dist: 900, scale: 1.0, target: [90, 0, 110] };
const canvas = $("arm");
const ctx = canvas.getContext("2d");

function project(p) {
  const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw);
  const cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
  const d = [cp * cy, cp * sy, sp];           // from the target towards the camera
  const r = [-sy, cy, 0];                      // screen right
  const u = [-sp * cy, -sp * sy, cp];          // screen up = r x (-d)
  const q = [p[0] - cam.target[0], p[1] - cam.target[1], p[2] - cam.target[2]];
  const xc = q[0] * r[0] + q[1] * r[1];
  const yc = q[0] * u[0] + q[1] * u[1] + q[2] * u[2];
  const zc = q[0] * d[0] + q[1] * d[1] + q[2] * d[2];
  const f = cam.dist / Math.max(cam.dist - zc, 1) * 1.35 * cam.scale;
  return [canvas.width / 2 + xc * f, canvas.height * 0.58 - yc * f];
}

function line(a, b, style, width, dash) {
  const p = project(a), q = project(b);
  ctx.strokeStyle = style; ctx.lineWidth = width; ctx.setLineDash(dash || []);
  ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
}

function armPolyline(points) {
  // foot, top of the base column, shoulder, elbow, tool
  return [points[0], [0, 0, points[1][2]], points[1], points[2], points[3]];
}

function drawArm(points, style, width, dash) {
  const pl = armPolyline(points);
  for (let i = 0; i + 1 < pl.length; i++) line(pl[i], pl[i + 1], style, width, dash);
  ctx.setLineDash([]);
  ctx.fillStyle = style;
  for (const p of pl.slice(2)) {
    const s = project(p);
    ctx.beginPath(); ctx.arc(s[0], s[1], width * 0.8, 0, 2 * Math.PI); ctx.fill();
  }
}

function cross(p, style) {
  const s = project(p);
  ctx.strokeStyle = style; ctx.lineWidth = 2; ctx.setLineDash([]);
  ctx.beginPath();
  ctx.moveTo(s[0] - 7, s[1] - 7); ctx.lineTo(s[0] + 7, s[1] + 7);
  ctx.moveTo(s[0] - 7, s[1] + 7); ctx.lineTo(s[0] + 7, s[1] - 7);
  ctx.stroke();
}

const trail = [];

function draw(state) {
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  for (let k = -200; k <= 400; k += 50) {      // floor grid, mm
    line([k, -300, 0], [k, 300, 0], "#e3e7ec", 1);
  }
  for (let k = -300; k <= 300; k += 50) line([-200, k, 0], [400, k, 0], "#e3e7ec", 1);
  line([0, 0, 0], [100, 0, 0], "#d32f2f", 2);
  line([0, 0, 0], [0, 100, 0], "#388e3c", 2);
  line([0, 0, 0], [0, 0, 100], "#1565c0", 2);
  const pts = state.points || {};
  if (pts.plant) {
    const tool = pts.plant[3];
    const last = trail[trail.length - 1];
    if (!last || Math.hypot(tool[0] - last[0], tool[1] - last[1], tool[2] - last[2]) > 0.5) {
      trail.push(tool); if (trail.length > 400) trail.shift();
    }
    if (trail.length > 1) {                    // one path: 400 strokes would cost a frame
      ctx.strokeStyle = "#9fb8d0"; ctx.lineWidth = 1; ctx.setLineDash([]);
      ctx.beginPath();
      trail.forEach((p, i) => { const q = project(p); if (i) ctx.lineTo(q[0], q[1]); else ctx.moveTo(q[0], q[1]); });
      ctx.stroke();
    }
    drawArm(pts.plant, "#2f5d8a", 7);
  }
  if (pts.setpoint) drawArm(pts.setpoint, "#8e44ad", 1.2);
  if (pts.plc) {
    drawArm(pts.plc, "#e8710a", 2.5, [7, 5]);
    if (pts.tool) {                            // the 5-axis wrist: flange and 60 mm tool
      line(pts.plc[3], pts.tool[0], "#f0a060", 1.5);
      line(pts.tool[0], pts.tool[1], "#f0a060", 1.5);
      const tip = project(pts.tool[1]);
      ctx.fillStyle = "#f0a060"; ctx.beginPath(); ctx.arc(tip[0], tip[1], 2.5, 0, 2 * Math.PI); ctx.fill();
    }
  }
  const tool = state.tool || {};
  if (tool.cartesian) cross(tool.cartesian, "#2e7d32");
  const j = state.joints || {};
  ctx.fillStyle = "#1d232b"; ctx.font = "12px system-ui";
  ctx.fillText("output " + (j.plc || []).map((a) => fmt(a, 1)).join("  ") + " deg", 10, 18);
  ctx.fillText("plant  " + (j.plant || []).map((a) => fmt(a, 1)).join("  ") + " deg", 10, 34);
  canvas.dataset.plcJoints = (j.plc || []).join(",");
  canvas.dataset.plantJoints = (j.plant || []).join(",");
  canvas.dataset.setpointJoints = (j.setpoint || []).join(",");
  canvas.dataset.tool = (tool.output || []).join(",");
  canvas.dataset.seq = state.seq;
  armbench.frames += 1;
  // `at` and the snapshot's `t` (when the server read the PLC) are epoch ms / s
  armbench.drawn = { seq: state.seq, plc: j.plc, plant: j.plant, target: j.target, t: state.t,
                     at: performance.timeOrigin + performance.now() };
  armbench.history.push(armbench.drawn);
  if (armbench.history.length > 256) armbench.history.shift();
}

// Each snapshot is drawn when it arrives (the page's update rate is the server's); camera
// moves redraw at most once per display frame.
let pending = null;
function frame() {
  if (pending) { draw(pending); pending = null; }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);

let drag = null;
canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", (e) => {
  if (!drag) return;
  cam.yaw -= (e.clientX - drag[0]) * 0.01;
  cam.pitch = Math.max(-0.2, Math.min(1.5, cam.pitch + (e.clientY - drag[1]) * 0.01));
  drag = [e.clientX, e.clientY];
  if (armbench.state) pending = armbench.state;
});
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  cam.scale = Math.max(0.3, Math.min(4, cam.scale * (e.deltaY < 0 ? 1.1 : 1 / 1.1)));
  if (armbench.state) pending = armbench.state;
}, { passive: false });

// ---- header, banner and tables -------------------------------------------------------------
function kv(id, rows) {
  $(id).tBodies[0].innerHTML = rows.map(([k, v]) => `<tr><td>${esc(k)}</td><td>${v}</td></tr>`).join("");
}

function badge(text, cls) { return `<span class="badge ${cls}">${esc(text)}</span>`; }

const recvTimes = [];
function update(s) {
  armbench.state = s;
  const now = performance.now();
  recvTimes.push(now);
  while (recvTimes.length && recvTimes[0] < now - 1000) recvTimes.shift();
  $("pagehz").textContent = recvTimes.length;
  const conn = $("conn");
  conn.textContent = s.connected ? "connected" : (s.error || "not connected");
  conn.className = "badge " + (s.connected ? "ok" : "bad");
  updateFaults(s);
  if (!s.connected) return;
  const t0 = performance.now();
  if (s.mode === "controller" && !s.waiting) {
    draw(s);
    updateJoints(s);
  }
  // The tables below change the layout; at 10 Hz they cost the drawing no frames.
  if (now - lastTables >= 100) { lastTables = now; updateTables(s); }
  armbench.busyMs += performance.now() - t0;
}

let lastTables = -1e9;
let shownEvent = -1;

// The banner: the last command's answer (this page's, or any page's when newer) and what is
// wrong now. It sits in the sticky header, so it is in view wherever the page is scrolled.
let ownResult = null;   // {at: epoch ms, ok, message}
function showLastCommand(s) {
  const server = s && s.last_command ? { at: s.last_command.t * 1000, ok: s.last_command.ok,
                                          message: s.last_command.message } : null;
  const r = ownResult && (!server || ownResult.at >= server.at) ? ownResult : server;
  if (!r) return;
  const el = $("lastcmd");
  const text = `${new Date(r.at).toLocaleTimeString()} ${r.message}`;
  if (el.textContent !== text) el.textContent = text;
  el.className = r.pending ? "pending" : r.ok ? "done" : "error";
}

function updateFaults(s) {
  const faults = [];
  if (!s.connected) faults.push(s.error || "not connected to the PLC");
  if (s.waiting) faults.push(s.waiting);
  if (s.plc && s.plc.fault) faults.push("PLC fault at " + s.plc.fault);
  for (const f of s.faults || []) if (!faults.includes(f)) faults.push(f);
  const html = faults.map((f) => `<span class="fault">${esc(f)}</span>`).join("");
  const el = $("faults");
  if (el.innerHTML !== html) el.innerHTML = html;
  showLastCommand(s);
}

function updateHeader(s) {
  $("plcaddr").textContent = s.plc_address;
  $("progname").textContent = s.program || "";
  const plc = s.plc;
  const st = $("plcstate");
  st.textContent = plc.state || "n/a";
  st.className = "badge " + (plc.state === "RUNNING" ? "ok" : plc.state ? "bad" : "warn");
  if (s.mode !== "controller" || s.waiting) return;
  $("scancount").textContent = s.scan_count;
  $("scanhz").textContent = fmt(s.scan_hz, 1);
  const c = s.controller;
  const cs = $("ctlstate");
  cs.textContent = c.state + (c.busy_mailbox ? ` (mailbox ${c.busy_mailbox})` : "");
  cs.className = "badge " + (c.state === "Ready" ? "ok" : "warn");
  const m = s.motion, ms = $("motionstate");
  const what = m.kind ? m.kind_name : "none";
  ms.textContent = !m.kind ? "none" : m.busy ? `${what} ${fmt(100 * (m.progress || 0), 0)}%` :
    m.error ? `${what} error ${m.error_id} ${m.error_name}` : m.aborted ? `${what} aborted` : `${what} done`;
  ms.className = "badge " + (m.error ? "bad" : m.busy ? "warn" : "ok");
}

const JOINT_ROWS = ["Base", "Shoulder", "Elbow"];
function updateJoints(s) {
  const jt = s.joints, ch = s.channels, w = s.wrist;
  const rows = JOINT_ROWS.map((name, i) =>
    `<tr><td class="l">${name}</td><td>${fmt(jt.target[i])}</td><td>${fmt(jt.setpoint[i])}</td>` +
    `<td class="out">${fmt(jt.plc[i])}</td><td>${fmt(jt.plant[i])}</td>` +
    `<td>${fmt(ch[i].plc_pulse_us, 1)}</td><td>${ch[i].full_off ? "off" : ch[i].count}</td>` +
    `<td>${fmt(ch[i].plant_pulse_us, 1)}</td><td>${fmt(ch[i].servo_deg)}</td></tr>`);
  ["WristPitch", "WristRoll"].forEach((name, i) => rows.push(
    `<tr><td class="l">${name}</td><td>-</td><td>${fmt(w.setpoint[i])}</td><td class="out">${fmt(w.output[i])}</td>` +
    `<td>-</td><td>${fmt(w.pulse_us[i], 1)}</td><td>${ch[3 + i].full_off ? "off" : ch[3 + i].count}</td><td>-</td><td>-</td></tr>`));
  rows.push(`<tr><td class="l">Gripper</td><td>${fmt(w.gripper_pct, 1)} %</td><td>-</td><td class="out">${fmt(w.gripper_deg)}</td>` +
    `<td>-</td><td>${fmt(w.gripper_pulse_us, 1)}</td><td>${ch[5].full_off ? "off" : ch[5].count}</td><td>-</td><td>-</td></tr>`);
  $("joints").tBodies[0].innerHTML = rows.join("");
  const t = s.tool;
  const xyz = (p) => p ? p.map((v) => `<td>${fmt(v)}</td>`).join("") : "<td>-</td><td>-</td><td>-</td>";
  $("tool").tBodies[0].innerHTML = [
    ["output stage: reference FK of OutBaseDeg..", t.output, "out"],
    ["motion setpoint: reference FK of SetBaseDeg..", t.setpoint, ""],
    ["Cartesian setpoint (CartX..Z, while a Cartesian motion runs)", t.cartesian, ""],
    ["plant: reference FK of the servo models", t.plant, ""],
    ["PLC's FK echo of the last joint-move target (EchoX..Z)", t.echo, ""],
  ].map(([k, p, cls]) => `<tr class="${cls}"><td class="l">${esc(k)}</td>${xyz(p)}</tr>`).join("");
}

function updateTables(s) {
  updateHeader(s);
  kv("plc", plcRows(s));
  updateEvents(s);
  if (s.mode !== "controller" || s.waiting) return;
  const ch = s.channels, c = s.controller, m = s.motion;
  $("channels").tBodies[0].innerHTML = ch.map((r) =>
    `<tr><td>${r.channel}</td><td class="l">${esc(r.joint)}</td><td>0x${r.word.toString(16).padStart(4, "0")}</td>` +
    `<td>${r.count}</td><td>${r.full_off ? "yes" : ""}</td></tr>`).join("");
  $("mailboxes").tBodies[0].innerHTML = s.mailboxes.map((mb) => {
    const cls = (mb.pending ? "pending " : "") + (mb.result ? "rejected " : "") + (mb.owner ? "owned" : "");
    const state = !mb.session ? "empty" : mb.pending ? "waiting" : mb.owner ? "answered" : "free";
    return `<tr class="${cls}"><td>${mb.mailbox}</td><td>${mb.session}</td><td>${mb.seq}</td>` +
      `<td class="l">${mb.code} ${esc(mb.command)}</td><td>${mb.int1}</td><td>${mb.int2}</td>` +
      `<td>${mb.args.slice(0, 3).map((a) => fmt(a, 1)).join(" / ")}</td><td>${mb.owner}</td>` +
      `<td>${mb.ack_seq}</td><td class="res l">${mb.result} ${esc(mb.result_name)}</td><td class="l">${state}</td></tr>`;
  }).join("");
  kv("ctl", [["state (CtlState)", esc(c.state)], ["InitPwm mailbox (BusyMailbox)", c.busy_mailbox],
    ["commands answered", c.commands_answered], ["commands ignored", c.commands_ignored],
    ["motion (MotionKind, mailbox, seq)", `${esc(m.kind_name)}, ${m.mailbox}, ${m.seq}; ${m.starts} started`],
    ["motion state", `${m.busy ? "busy" : m.done ? "done" : m.error ? "error " + m.error_id + " " + esc(m.error_name) : m.aborted ? "aborted" : "-"}` +
      `${m.at_limit ? ", at a limit" : ""}${m.slew_limited ? ", slew-limited" : ""}`],
    ["PwmReady / prescale", `${c.pwm_ready ? "yes" : "no"} / ${c.prescale}`],
    ["PwmInitRequest (%QX0.0)", c.PwmInitRequest ? "TRUE" : "FALSE"],
    ["PwmDriverReady / Fault (%IX0.0/0.1)", `${c.PwmDriverReady ? "TRUE" : "FALSE"} / ${c.PwmDriverFault ? "TRUE" : "FALSE"}`],
    ["batch owner / count / failures", `${c.batch_owner} / ${c.batch_count} / ${c.batch_failures}`],
    ["plant PCA9685", s.plant.pca_running ? `running ${fmt(s.plant.update_rate_hz, 2)} Hz` : "not running (send Init PWM)"]]);
}

function plcRows(s) {
  const plc = s.plc;
  const rows = [["address", esc(s.plc_address)], ["program", esc(s.program || "")],
    ["state", plc.state ? badge(plc.state, plc.state === "RUNNING" ? "ok" : "bad") : esc(plc.note)],
    ["fault", plc.fault ? `<b class="fault">${esc(plc.fault)}</b>` : "none"],
    ["view's polls", fmt(s.poll_hz, 1) + " Hz"]];
  if (s.mode === "controller" && !s.waiting) {
    rows.push(["scans (ScanCount)", s.scan_count], ["scan rate (from ScanCount)", fmt(s.scan_hz, 1) + " Hz"]);
  }
  for (const t of plc.tasks) {
    rows.push([`task ${t.name}`, `every ${fmt(t.interval_ms, 3)} ms, ${t.scans} scans, ${t.overruns} overruns`]);
    rows.push([`  execution`, `mean ${fmt(t.exec_mean_us, 1)} us, max ${fmt(t.exec_max_us, 1)} us`]);
    rows.push([`  start jitter`, `p50 ${fmt(t.jitter_p50_us, 1)} us, p99 ${fmt(t.jitter_p99_us, 1)} us, max ${fmt(t.jitter_max_us, 1)} us`]);
  }
  return rows;
}

function updateEvents(s) {
  const events = s.events || [];
  const lastEvent = events.length ? events[events.length - 1].id : 0;
  if (lastEvent === shownEvent) return;
  shownEvent = lastEvent;
  $("events").innerHTML = events.slice().reverse().map((e) =>
    `<li class="${e.kind}">${new Date(e.t * 1000).toLocaleTimeString()} ${esc(e.text)}</li>`).join("");
}

// ---- WebSocket ------------------------------------------------------------------------------
function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.onmessage = (ev) => {
    armbench.messages += 1;
    update(JSON.parse(ev.data));
    ws.send("drawn");  // flow control: the server keeps at most a few snapshots in flight
  };
  ws.onclose = () => {
    const conn = $("conn");
    conn.textContent = "web server gone: reconnecting"; conn.className = "badge bad";
    setTimeout(connect, 1000);
  };
}

// ---- commands --------------------------------------------------------------------------------
function showResult(ok, text, isPending) {
  ownResult = { at: Date.now(), ok, message: text, pending: isPending };
  showLastCommand(armbench.state);
}

async function send(cmd, form) {
  const fields = {};
  for (const f of cmd.fields) fields[f.key] = form.elements[f.key].value;  // checked by the server
  showResult(true, `${cmd.label}: sending...`, true);
  let answer;
  try {
    const r = await fetch("/api/command", { method: "POST", headers: { "Content-Type": "application/json" },
                                            body: JSON.stringify({ name: cmd.name, fields }) });
    answer = await r.json();
  } catch (e) {
    answer = { ok: false, message: `${cmd.label}: the web server did not answer (${e})` };
  }
  armbench.lastResult = answer;
  showResult(answer.ok, answer.message, false);
  const bt = $("batch");
  if (answer.batch && answer.batch.length) {
    bt.hidden = false;
    bt.tBodies[0].innerHTML = answer.batch.map((b, i) =>
      `<tr><td>${i + 1}</td>${b.joints.concat(b.echo).map((v) => `<td>${fmt(v)}</td>`).join("")}` +
      `<td>${b.error_id} ${esc(b.error_id ? b.error_name : "")}</td></tr>`).join("");
  }
}

function fieldHtml(f) {
  const id = `${f.key}`;
  if (f.kind === "choice") {
    return `<label>${esc(f.label)} <select name="${id}">` + f.choices.map(([v, t]) =>
      `<option value="${v}"${v === f.default ? " selected" : ""}>${esc(t)}</option>`).join("") + "</select></label>";
  }
  if (f.kind === "points") {
    return `<label>${esc(f.label)}<br><textarea name="${id}">${esc(f.default)}</textarea></label>`;
  }
  return `<label>${esc(f.label)} <input name="${id}" type="text" inputmode="decimal" value="${esc(f.default)}">` +
    `${f.unit ? " " + esc(f.unit) : ""}</label>`;
}

function showGroup(group) {
  for (const b of $("cmdtabs").children) b.setAttribute("aria-selected", String(b.dataset.group === group));
  for (const f of $("cmdforms").children) f.hidden = f.dataset.group !== group;
}

async function loadCommands() {
  const r = await fetch("/api/commands");
  const { commands, groups: order } = await r.json();
  const groups = [];
  for (const cmd of commands) {
    const form = document.createElement("form");
    form.className = "cmd"; form.dataset.command = cmd.name; form.dataset.group = cmd.group;
    form.innerHTML = `<div class="help"><b>${esc(cmd.label)}</b> (code ${cmd.code}): ${esc(cmd.help)}</div>` +
      cmd.fields.map(fieldHtml).join("") + `<button type="submit" name="send">${esc(cmd.label)}</button>`;
    form.addEventListener("submit", (e) => { e.preventDefault(); send(cmd, form); });
    if (cmd.group === "") { $("cmdalways").appendChild(form); continue; }
    if (!groups.includes(cmd.group)) groups.push(cmd.group);
    $("cmdforms").appendChild(form);
  }
  for (const g of order.filter((x) => groups.includes(x))) {
    const b = document.createElement("button");
    b.type = "button"; b.dataset.group = g; b.textContent = g; b.setAttribute("role", "tab");
    b.addEventListener("click", () => showGroup(g));
    $("cmdtabs").appendChild(b);
  }
  if (groups.length) showGroup(order.find((x) => groups.includes(x)));
}

// ---- located variables ------------------------------------------------------------------------
let registers = [];
function renderRegisters() {
  if ($("view-variables").hidden && registers.length && $("registers").tBodies[0].rows.length) return;
  const q = $("regfilter").value.trim().toLowerCase();
  const rows = registers.filter((r) => !q || [r.name, r.location, r.group, r.description, r.type].some((x) => x.toLowerCase().includes(q)));
  $("registers").tBodies[0].innerHTML = rows.slice(0, 2000).map((r) =>
    `<tr data-name="${esc(r.name)}"><td class="l">${esc(r.name)}</td><td class="l">${esc(r.location)}</td><td>${r.table} ${r.address}</td>` +
    `<td class="l">${esc(r.type)}</td><td class="value">${num(r.value)}</td>` +
    `<td class="l">${esc(r.description)}</td></tr>`).join("");
}
$("regfilter").addEventListener("input", renderRegisters);
async function pollRegisters() {
  try {
    const r = await fetch("/api/registers");
    registers = (await r.json()).registers;
    renderRegisters();
  } catch (e) { /* the WebSocket badge already says the server is gone */ }
  setTimeout(pollRegisters, $("view-variables").hidden ? 2000 : 250);
}

// ---- start -------------------------------------------------------------------------------
async function start() {
  const info = await (await fetch("/api/info")).json();
  armbench.info = info;
  const controller = info.mode === "controller";
  for (const e of document.querySelectorAll(".ctl-only")) e.hidden = !controller;
  $("progname").textContent = info.program;
  $("plcaddr").textContent = info.plc_address;
  $("unreachable").textContent = info.unreachable.length ? "Not reachable over Modbus (OpenPLC maps no " +
    "Modbus address to them): " + info.unreachable.map((u) => `${u.name} (${u.location})`).join(", ") : "";
  showView(location.hash.slice(1) || (controller ? "arm" : "variables"));
  pollRegisters();
  if (controller) await loadCommands();
  connect();
  if (window.armbenchTrace) window.armbenchTrace(info);
}
start();
