// armbench live view: the trace panel (as CODESYS Trace / TwinCAT Scope). The server samples
// the ticked variables as fast as the PLC answers; this page fetches the new samples ten
// times a second, keeps them in a buffer, plots the last seconds in one lane per variable
// (min/max per pixel column, so a long buffer costs a frame no more than a short one), pauses
// (the display and the buffer freeze; the samples that arrive meanwhile are kept aside and
// added on resume), and downloads the buffer as CSV. No third-party code.
"use strict";

window.armbenchTrace = function (info) {
  const T = armbench.trace = {
    config: 0, names: [], vars: [], rows: [], held: [], lastSeq: 0, paused: false, gaps: 0,
    max: 200000, rate: null, readMs: null, error: null,
  };
  const COLORS = ["#1565c0", "#e8710a", "#2e7d32", "#8e44ad", "#c62828", "#00838f", "#6d4c41",
    "#ad1457", "#558b2f", "#283593", "#ef6c00", "#00695c", "#4e342e", "#5e35b1", "#9e9d24", "#37474f"];
  const plot = $("trace-plot");
  const pctx = plot.getContext("2d");
  let variables = [];   // every located variable: {name, location, type, table}
  let dirty = true;
  // The selection the user has asked for so far: two boxes ticked before the first answer
  // arrives both count, and the requests go one after another so the last one wins.
  let want = null;
  let pending = 0;
  let sending = Promise.resolve();

  $("trace-max").textContent = 16;
  $("trace-period").textContent = fmt(info.trace.min_period_ms, 3);

  // ---- which variables -----------------------------------------------------------------
  function renderChoices() {
    const q = $("trace-filter").value.trim().toLowerCase();
    const shown = variables.filter((v) => !q || [v.name, v.location, v.type].some((x) => x.toLowerCase().includes(q)));
    $("trace-vars").innerHTML = shown.slice(0, 1000).map((v) => {
      const i = T.names.indexOf(v.name);
      const on = (want ?? T.names).includes(v.name);
      const sw = i >= 0 ? `<span class="swatch" style="background:${COLORS[i % COLORS.length]}"></span>` : "";
      return `<label><input type="checkbox" value="${esc(v.name)}"${on ? " checked" : ""}> ${sw}${esc(v.name)} ` +
        `<small>${esc(v.location)} ${esc(v.type)}</small></label>`;
    }).join("");
  }
  $("trace-filter").addEventListener("input", renderChoices);
  $("trace-vars").addEventListener("change", (e) => {
    const name = e.target.value;
    const base = want ?? T.names;
    want = e.target.checked ? base.filter((n) => n !== name).concat([name])
                            : base.filter((n) => n !== name);
    const names = want.slice();
    pending += 1;
    sending = sending.then(async () => {
      try {
        const r = await fetch("/api/trace", { method: "POST", headers: { "Content-Type": "application/json" },
                                              body: JSON.stringify({ variables: names }) });
        const a = await r.json();
        if (!a.ok) { T.error = a.message; want = null; renderChoices(); stats(); return; }
        T.error = null;
        adopt(a);
      } catch (err) { want = null; renderChoices(); }
      finally { pending -= 1; if (pending === 0) want = null; }
    });
  });

  function adopt(a) {
    // a new trace (ours, or another page's): start the buffer again
    T.config = a.config; T.vars = a.variables; T.names = a.variables.map((v) => v.name);
    T.rows = []; T.held = []; T.lastSeq = 0; T.gaps = 0;
    renderChoices(); legend(); dirty = true;
  }

  // ---- samples ---------------------------------------------------------------------------
  async function poll() {
    let more = false;
    try {
      const r = await fetch(`/api/trace?since=${T.lastSeq}&config=${T.config}`);
      const a = await r.json();
      // configurations only count up: an older one is an answer the server gave before the
      // page took a newer selection (its POST answered first), and its samples are stale
      if (a.config < T.config) { setTimeout(poll, 0); return; }
      if (a.config !== T.config) adopt(a);
      const into = T.paused ? T.held : T.rows;
      for (const s of a.samples) {
        if (T.lastSeq && s[0] !== T.lastSeq + 1) T.gaps += 1;
        T.lastSeq = s[0];
        into.push(s.slice(1));
      }
      if (T.rows.length > T.max * 1.1) T.rows.splice(0, T.rows.length - T.max);
      T.rate = a.rate_hz; T.readMs = a.read_ms; T.error = a.error;
      more = a.more;
      if (a.samples.length && !T.paused) dirty = true;
      stats();
    } catch (e) { /* the header already says the server is gone */ }
    setTimeout(poll, more ? 0 : 100);
  }

  function stats() {
    const parts = [`${T.rows.length} samples in the buffer`];
    if (T.names.length) parts.push(`${fmt(T.rate, 0)} samples/s, read ${fmt(T.readMs, 2)} ms`);
    if (T.paused) parts.push(`paused: ${T.held.length} new samples kept aside`);
    if (T.gaps) parts.push(`${T.gaps} gap(s)`);
    if (T.error) parts.push(T.error);
    $("trace-stats").textContent = parts.join("; ");
  }

  $("trace-pause").addEventListener("click", () => {
    T.paused = !T.paused;
    if (!T.paused) { for (const r of T.held) T.rows.push(r); T.held = []; dirty = true; }
    $("trace-pause").textContent = T.paused ? "Resume" : "Pause";
    stats();
  });
  $("trace-clear").addEventListener("click", () => { T.rows = []; T.held = []; dirty = true; stats(); });
  $("trace-window").addEventListener("change", () => { dirty = true; });

  // ---- CSV ----------------------------------------------------------------------------------
  $("trace-csv").addEventListener("click", () => {
    const t0 = T.rows.length ? T.rows[0][0] : 0;
    const lines = [["time_s", "unix_time_s", ...T.names].join(",")];
    for (const r of T.rows) {
      lines.push([(r[0] - t0).toFixed(6), r[0].toFixed(6),
        ...r.slice(1).map((v) => v === null ? "nan" : String(v))].join(","));
    }
    const blob = new Blob([lines.join("\n") + "\n"], { type: "text/csv" });
    const a = document.createElement("a");
    const d = new Date();
    const p2 = (n) => String(n).padStart(2, "0");
    a.download = `armbench-trace-${d.getFullYear()}${p2(d.getMonth() + 1)}${p2(d.getDate())}-` +
      `${p2(d.getHours())}${p2(d.getMinutes())}${p2(d.getSeconds())}.csv`;
    a.href = URL.createObjectURL(blob);
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  });

  // ---- the plot ----------------------------------------------------------------------------
  function firstAtOrAfter(t) {       // binary search: rows are in time order
    let lo = 0, hi = T.rows.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (T.rows[mid][0] < t) lo = mid + 1; else hi = mid; }
    return lo;
  }

  let visible = [];  // per variable: {min, max, last} over the window
  function draw() {
    const w = Math.max(300, Math.floor(plot.clientWidth || plot.width));
    if (plot.width !== w) plot.width = w;
    const W = plot.width, H = plot.height;
    const left = 8, right = 70, top = 6, bottom = 22;
    const pw = W - left - right, ph = H - top - bottom;
    pctx.clearRect(0, 0, W, H);
    pctx.font = "11px system-ui";
    const n = T.names.length;
    const win = +$("trace-window").value;
    const rows = T.rows;
    const tEnd = rows.length ? rows[rows.length - 1][0] : 0;
    const t0 = tEnd - win;
    const i0 = firstAtOrAfter(t0);
    // time grid: one line per second (or per 5 / 10 s for wide windows)
    const step = win <= 10 ? 1 : win <= 30 ? 5 : 10;
    pctx.strokeStyle = "#eef1f4"; pctx.fillStyle = "#5d6a78"; pctx.lineWidth = 1;
    for (let k = 0; k <= win; k += step) {
      const x = left + pw - (k / win) * pw;
      pctx.beginPath(); pctx.moveTo(x, top); pctx.lineTo(x, top + ph); pctx.stroke();
      const label = k ? `-${k} s` : "now";
      pctx.fillText(label, Math.max(0, Math.min(W - pctx.measureText(label).width, x - 12)), H - 6);
    }
    visible = [];
    if (!n) {
      pctx.fillStyle = "#5d6a78"; pctx.font = "14px system-ui";
      pctx.fillText("tick variables on the left to trace them", left + 20, top + 30);
      plot.dataset.drawn = 0;
      return;
    }
    const laneH = ph / n;
    for (let v = 0; v < n; v++) {
      const y0 = top + v * laneH;
      let lo = Infinity, hi = -Infinity, last = null;
      for (let i = i0; i < rows.length; i++) {
        const x = rows[i][v + 1];
        if (x === null) continue;
        if (x < lo) lo = x; if (x > hi) hi = x;
        last = x;
      }
      visible.push({ min: lo, max: hi, last });
      pctx.strokeStyle = "#c9d0d8";
      pctx.beginPath(); pctx.moveTo(left, y0 + laneH); pctx.lineTo(left + pw, y0 + laneH); pctx.stroke();
      const color = COLORS[v % COLORS.length];
      pctx.fillStyle = color; pctx.font = "bold 11px system-ui";
      pctx.fillText(T.names[v], left + 4, y0 + 12);
      if (lo === Infinity) continue;
      const isBool = T.vars[v] && T.vars[v].type === "BOOL";
      let a = isBool ? 0 : lo, b = isBool ? 1 : hi;
      if (b - a < 1e-12) { a -= 1; b += 1; }
      const pad = (b - a) * 0.08;
      a -= pad; b += pad;
      const yOf = (x) => y0 + 4 + (laneH - 8) * (1 - (x - a) / (b - a));
      pctx.fillStyle = "#5d6a78"; pctx.font = "11px system-ui";
      pctx.fillText(isBool ? "TRUE" : num(hi), left + pw + 4, y0 + 12);
      pctx.fillText(isBool ? "FALSE" : num(lo), left + pw + 4, y0 + laneH - 4);
      // one vertical stroke per pixel column (min..max), joined column to column
      pctx.strokeStyle = color; pctx.lineWidth = 1.5; pctx.beginPath();
      let col = -1, cmin = 0, cmax = 0, started = false;
      const flush = () => {
        const x = left + col + 0.5;
        if (!started) { pctx.moveTo(x, yOf(cmin)); started = true; } else pctx.lineTo(x, yOf(cmin));
        pctx.lineTo(x, yOf(cmax));
      };
      for (let i = i0; i < rows.length; i++) {
        const x = rows[i][v + 1];
        if (x === null) continue;
        const c = Math.min(pw - 1, Math.floor((rows[i][0] - t0) / win * pw));
        if (c !== col) { if (col >= 0) flush(); col = c; cmin = cmax = x; } else { if (x < cmin) cmin = x; if (x > cmax) cmax = x; }
      }
      if (col >= 0) flush();
      pctx.stroke();
    }
    plot.dataset.drawn = rows.length - i0;
    legend();
  }

  function legend() {
    $("trace-legend").tBodies[0].innerHTML = T.vars.map((v, i) => {
      const s = visible[i] || {};
      const show = (x) => x === undefined || x === null || !isFinite(x) ? "-" : num(x);
      return `<tr><td class="l"><span class="swatch" style="background:${COLORS[i % COLORS.length]}"></span>${esc(v.name)}</td>` +
        `<td>${show(s.last)}</td><td>${show(s.min)}</td><td>${show(s.max)}</td><td class="l">${esc(v.location)} ${esc(v.type)}</td></tr>`;
    }).join("");
  }

  function frame() {
    if (dirty && !$("view-trace").hidden) { dirty = false; draw(); }
    requestAnimationFrame(frame);
  }
  for (const b of document.querySelectorAll("#views button")) b.addEventListener("click", () => { dirty = true; });

  async function loadVariables() {
    try {
      const regs = (await (await fetch("/api/registers")).json()).registers;
      if (!regs.length) { setTimeout(loadVariables, 300); return; }
      variables = regs.map((r) => ({ name: r.name, location: r.location, type: r.type }));
      renderChoices();
    } catch (e) { setTimeout(loadVariables, 1000); }
  }

  (async () => {
    loadVariables();
    try {
      const a = await (await fetch("/api/trace?since=0")).json();
      adopt(a);
      T.config = a.config;
    } catch (e) { /* poll() tries again */ }
    poll();
    requestAnimationFrame(frame);
  })();
};
