// wiretape view: draws the timeline of the session held in #wiretape-data
// (its layout is page_data() in python/wiretape/tools/view.py).
"use strict";
(function () {
  const PAGE_FORMAT = 1;
  const COLOURS = {
    tx: "#1f6fd1", rx: "#1a9a3a", axis: "#888888", grid: "#eeeeee", text: "#1b1b1b",
    exchangeA: "#dde6f3", exchangeB: "#c9d6ea", selected: "#ff8c00", mismatch: "#c62828",
    outcome: { ok: "#3a9a4a", error: "#e0a000", crash: "#c62828", hang: "#e05a00" },
    event: {
      fault: "#c62828", device_lost: "#000000", capture_gap: "#8a8a8a", settings: "#6a3fb5",
      modem_lines: "#b5287a", break: "#b5287a", flush_input: "#e07a00", flush_output: "#e07a00",
      drain: "#a0a0a0", client_connect: "#0a8a8a", client_disconnect: "#0a6060",
      open: "#404040", close: "#404040", redaction: "#8a6d00",
    },
  };
  const OUTCOME_RANK = { ok: 0, error: 1, hang: 2, crash: 3 };
  const LIST_ROWS = 2000;
  const RULER_H = 22, EXCHANGE_H = 18, RUNS_H = 14, LANE_H = 34, EVENTS_H = 24, GROUP_GAP = 6;
  const LABEL_W = 64;

  const data = JSON.parse(document.getElementById("wiretape-data").textContent);
  if (data.format !== PAGE_FORMAT) {
    document.getElementById("hex").textContent =
      "This page's data is of format " + data.format + "; this script reads format " + PAGE_FORMAT + ".";
    return;
  }

  // ---- the records, in columns
  const rec = data.records;
  const count = rec.t_ns.length;
  const times = Float64Array.from(rec.t_ns);
  const kinds = Uint8Array.from(rec.kind);
  const kindNames = data.kinds;
  const TX = kindNames.indexOf("tx"), RX = kindNames.indexOf("rx");
  const offsets = new Float64Array(count + 1);
  for (let i = 0; i < count; i++) offsets[i + 1] = offsets[i] + rec.kept[i];
  let allBytes = null;
  function bytesOf(i) {
    if (allBytes === null) {
      const text = atob(rec.bytes);
      allBytes = new Uint8Array(text.length);
      for (let j = 0; j < text.length; j++) allBytes[j] = text.charCodeAt(j);
    }
    return allBytes.subarray(offsets[i], offsets[i + 1]);
  }
  const lastT = count ? times[count - 1] : 0;
  const span = Math.max(lastT, 1e6);

  // The exchange each record belongs to (-1: none), and the worst campaign
  // outcome of each exchange.
  const exchanges = data.exchanges;  // [index, first, end, reqFirst, reqLast, respFirst, respLast, reqBytes, respBytes, client]
  const exchangeOf = new Int32Array(count).fill(-1);
  for (const e of exchanges) for (let i = e[1]; i < e[2] && i < count; i++) exchangeOf[i] = e[0];
  const exchangeStart = exchanges.map(e => e[3] !== null ? e[3] : (e[1] < count ? times[e[1]] : 0));
  const exchangeEnd = exchanges.map((e, n) => Math.max(exchangeStart[n], e[4] || 0, e[6] || 0));
  const runsByExchange = new Map();
  const campaign = data.campaign;
  if (campaign) for (const run of campaign.runs) {
    if (run.exchange === undefined) continue;
    if (!runsByExchange.has(run.exchange)) runsByExchange.set(run.exchange, []);
    runsByExchange.get(run.exchange).push(run);
  }
  function worstOutcome(runs) {
    let worst = null;
    for (const run of runs) if (worst === null || OUTCOME_RANK[run.outcome] > OUTCOME_RANK[worst]) worst = run.outcome;
    return worst;
  }

  // The mismatch of a replay's -o recording: the tx record holding the
  // first byte the client wrote that the replayed session does not hold.
  let mismatchRecord = -1;
  if (data.mismatch) {
    let seen = 0;
    for (let i = 0; i < count; i++) {
      if (kinds[i] !== TX) continue;
      const size = rec.size[i];
      if (data.mismatch.tx_offset < seen + size) { mismatchRecord = i; break; }
      seen += size;
    }
  }

  // ---- lanes: per channel a tx, an rx and an events lane
  const lanes = [];
  let y = RULER_H + EXCHANGE_H + (campaign ? RUNS_H : 0) + GROUP_GAP;
  for (const channel of data.channels) {
    for (const [name, height] of [["tx", LANE_H], ["rx", LANE_H], ["events", EVENTS_H]]) {
      lanes.push({ channel: channel.id, channelName: channel.name, name, top: y, height });
      y += height;
    }
    y += GROUP_GAP;
  }
  const canvasHeight = y + 4;
  function laneOfKind(k) { return k === TX ? "tx" : k === RX ? "rx" : "events"; }
  // The channel of each record: one number for all, or one per record.
  const channelOf = Array.isArray(rec.channel) ? (i => rec.channel[i]) : (() => rec.channel);
  const laneIndex = new Map(lanes.map((lane, n) => [lane.channel + "/" + lane.name, n]));
  function laneOf(i) { return laneIndex.get(channelOf(i) + "/" + laneOfKind(kinds[i])); }

  // ---- view state
  const canvas = document.getElementById("lanes");
  const ctx = canvas.getContext("2d");
  let width = 0;
  let t0 = -span * 0.01, t1 = span * 1.01;
  let selected = -1, hovered = -1;

  function plotWidth() { return Math.max(width - LABEL_W, 10); }
  function xOf(t) { return LABEL_W + (t - t0) / (t1 - t0) * plotWidth(); }
  function tOf(x) { return t0 + (x - LABEL_W) / plotWidth() * (t1 - t0); }
  function firstAtOrAfter(array, t) {  // binary search in a non-decreasing array
    let lo = 0, hi = array.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (array[mid] < t) lo = mid + 1; else hi = mid; }
    return lo;
  }

  function seconds(t_ns, digits) { return (t_ns / 1e9).toFixed(digits === undefined ? 6 : digits) + " s"; }

  function resize() {
    const ratio = window.devicePixelRatio || 1;
    width = canvas.parentElement.clientWidth || 800;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(canvasHeight * ratio);
    canvas.style.height = canvasHeight + "px";
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  }

  function drawRuler() {
    const per = (t1 - t0) / plotWidth() * 100;  // ns per 100 px
    const magnitude = Math.pow(10, Math.floor(Math.log10(per)));
    const step = [1, 2, 5, 10].map(m => m * magnitude).find(s => s >= per);
    const digits = Math.max(0, Math.min(9, -Math.floor(Math.log10(step / 1e9))));
    ctx.fillStyle = COLOURS.text; ctx.font = "11px sans-serif"; ctx.textBaseline = "middle";
    for (let t = Math.ceil(t0 / step) * step; t <= t1; t += step) {
      const x = Math.round(xOf(t)) + 0.5;
      ctx.strokeStyle = COLOURS.grid; ctx.beginPath(); ctx.moveTo(x, RULER_H); ctx.lineTo(x, canvasHeight); ctx.stroke();
      ctx.fillText(seconds(t, digits), x + 2, RULER_H / 2);
    }
  }

  function drawExchanges() {
    const top = RULER_H, pw = plotWidth();
    const lo = Math.max(0, firstAtOrAfter(exchangeStart, t0) - 1);
    let lastLabel = -1e9, lastX = -1;
    ctx.font = "10px sans-serif"; ctx.textBaseline = "middle";
    for (let n = lo; n < exchanges.length && exchangeStart[n] <= t1; n++) {
      const x0 = Math.max(LABEL_W, xOf(exchangeStart[n]));
      const x1 = Math.min(LABEL_W + pw, Math.max(xOf(exchangeEnd[n]), x0 + 3));
      if (x1 < LABEL_W || Math.floor(x1) <= lastX) continue;  // decimated: one per pixel
      lastX = Math.floor(x1);
      ctx.fillStyle = n % 2 ? COLOURS.exchangeB : COLOURS.exchangeA;
      ctx.fillRect(x0, top + 1, x1 - x0, EXCHANGE_H - 2);
      if (x1 - x0 > 22 && x0 - lastLabel > 22) {
        ctx.fillStyle = COLOURS.text; ctx.fillText("#" + exchanges[n][0], x0 + 2, top + EXCHANGE_H / 2);
        lastLabel = x0;
      }
      if (campaign) {
        const runs = runsByExchange.get(n);
        if (runs) {
          ctx.fillStyle = COLOURS.outcome[worstOutcome(runs)];
          ctx.fillRect(x0, top + EXCHANGE_H + 1, Math.max(x1 - x0, 3), RUNS_H - 2);
        }
      }
    }
    if (campaign) for (const run of campaign.runs) {
      if (run.t_ns === undefined || run.t_ns < t0 || run.t_ns > t1) continue;
      ctx.fillStyle = COLOURS.outcome[run.outcome];
      ctx.fillRect(xOf(run.t_ns) - 1, top + EXCHANGE_H + 1, 3, RUNS_H - 2);
    }
    ctx.fillStyle = COLOURS.text; ctx.font = "11px sans-serif";
    ctx.fillText("exchanges", 2, top + EXCHANGE_H / 2);
    if (campaign) ctx.fillText("faults", 2, top + EXCHANGE_H + RUNS_H / 2);
  }

  function drawLanes() {
    const pw = Math.ceil(plotWidth());
    const lo = Math.max(0, firstAtOrAfter(times, t0));
    const hi = firstAtOrAfter(times, t1 + 1);
    // Decimation: one bar per pixel column and lane, as high as the largest
    // record there; one event marker per column.
    const columns = lanes.map(lane => lane.name === "events" ? new Int32Array(pw + 1).fill(-1) : new Float64Array(pw + 1));
    let maxSize = 1;
    for (let i = lo; i < hi; i++) {
      const col = Math.floor(xOf(times[i]) - LABEL_W);
      if (col < 0 || col > pw) continue;
      const k = kinds[i], n = laneOf(i);
      if (n === undefined) continue;
      if (k === TX || k === RX) {
        const bars = columns[n], size = rec.size[i] + 1;
        if (size > bars[col]) bars[col] = size;
        if (size > maxSize) maxSize = size;
      } else if (columns[n][col] < 0 || kindNames[k] === "fault") {
        columns[n][col] = i;
      }
    }
    const scale = Math.log(maxSize + 1);
    lanes.forEach((lane, n) => {
      ctx.fillStyle = COLOURS.text; ctx.font = "11px sans-serif"; ctx.textBaseline = "middle";
      ctx.fillText(data.channels.length > 1 ? lane.channelName + " " + lane.name : lane.name, 2, lane.top + lane.height / 2);
      ctx.strokeStyle = COLOURS.grid; ctx.beginPath();
      ctx.moveTo(LABEL_W, lane.top + lane.height + 0.5); ctx.lineTo(LABEL_W + pw, lane.top + lane.height + 0.5); ctx.stroke();
      if (lane.name === "events") {
        let lastLabel = -1e9;
        for (let col = 0; col <= pw; col++) {
          const i = columns[n][col];
          if (i < 0) continue;
          const name = kindNames[kinds[i]];
          ctx.fillStyle = COLOURS.event[name] || COLOURS.axis;
          ctx.fillRect(LABEL_W + col - 1, lane.top + 3, 3, lane.height - 6);
          if (col - lastLabel > 90) {
            ctx.fillStyle = COLOURS.text; ctx.font = "10px sans-serif";
            ctx.fillText(name, LABEL_W + col + 4, lane.top + lane.height / 2);
            lastLabel = col;
          }
        }
        return;
      }
      const bars = columns[n];
      ctx.fillStyle = COLOURS[lane.name];
      for (let col = 0; col <= pw; col++) {
        if (!bars[col]) continue;
        const h = Math.max(3, Math.round((lane.height - 6) * (0.25 + 0.75 * Math.log(bars[col] + 1) / scale)));
        ctx.fillRect(LABEL_W + col - 1, lane.top + lane.height - 2 - h, 3, h);
      }
    });
    drawFrames();
  }

  // A profile's frames: their names over the bars, where there is room.
  const frames = data.frames;  // [t_ns, "tx"|"rx", size, name]
  const frameTimes = Float64Array.from(frames.map(f => f[0]));
  function drawFrames() {
    if (!frames.length) return;
    const lastLabel = { tx: -1e9, rx: -1e9 };
    ctx.font = "10px sans-serif"; ctx.textBaseline = "top"; ctx.fillStyle = COLOURS.text;
    for (let n = firstAtOrAfter(frameTimes, t0); n < frames.length && frames[n][0] <= t1; n++) {
      const f = frames[n], x = xOf(f[0]);
      const lane = lanes.find(l => l.name === f[1]);
      if (!lane) continue;
      const label = String(f[3]).split(" ")[0];
      const w = ctx.measureText(label).width;
      if (x - lastLabel[f[1]] < 6) continue;
      ctx.fillText(label, x + 3, lane.top + 1);
      lastLabel[f[1]] = x + w;
    }
  }

  function drawMarks() {
    for (const [i, colour, label] of [[selected, COLOURS.selected, null], [mismatchRecord, COLOURS.mismatch, "mismatch"]]) {
      if (i < 0 || times[i] < t0 || times[i] > t1) continue;
      const x = Math.round(xOf(times[i])) + 0.5;
      ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.beginPath();
      ctx.moveTo(x, RULER_H); ctx.lineTo(x, canvasHeight); ctx.stroke(); ctx.lineWidth = 1;
      if (label) { ctx.fillStyle = colour; ctx.font = "bold 11px sans-serif"; ctx.textBaseline = "top"; ctx.fillText(label, x + 4, canvasHeight - 14); }
    }
  }

  let pending = false;
  function draw() {
    pending = false;
    ctx.clearRect(0, 0, width, canvasHeight);
    drawRuler();
    drawExchanges();
    drawLanes();
    drawMarks();
    document.getElementById("status").textContent = seconds(t0, 6) + " … " + seconds(t1, 6);
    canvas.dataset.from = String(t0); canvas.dataset.to = String(t1);
  }
  function redraw() { if (!pending) { pending = true; requestAnimationFrame(draw); } }

  // ---- the hex/ASCII pane
  function hexLines(bytes) {
    const lines = [];
    for (let at = 0; at < bytes.length; at += 16) {
      const chunk = bytes.subarray(at, at + 16);
      let hex = "", text = "";
      for (const b of chunk) { hex += b.toString(16).padStart(2, "0") + " "; text += b >= 0x20 && b < 0x7f ? String.fromCharCode(b) : "."; }
      lines.push(at.toString(16).padStart(8, "0") + "  " + hex.padEnd(48) + " |" + text + "|");
    }
    return lines;
  }
  function describe(i) {
    const name = kindNames[kinds[i]];
    let line = "record " + i + "  +" + seconds(times[i]) + "  " + name + "  " + rec.size[i] + " bytes";
    if (exchangeOf[i] >= 0) line += "  exchange " + exchangeOf[i];
    if (i === mismatchRecord) line += "  MISMATCH";
    return line;
  }
  function showRecord(i) {
    const pane = document.getElementById("hex");
    if (i < 0) { pane.textContent = "Point at a record or click it."; pane.removeAttribute("data-record"); return; }
    const bytes = bytesOf(i);
    const lines = [describe(i)];
    if (kinds[i] !== TX && kinds[i] !== RX) lines.push(new TextDecoder().decode(bytes) || "{}");
    lines.push(...hexLines(bytes));
    if (rec.kept[i] < rec.size[i]) lines.push("(the first " + rec.kept[i] + " of " + rec.size[i] + " bytes are in this page)");
    if (i === mismatchRecord) lines.push("", "expected: " + data.mismatch.expected, "actual:   " + data.mismatch.actual);
    pane.textContent = lines.join("\n");
    pane.dataset.record = String(i);
  }
  function select(i, reveal) {
    selected = i;
    if (reveal && i >= 0 && (times[i] < t0 || times[i] > t1)) {
      const half = (t1 - t0) / 2; t0 = times[i] - half; t1 = times[i] + half;
    }
    showRecord(i);
    redraw();
  }

  // ---- pointer and keys
  function recordAt(x, y) {
    const lane = lanes.find(l => y >= l.top && y < l.top + l.height);
    if (!lane) return -1;
    const t = tOf(x), slack = 5 * (t1 - t0) / plotWidth();
    let best = -1, bestDistance = Infinity;
    for (let i = Math.max(0, firstAtOrAfter(times, t - slack)); i < count && times[i] <= t + slack; i++) {
      if (lanes[laneOf(i)] !== lane) continue;
      const distance = Math.abs(times[i] - t);
      if (distance < bestDistance) { best = i; bestDistance = distance; }
    }
    return best;
  }
  let drag = null;
  const box = canvas.parentElement;
  canvas.addEventListener("mousedown", event => { drag = { x: event.offsetX, t0, t1, moved: false }; box.classList.add("dragging"); });
  window.addEventListener("mouseup", event => {
    if (drag && !drag.moved && event.target === canvas) select(recordAt(event.offsetX, event.offsetY), false);
    drag = null; box.classList.remove("dragging");
  });
  canvas.addEventListener("mousemove", event => {
    if (drag) {
      const dx = event.offsetX - drag.x;
      if (Math.abs(dx) > 2) drag.moved = true;
      const dt = dx / plotWidth() * (drag.t1 - drag.t0);
      t0 = drag.t0 - dt; t1 = drag.t1 - dt; redraw();
      return;
    }
    const i = recordAt(event.offsetX, event.offsetY);
    if (i !== hovered) { hovered = i; showRecord(i >= 0 ? i : selected); }
  });
  canvas.addEventListener("mouseleave", () => { hovered = -1; showRecord(selected); });
  function zoom(factor, x) {
    const t = tOf(x === undefined ? LABEL_W + plotWidth() / 2 : x);
    const width_ns = Math.max((t1 - t0) * factor, 1000);  // no closer than 1 µs across
    const share = (t - t0) / (t1 - t0);
    t0 = t - share * width_ns; t1 = t0 + width_ns; redraw();
  }
  canvas.addEventListener("wheel", event => { event.preventDefault(); zoom(Math.pow(1.0015, event.deltaY), event.offsetX); }, { passive: false });
  function fit() { t0 = -span * 0.01; t1 = span * 1.01; redraw(); }
  document.getElementById("fit").addEventListener("click", fit);
  document.getElementById("zoom-in").addEventListener("click", () => zoom(0.5));
  document.getElementById("zoom-out").addEventListener("click", () => zoom(2));
  window.addEventListener("keydown", event => {
    if (event.key === "+" || event.key === "=") zoom(0.5);
    else if (event.key === "-") zoom(2);
    else if (event.key === "Home") fit();
    else if (event.key === "ArrowRight" && selected + 1 < count) select(selected + 1, true);
    else if (event.key === "ArrowLeft" && selected > 0) select(selected - 1, true);
  });
  window.addEventListener("resize", () => { resize(); redraw(); });

  // ---- the header, the notes and the lists (after the first paint)
  function summary() {
    const h = data.session.header, parts = [count + " records", exchanges.length + " exchanges", seconds(lastT, 3)];
    if (h.port_type) parts.push(h.port_type + ": " + (h.port_options || ""));
    if (data.session.profile) parts.push("profile " + data.session.profile + " (" + frames.length + " frames)");
    if (h.start_utc) parts.push("started " + h.start_utc);
    document.getElementById("summary").textContent = parts.join(" · ");
    const notes = document.getElementById("notes");
    function note(className, text) { const div = document.createElement("div"); div.className = className; div.textContent = text; notes.appendChild(div); }
    if (data.session.damage) note("damage", "Damaged: " + data.session.damage + " (the records before it are shown)");
    if (data.mismatch) note("mismatch", "Mismatch (record " + mismatchRecord + ", tx byte " + data.mismatch.tx_offset + "): the client wrote bytes that " + data.mismatch.original + " does not hold\nexpected: " + data.mismatch.expected + "\nactual:   " + data.mismatch.actual);
    if (campaign && !campaign.same_session) note("warning", "The campaign " + campaign.path + " ran on a session whose bytes differ from this one's.");
  }

  function escapeText(bytes) {
    let text = "";
    for (const b of bytes) text += b === 10 ? "\\n" : b === 13 ? "\\r" : b >= 0x20 && b < 0x7f ? String.fromCharCode(b) : "\\x" + b.toString(16).padStart(2, "0");
    return text;
  }
  function table(id, title, head, rows, total) {
    const section = document.createElement("div");
    section.id = id;
    const h2 = document.createElement("h2"); h2.textContent = title + " (" + total + ")"; section.appendChild(h2);
    const tableElement = document.createElement("table");
    const header = tableElement.insertRow();
    for (const cell of head) { const th = document.createElement("th"); th.textContent = cell; header.appendChild(th); }
    for (const row of rows) {
      const tr = tableElement.insertRow();
      if (row.record !== undefined && row.record >= 0) tr.dataset.record = String(row.record);
      if (row.className) tr.className = row.className;
      for (const cell of row.cells) tr.insertCell().textContent = cell;
    }
    section.appendChild(tableElement);
    if (total > rows.length) { const more = document.createElement("div"); more.className = "more"; more.textContent = "… " + (total - rows.length) + " more: zoom the timeline to see them"; section.appendChild(more); }
    document.getElementById("lists").appendChild(section);
  }
  function lists() {
    if (campaign) {
      table("runs", "Fault campaign " + campaign.path, ["case", "fault", "outcome", "exit", "seconds", "exchange", "reproduce"],
        campaign.runs.slice(0, LIST_ROWS).map(run => ({
          record: run.exchange !== undefined ? exchanges[run.exchange][1] : -1, className: "outcome-" + run.outcome,
          cells: [run.case, run.kind + "@" + run.where, run.outcome, run.exit === null ? "" : run.exit, run.seconds.toFixed(3),
            run.exchange !== undefined ? "#" + exchanges[run.exchange][0] : "", run.repro] })), campaign.runs.length);
    }
    table("exchange-list", "Exchanges", ["#", "time", "request", "response bytes", "faults"],
      exchanges.slice(0, LIST_ROWS).map((e, n) => {
        let request = "";
        for (let i = e[1]; i < e[2] && i < count && request.length < 60; i++) if (kinds[i] === TX) request += escapeText(bytesOf(i));
        const runs = runsByExchange.get(n) || [];
        const worst = worstOutcome(runs);
        return { record: e[1], className: worst ? "outcome-" + worst : "",
          cells: ["#" + e[0], e[3] !== null ? "+" + seconds(e[3]) : "", request.slice(0, 60), e[8],
            runs.map(run => run.kind + ":" + run.outcome).join(" ")] };
      }), exchanges.length);
    if (frames.length) {
      table("frame-list", "Frames (" + data.session.profile + ")", ["time", "dir", "bytes", "frame"],
        frames.slice(0, LIST_ROWS).map(f => ({ record: firstAtOrAfter(times, f[0]), cells: ["+" + seconds(f[0]), f[1], f[2], f[3]] })), frames.length);
    }
    const events = [];
    let eventCount = 0;
    for (let i = 0; i < count; i++) {
      if (kinds[i] === TX || kinds[i] === RX) continue;
      eventCount++;
      if (events.length < LIST_ROWS) events.push({ record: i, cells: ["+" + seconds(times[i]), kindNames[kinds[i]], new TextDecoder().decode(bytesOf(i))] });
    }
    table("event-list", "Events", ["time", "kind", "payload"], events, eventCount);
    document.getElementById("lists").addEventListener("click", event => {
      const row = event.target.closest("tr[data-record]");
      if (row) select(Number(row.dataset.record), true);
    });
    document.documentElement.dataset.listsReady = "true";
  }

  // Where things are drawn, for tests that point at them (CSS pixels from
  // the canvas's left and top edges).
  window.wiretapeView = {
    xOf: xOf,
    laneMiddle: name => { const lane = lanes.find(l => l.name === name); return lane.top + lane.height / 2; },
    range: () => [t0, t1],
  };

  // ---- start: the first paint, then the rest
  resize();
  summary();
  const wanted = /(?:^#|&)record=(\d+)/.exec(location.hash);
  if (wanted && Number(wanted[1]) < count) {
    const i = Number(wanted[1]);
    const around = Math.max((t1 - t0) / 200, 1e6);
    t0 = times[i] - around; t1 = times[i] + around;
    selected = i; showRecord(i);
  }
  draw();
  requestAnimationFrame(() => {
    document.documentElement.dataset.firstPaintMs = performance.now().toFixed(1);
    setTimeout(() => { lists(); document.documentElement.dataset.ready = "true"; }, 0);
  });
})();
