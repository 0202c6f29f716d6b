// wiretape view: draws the timeline of the session held in #wiretape-data
// (its layout is page_data() in python/wiretape/tools/view.py), and the
// record table, search, follow stream and cursors.
"use strict";
(function () {
  const PAGE_FORMAT = 2;
  const COLOURS = {
    tx: "#1f6fd1", rx: "#1a9a3a", axis: "#888888", grid: "#eeeeee", text: "#1b1b1b",
    exchangeA: "#dde6f3", exchangeB: "#c9d6ea", selected: "#ff8c00", mismatch: "#c62828",
    cursorA: "#7b1fa2", cursorB: "#00838f", fold: "#f0f0f0", summary: "#f6f6f6",
    outcome: { ok: "#3a9a4a", error: "#e0a000", crash: "#c62828", hang: "#e05a00" },
    event: {
      fault: "#c62828", device_lost: "#000000", capture_gap: "#8a8a8a", settings: "#6a3fb5",
      modem_lines: "#b5287a", break: "#b5287a", flush_input: "#e07a00", flush_output: "#e07a00",
      drain: "#a0a0a0", client_connect: "#0a8a8a", client_disconnect: "#0a6060",
      open: "#404040", close: "#404040", redaction: "#8a6d00",
    },
  };
  const OUTCOME_RANK = { ok: 0, error: 1, hang: 2, crash: 3 };
  const LIST_ROWS = 2000, TABLE_ROWS = 200, STREAM_CHARS = 400000;
  const RULER_H = 22, EXCHANGE_H = 18, RUNS_H = 14, LANE_H = 34, EVENTS_H = 24, GROUP_GAP = 6;
  // An idle gap is folded when it is this long and this share of the
  // session; folded, it is as wide as this share of the time not idle.
  const FOLD_MIN_NS = 1e9, FOLD_MIN_SHARE = 0.05, FOLDED_SHARE = 0.03;

  const data = JSON.parse(document.getElementById("wiretape-data").textContent);
  if (data.format !== PAGE_FORMAT) {
    document.getElementById("hex").textContent =
      "This page's data is of format " + data.format + "; this script reads format " + PAGE_FORMAT + ".";
    return;
  }
  const $ = id => document.getElementById(id);

  // ---- the records held in detail, in columns
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
  const decimated = data.decimated;
  // Past detailEnd the session is in the summary timeline only.
  const detailEnd = decimated ? decimated.shown_until_t_ns : Infinity;
  const lastT = Math.max(count ? times[count - 1] : 0, data.session.last_t_ns || 0);
  const span = Math.max(lastT, 1e6);
  const channelOf = Array.isArray(rec.channel) ? (i => rec.channel[i]) : (() => rec.channel);
  const channelName = new Map(data.channels.map(c => [c.id, c.name]));
  const several = data.channels.length > 1;

  // The exchange each record belongs to (-1: none), and the worst campaign
  // outcome of each exchange.
  // [index, first, end, reqFirst, reqLast, respFirst, respLast, reqBytes, respBytes, client, channel, latency_ns]
  const exchanges = data.exchanges;
  const exchangeOf = new Int32Array(count).fill(-1);  // the exchange's row
  exchanges.forEach((e, n) => { for (let i = e[1]; i < e[2] && i < count; i++) exchangeOf[i] = n; });
  const exchangeStart = exchanges.map(e => e[3] !== null ? e[3] : (e[1] < count ? times[e[1]] : 0));
  const exchangeEnd = exchanges.map((e, n) => Math.max(exchangeStart[n], e[4] || 0, e[6] || 0));
  function exchangeName(n) { const e = exchanges[n]; return (several ? channelName.get(e[10]) : "") + "#" + e[0]; }
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

  // ---- idle gaps folded: the time axis is piecewise linear, each long
  // gap between records drawn as FOLDED_SHARE of the time that is not idle.
  const gapA = [], gapB = [], gapD = [], removedAfter = [];
  let foldOn = true;
  const FOLDED = (function findGaps() {
    const least = Math.max(FOLD_MIN_NS, span * FOLD_MIN_SHARE), found = [];
    let idle = 0;
    for (let i = 1; i < count; i++) {
      if (times[i] - times[i - 1] >= least) { found.push(i); idle += times[i] - times[i - 1]; }
    }
    const folded = Math.max((span - idle) * FOLDED_SHARE, 1e6);
    let removed = 0;
    for (const i of found) {
      const gap = times[i] - times[i - 1];
      if (gap < 10 * folded) continue;
      gapA.push(times[i - 1]); gapB.push(times[i]); gapD.push(times[i - 1] - removed);
      removed += gap - folded; removedAfter.push(removed);
    }
    return folded;
  })();
  function lastAtOrBefore(array, v) {
    let lo = 0, hi = array.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (array[mid] <= v) lo = mid + 1; else hi = mid; }
    return lo - 1;
  }
  function toD(t) {  // real session time -> axis time
    if (!foldOn) return t;
    const k = lastAtOrBefore(gapA, t);
    if (k < 0) return t;
    if (t < gapB[k]) return gapD[k] + (t - gapA[k]) * FOLDED / (gapB[k] - gapA[k]);
    return t - removedAfter[k];
  }
  function fromD(d) {  // axis time -> real session time
    if (!foldOn) return d;
    const k = lastAtOrBefore(gapD, d);
    if (k < 0) return d;
    if (d < gapD[k] + FOLDED) return gapA[k] + (d - gapD[k]) * (gapB[k] - gapA[k]) / FOLDED;
    return d + removedAfter[k];
  }

  // ---- lanes: per channel a tx, an rx and an events lane
  const lanes = [];
  let y = RULER_H + EXCHANGE_H + (campaign ? RUNS_H : 0) + GROUP_GAP;
  for (const channel of data.channels) {
    for (const [name, height] of [["tx", LANE_H], ["rx", LANE_H], ["events", EVENTS_H]]) {
      lanes.push({ channel: channel.id, channelName: channel.name, name, top: y, height,
        label: several ? channel.name + " " + name : name });
      y += height;
    }
    y += GROUP_GAP;
  }
  const canvasHeight = y + 4;
  function laneOfKind(k) { return k === TX ? "tx" : k === RX ? "rx" : "events"; }
  const laneIndex = new Map(lanes.map((lane, n) => [lane.channel + "/" + lane.name, n]));
  function laneOf(i) { return laneIndex.get(channelOf(i) + "/" + laneOfKind(kinds[i])); }

  // ---- view state (d0, d1: the axis times at the plot's edges)
  const canvas = $("lanes");
  const ctx = canvas.getContext("2d");
  let width = 0;
  // The labels' column is as wide as the widest label: none is clipped.
  ctx.font = "11px sans-serif";
  const LABEL_W = Math.ceil(Math.max(64, ...lanes.map(l => ctx.measureText(l.label).width + 10),
    ctx.measureText("exchanges").width + 10));
  let d0 = 0, d1 = 1;
  let selected = -1, hovered = -1;
  const cursors = { A: -1, B: -1 };

  function plotWidth() { return Math.max(width - LABEL_W, 10); }
  function xOfD(d) { return LABEL_W + (d - d0) / (d1 - d0) * plotWidth(); }
  function xOf(t) { return xOfD(toD(t)); }
  function tOf(x) { return fromD(d0 + (x - LABEL_W) / plotWidth() * (d1 - d0)); }
  function firstAtOrAfter(array, t) {  // binary search in a non-decreasing array
    let lo = 0, hi = array.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (array[mid] < t) lo = mid + 1; else hi = mid; }
    return lo;
  }
  function seconds(t_ns, digits) { return (t_ns / 1e9).toFixed(digits === undefined ? 6 : digits) + " s"; }
  function duration(ns) {
    const a = Math.abs(ns);
    return a >= 1e9 ? (ns / 1e9).toFixed(6) + " s" : a >= 1e6 ? (ns / 1e6).toFixed(3) + " ms" : (ns / 1e3).toFixed(1) + " µs";
  }
  // Text drawn at x, or left of x when it would pass the right edge.
  function label(text, x, yy, gap) {
    const w = ctx.measureText(text).width, right = LABEL_W + plotWidth();
    const at = x + gap + w <= right ? x + gap : x - gap - w;
    if (at >= LABEL_W) ctx.fillText(text, at, yy);
    return at + w;
  }

  function resize() {
    const ratio = window.devicePixelRatio || 1;
    width = canvas.parentElement.clientWidth || 800;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(canvasHeight * ratio);
    canvas.style.height = canvasHeight + "px";
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  }

  // The stretches of real time between folds that are in view.
  function segments() {
    const out = [], a = fromD(d0), b = fromD(d1);
    let from = a;
    if (foldOn) for (let k = Math.max(0, lastAtOrBefore(gapA, a)); k < gapA.length && gapA[k] < b; k++) {
      if (gapB[k] <= a) continue;
      if (gapA[k] > from) out.push([from, gapA[k]]);
      from = Math.max(from, gapB[k]);
    }
    if (from < b) out.push([from, b]);
    return out;
  }

  function drawRuler() {
    const per = (d1 - d0) / plotWidth() * 100;  // ns per 100 px
    const magnitude = Math.pow(10, Math.floor(Math.log10(per)));
    const step = [1, 2, 5, 10].map(m => m * magnitude).find(s => s >= per);
    const digits = Math.max(0, Math.min(9, -Math.floor(Math.log10(step / 1e9))));
    ctx.fillStyle = COLOURS.text; ctx.font = "11px sans-serif"; ctx.textBaseline = "middle";
    let lastText = -1e9;
    for (const [a, b] of segments()) {
      for (let t = Math.ceil(a / step) * step; t <= b; t += step) {
        const x = Math.round(xOf(t)) + 0.5;
        ctx.strokeStyle = COLOURS.grid; ctx.beginPath(); ctx.moveTo(x, RULER_H); ctx.lineTo(x, canvasHeight); ctx.stroke();
        const text = seconds(t, digits);
        if (x > lastText + 4 && x + 2 + ctx.measureText(text).width <= width) lastText = label(text, x, RULER_H / 2, 2);
      }
    }
  }

  function drawFolds() {
    ctx.font = "10px sans-serif"; ctx.textBaseline = "middle";
    for (let k = 0; foldOn && k < gapA.length; k++) {
      const x0 = xOf(gapA[k]), x1 = xOf(gapB[k]);
      if (x1 < LABEL_W || x0 > LABEL_W + plotWidth()) continue;
      ctx.fillStyle = COLOURS.fold; ctx.fillRect(Math.max(x0, LABEL_W), RULER_H, x1 - Math.max(x0, LABEL_W), canvasHeight - RULER_H);
      ctx.strokeStyle = COLOURS.axis; ctx.setLineDash([3, 3]);
      for (const x of [x0, x1]) { ctx.beginPath(); ctx.moveTo(x, RULER_H); ctx.lineTo(x, canvasHeight); ctx.stroke(); }
      ctx.setLineDash([]);
      ctx.fillStyle = COLOURS.axis;
      const text = "⋯ " + duration(gapB[k] - gapA[k]) + " idle";
      if (ctx.measureText(text).width < x1 - x0 + 60) label(text, (x0 + x1) / 2 - ctx.measureText(text).width / 2, canvasHeight - 8, 0);
    }
  }

  function drawExchanges() {
    const top = RULER_H, pw = plotWidth();
    const lo = Math.max(0, firstAtOrAfter(exchangeStart, fromD(d0)) - 1);
    let lastLabel = -1e9, lastX = -1;
    ctx.font = "10px sans-serif"; ctx.textBaseline = "middle";
    const end = fromD(d1);
    for (let n = lo; n < exchanges.length && exchangeStart[n] <= end; n++) {
      const x0 = Math.max(LABEL_W, xOf(exchangeStart[n]));
      const x1 = Math.min(LABEL_W + pw, Math.max(xOf(exchangeEnd[n]), x0 + 3));
      if (x1 < LABEL_W || Math.floor(x1) <= lastX) continue;  // decimated: one per pixel
      lastX = Math.floor(x1);
      ctx.fillStyle = n % 2 ? COLOURS.exchangeB : COLOURS.exchangeA;
      ctx.fillRect(x0, top + 1, x1 - x0, EXCHANGE_H - 2);
      const name = exchangeName(n), w = ctx.measureText(name).width;
      if (x1 - x0 > w + 4 && x0 - lastLabel > w + 4) {
        ctx.fillStyle = COLOURS.text; ctx.fillText(name, x0 + 2, top + EXCHANGE_H / 2);
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
      if (run.t_ns === undefined || toD(run.t_ns) < d0 || toD(run.t_ns) > d1) continue;
      ctx.fillStyle = COLOURS.outcome[run.outcome];
      ctx.fillRect(xOf(run.t_ns) - 1, top + EXCHANGE_H + 1, 3, RUNS_H - 2);
    }
    ctx.fillStyle = COLOURS.text; ctx.font = "11px sans-serif";
    ctx.fillText("exchanges", 2, top + EXCHANGE_H / 2);
    if (campaign) ctx.fillText("faults", 2, top + EXCHANGE_H + RUNS_H / 2);
  }

  function barHeight(lane, size, scale) {
    return Math.max(3, Math.round((lane.height - 6) * (0.25 + 0.75 * Math.log(size + 1) / scale)));
  }

  function drawLanes() {
    const pw = Math.ceil(plotWidth());
    const lo = Math.max(0, firstAtOrAfter(times, fromD(d0)));
    const hi = firstAtOrAfter(times, fromD(d1) + 1);
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
    for (const lane of summaryLanes) for (const [, , largest] of lane.bins) if (largest + 1 > maxSize) maxSize = largest + 1;
    const scale = Math.log(maxSize + 1);
    lanes.forEach((lane, n) => {
      ctx.fillStyle = COLOURS.text; ctx.font = "11px sans-serif"; ctx.textBaseline = "middle";
      ctx.fillText(lane.label, 2, lane.top + lane.height / 2);
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
          if (LABEL_W + col > lastLabel + 8) {
            ctx.fillStyle = COLOURS.text; ctx.font = "10px sans-serif";
            lastLabel = label(name, LABEL_W + col, lane.top + lane.height / 2, 4);
          }
        }
        return;
      }
      const bars = columns[n];
      ctx.fillStyle = COLOURS[lane.name];
      for (let col = 0; col <= pw; col++) {
        if (!bars[col]) continue;
        const h = barHeight(lane, bars[col], scale);
        ctx.fillRect(LABEL_W + col - 1, lane.top + lane.height - 2 - h, 3, h);
      }
    });
    drawSummary(scale);
    drawFrames();
  }

  // Past the detail, the summary's bins (records counted per bin, the
  // largest's size), on a shaded ground that says so.
  const summaryLanes = decimated ? data.summary.lanes : [];
  function drawSummary(scale) {
    if (!decimated) return;
    const binNs = data.summary.bin_ns, right = LABEL_W + plotWidth();
    const from = Math.max(LABEL_W, xOf(detailEnd));
    if (from >= right) return;
    ctx.fillStyle = COLOURS.summary;
    ctx.fillRect(from, RULER_H, right - from, canvasHeight - RULER_H);
    for (const summary of summaryLanes) {
      const lane = lanes[laneIndex.get(summary.channel + "/" + summary.lane)];
      if (!lane) continue;
      for (const [bin, , largest] of summary.bins) {
        const t = bin * binNs;
        if (t + binNs <= detailEnd) continue;
        const x0 = Math.max(from, xOf(t)), x1 = Math.min(right, xOf(t + binNs));
        if (x1 < from || x0 > right) continue;
        ctx.fillStyle = summary.lane === "events" ? COLOURS.axis : COLOURS[summary.lane];
        const h = summary.lane === "events" ? lane.height - 6 : barHeight(lane, largest + 1, scale);
        ctx.fillRect(x0, lane.top + lane.height - 2 - h - (summary.lane === "events" ? 1 : 0), Math.max(x1 - x0, 1), h);
      }
    }
    ctx.fillStyle = COLOURS.axis; ctx.font = "10px sans-serif"; ctx.textBaseline = "top";
    label("summary only: detail ends here", from, RULER_H + 2, 3);
  }

  // A profile's frames: their names over the bars, where there is room.
  const frames = data.frames;  // [t_ns, "tx"|"rx", size, name, channel?]
  const frameTimes = Float64Array.from(frames.map(f => f[0]));
  function drawFrames() {
    if (!frames.length) return;
    const lastLabel = new Map();
    ctx.font = "10px sans-serif"; ctx.textBaseline = "top"; ctx.fillStyle = COLOURS.text;
    const end = fromD(d1);
    for (let n = firstAtOrAfter(frameTimes, fromD(d0)); n < frames.length && frames[n][0] <= end; n++) {
      const f = frames[n], x = xOf(f[0]);
      const lane = lanes[laneIndex.get((f.length > 4 ? f[4] : data.channels[0].id) + "/" + f[1])];
      if (!lane) continue;
      const text = String(f[3]).split(" ")[0];
      if (x - (lastLabel.get(lane) || -1e9) < 6) continue;
      lastLabel.set(lane, label(text, x, lane.top + 1, 3));
    }
  }

  function drawMarks() {
    const marks = [[selected, COLOURS.selected, null], [mismatchRecord, COLOURS.mismatch, "mismatch"],
      [cursors.A, COLOURS.cursorA, "A"], [cursors.B, COLOURS.cursorB, "B"]];
    for (const [i, colour, text] of marks) {
      if (i < 0 || toD(times[i]) < d0 || toD(times[i]) > d1) continue;
      const x = Math.round(xOf(times[i])) + 0.5;
      ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.beginPath();
      if (text === "A" || text === "B") ctx.setLineDash([5, 3]);
      ctx.moveTo(x, RULER_H); ctx.lineTo(x, canvasHeight); ctx.stroke(); ctx.lineWidth = 1; ctx.setLineDash([]);
      if (text) { ctx.fillStyle = colour; ctx.font = "bold 11px sans-serif"; ctx.textBaseline = "top"; label(text, x, canvasHeight - 14, 4); }
    }
  }

  let pending = false;
  function draw() {
    pending = false;
    ctx.clearRect(0, 0, width, canvasHeight);
    drawFolds();
    drawRuler();
    drawExchanges();
    drawLanes();
    drawMarks();
    const [a, b] = [fromD(d0), fromD(d1)];
    $("status").textContent = seconds(a, 6) + " … " + seconds(b, 6);
    canvas.dataset.from = String(a); canvas.dataset.to = String(b);
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
    if (several) line += "  channel " + channelName.get(channelOf(i));
    if (exchangeOf[i] >= 0) line += "  exchange " + exchanges[exchangeOf[i]][0];
    if (i === mismatchRecord) line += "  MISMATCH";
    return line;
  }
  function showRecord(i) {
    const pane = $("hex");
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
    if (reveal && i >= 0 && (toD(times[i]) < d0 || toD(times[i]) > d1)) {
      const half = (d1 - d0) / 2, d = toD(times[i]); d0 = d - half; d1 = d + half;
    }
    showRecord(i);
    if (tableReady) showTableAt(i);
    redraw();
  }

  // ---- pointer and keys
  function recordAt(x, yy) {
    const lane = lanes.find(l => yy >= l.top && yy < l.top + l.height);
    if (!lane) return -1;
    const t = tOf(x), lo = tOf(x - 5), hi = tOf(x + 5);
    let best = -1, bestDistance = Infinity;
    for (let i = Math.max(0, firstAtOrAfter(times, lo)); i < count && times[i] <= hi; i++) {
      if (lanes[laneOf(i)] !== lane) continue;
      const distance = Math.abs(times[i] - t);
      if (distance < bestDistance) { best = i; bestDistance = distance; }
    }
    return best;
  }
  let drag = null;
  const box = canvas.parentElement;
  canvas.addEventListener("mousedown", event => { drag = { x: event.offsetX, d0, d1, moved: false }; box.classList.add("dragging"); });
  window.addEventListener("mouseup", event => {
    if (drag && !drag.moved && event.target === canvas) {
      const i = recordAt(event.offsetX, event.offsetY);
      if (event.shiftKey) setCursor("B", i); else if (event.altKey) setCursor("A", i); else select(i, false);
    }
    drag = null; box.classList.remove("dragging");
  });
  canvas.addEventListener("mousemove", event => {
    if (drag) {
      const dx = event.offsetX - drag.x;
      if (Math.abs(dx) > 2) drag.moved = true;
      const dd = dx / plotWidth() * (drag.d1 - drag.d0);
      d0 = drag.d0 - dd; d1 = drag.d1 - dd; redraw();
      return;
    }
    const i = recordAt(event.offsetX, event.offsetY);
    if (i !== hovered) { hovered = i; showRecord(i >= 0 ? i : selected); }
  });
  canvas.addEventListener("mouseleave", () => { hovered = -1; showRecord(selected); });
  function zoom(factor, x) {
    const d = d0 + ((x === undefined ? LABEL_W + plotWidth() / 2 : x) - LABEL_W) / plotWidth() * (d1 - d0);
    const across = Math.max((d1 - d0) * factor, 1000);  // no closer than 1 µs across
    const share = (d - d0) / (d1 - d0);
    d0 = d - share * across; d1 = d0 + across; redraw();
  }
  canvas.addEventListener("wheel", event => { event.preventDefault(); zoom(Math.pow(1.0015, event.deltaY), event.offsetX); }, { passive: false });
  function fit() { const whole = toD(span); d0 = -whole * 0.01; d1 = whole * 1.01; redraw(); }
  $("fit").addEventListener("click", fit);
  $("zoom-in").addEventListener("click", () => zoom(0.5));
  $("zoom-out").addEventListener("click", () => zoom(2));
  $("fold").addEventListener("click", () => {
    const [a, b] = [fromD(d0), fromD(d1)];
    foldOn = !foldOn; $("fold").setAttribute("aria-pressed", String(foldOn));
    d0 = toD(a); d1 = toD(b); redraw();
  });
  window.addEventListener("keydown", event => {
    if (event.target instanceof HTMLInputElement || event.target instanceof HTMLSelectElement) return;
    if (event.key === "+" || event.key === "=") zoom(0.5);
    else if (event.key === "-") zoom(2);
    else if (event.key === "Home") fit();
    else if (event.key === "ArrowRight" && selected + 1 < count) select(selected + 1, true);
    else if (event.key === "ArrowLeft" && selected > 0) select(selected - 1, true);
    else if (event.key === "a" || event.key === "b") setCursor(event.key.toUpperCase(), selected);
    else if (event.key === "n") searchNext();
  });
  window.addEventListener("resize", () => { resize(); redraw(); });

  // ---- two measurement cursors: the time between two records
  function setCursor(which, i) {
    cursors[which] = i;
    const box = $("cursors"), parts = [];
    for (const name of ["A", "B"]) {
      const at = cursors[name];
      parts.push(name + ": " + (at < 0 ? "—" : "record " + at + " at +" + seconds(times[at])));
      box.dataset[name.toLowerCase()] = String(at);
    }
    if (cursors.A >= 0 && cursors.B >= 0) {
      const delta = times[cursors.B] - times[cursors.A];
      parts.push("Δt B−A = " + duration(delta));
      box.dataset.deltaNs = String(delta);
    } else box.removeAttribute("data-delta-ns");
    box.textContent = parts.join("   ");
    redraw();
  }
  $("cursor-a").addEventListener("click", () => setCursor("A", selected));
  $("cursor-b").addEventListener("click", () => setCursor("B", selected));

  // ---- search: the records whose bytes hold the text (\n, \r, \t, \xNN
  // written as in the lists); within one record, not across records.
  function queryBytes(text) {
    const out = [];
    for (let j = 0; j < text.length; j++) {
      const c = text[j];
      if (c === "\\" && j + 1 < text.length) {
        const e = text[j + 1];
        if (e === "n") { out.push(10); j++; continue; }
        if (e === "r") { out.push(13); j++; continue; }
        if (e === "t") { out.push(9); j++; continue; }
        if (e === "\\") { out.push(92); j++; continue; }
        if (e === "x" && /^[0-9a-fA-F]{2}$/.test(text.slice(j + 2, j + 4))) { out.push(parseInt(text.slice(j + 2, j + 4), 16)); j += 3; continue; }
      }
      const code = c.charCodeAt(0);
      if (code < 0x80) out.push(code); else for (const b of new TextEncoder().encode(c)) out.push(b);
    }
    return out;
  }
  function holds(i, needle) {
    const hay = bytesOf(i);
    outer: for (let at = 0; at + needle.length <= hay.length; at++) {
      for (let j = 0; j < needle.length; j++) if (hay[at + j] !== needle[j]) continue outer;
      return true;
    }
    return false;
  }
  let matches = [], matchQuery = null;
  function searchNext() {
    const text = $("search").value;
    const status = $("search-status");
    if (!text) { matches = []; status.textContent = ""; status.dataset.matches = "0"; return; }
    if (text !== matchQuery) {
      const needle = queryBytes(text);
      matches = [];
      for (let i = 0; i < count; i++) if (holds(i, needle)) matches.push(i);
      matchQuery = text;
    }
    status.dataset.matches = String(matches.length);
    if (!matches.length) { status.textContent = "not found"; return; }
    let k = firstAtOrAfter(matches, selected + 1);
    if (k >= matches.length) k = 0;
    status.textContent = "match " + (k + 1) + " of " + matches.length;
    status.dataset.match = String(k + 1);
    select(matches[k], true);
  }
  $("search").addEventListener("keydown", event => { if (event.key === "Enter") searchNext(); });
  $("search-next").addEventListener("click", searchNext);

  // ---- follow stream: a channel's tx and rx as text, in recorded order,
  // each run of one direction one block (Wireshark's "Follow stream").
  function escapeText(bytes) {
    let text = "";
    for (const b of bytes) text += b === 10 ? "\\n" : b === 13 ? "\\r" : b >= 0x20 && b < 0x7f ? String.fromCharCode(b) : "\\x" + b.toString(16).padStart(2, "0");
    return text;
  }
  function streamText(bytes) {  // line ends kept as line ends
    let text = "";
    for (const b of bytes) text += b === 10 ? "\n" : b === 13 ? "" : b === 9 ? "\t" : b >= 0x20 && b < 0x7f ? String.fromCharCode(b) : "\\x" + b.toString(16).padStart(2, "0");
    return text;
  }
  function followStream() {
    const channel = selected >= 0 ? channelOf(selected) : data.channels[0].id;
    const pane = $("stream-text"), section = $("stream");
    pane.textContent = "";
    let block = null, blockKind = -1, chars = 0, blocks = 0, truncated = false;
    const bytesOfKind = { tx: 0, rx: 0 };
    for (let i = 0; i < count; i++) {
      const k = kinds[i];
      if ((k !== TX && k !== RX) || channelOf(i) !== channel) continue;
      bytesOfKind[kindNames[k]] += rec.size[i];
      if (chars >= STREAM_CHARS) { truncated = true; continue; }
      if (k !== blockKind) {
        block = document.createElement("span");
        block.className = "stream-" + kindNames[k];
        block.dataset.record = String(i);
        pane.appendChild(block);
        blockKind = k; blocks++;
      }
      const text = streamText(bytesOf(i));
      block.textContent += text;
      chars += text.length;
    }
    $("stream-title").textContent = "Follow stream" + (several ? " of channel " + channelName.get(channel) : "") +
      ": tx (host to device) " + bytesOfKind.tx + " bytes, rx (device to host) " + bytesOfKind.rx + " bytes, " +
      blocks + " turns" + (truncated ? "; the first " + STREAM_CHARS + " characters shown" : "");
    section.hidden = false;
    section.dataset.channel = String(channel);
    section.dataset.blocks = String(blocks);
  }
  $("follow").addEventListener("click", followStream);
  $("stream-close").addEventListener("click", () => { $("stream").hidden = true; });
  $("stream-text").addEventListener("click", event => {
    const span = event.target.closest("span[data-record]");
    if (span) select(Number(span.dataset.record), true);
  });

  // ---- the record table: filter, sort, Δt and latency
  let tableReady = false;
  let shown = new Int32Array(0);  // the rows, in the table's order
  let deltaOf = new Float64Array(0);  // Δt from the previous record the filter keeps
  let tablePage = 0, sortKey = "#", sortUp = true;
  function latencyOfRecord(i) {
    const n = exchangeOf[i];
    return n >= 0 && exchanges[n][1] === i && exchanges[n][11] !== null ? exchanges[n][11] : null;
  }
  const COLUMNS = {
    "#": i => i, "time": i => times[i], "Δt": i => deltaOf[i], "channel": i => channelName.get(channelOf(i)) || "",
    "kind": i => kindNames[kinds[i]], "bytes": i => rec.size[i], "exchange": i => exchangeOf[i],
    "latency": i => latencyOfRecord(i), "data": i => escapeText(bytesOf(i).subarray(0, 48)),
  };
  function cellsOf(i) {
    const latency = latencyOfRecord(i);
    return [String(i), "+" + seconds(times[i]), Number.isNaN(deltaOf[i]) ? "" : "+" + duration(deltaOf[i]),
      channelName.get(channelOf(i)) || "", kindNames[kinds[i]], String(rec.size[i]),
      exchangeOf[i] >= 0 ? exchangeName(exchangeOf[i]) : "", latency === null ? "" : duration(latency),
      escapeText(bytesOf(i).subarray(0, 48)) + (rec.size[i] > 48 ? "…" : "")];
  }
  function applyFilter() {
    const kind = $("kind-filter").value, channel = $("channel-filter").value, text = $("text-filter").value;
    const needle = text ? queryBytes(text) : null;
    const kept = [];
    deltaOf = new Float64Array(count).fill(NaN);
    let previous = -1;
    for (let i = 0; i < count; i++) {
      const k = kindNames[kinds[i]];
      if (kind === "tx" || kind === "rx" ? k !== kind : kind === "events" ? (kinds[i] === TX || kinds[i] === RX) : kind !== "" && k !== kind) continue;
      if (channel !== "" && String(channelOf(i)) !== channel) continue;
      if (needle && !holds(i, needle)) continue;
      if (previous >= 0) deltaOf[i] = times[i] - times[previous];
      previous = i;
      kept.push(i);
    }
    shown = Int32Array.from(kept);
    sortRows();
  }
  function sortRows() {
    const key = COLUMNS[sortKey], sign = sortUp ? 1 : -1;
    if (sortKey !== "#" || !sortUp) {
      const rows = Array.from(shown), values = new Map(rows.map(i => [i, key(i)]));
      rows.sort((a, b) => {
        const va = values.get(a), vb = values.get(b);
        const na = va === null || (typeof va === "number" && Number.isNaN(va)), nb = vb === null || (typeof vb === "number" && Number.isNaN(vb));
        if (na || nb) return na === nb ? a - b : na ? 1 : -1;  // blanks last
        return (va < vb ? -1 : va > vb ? 1 : a - b) * sign;
      });
      shown = Int32Array.from(rows);
    }
    tablePage = 0;
    renderTable();
  }
  function renderTable() {
    const table = $("record-table"), body = table.tBodies[0];
    body.textContent = "";
    const from = tablePage * TABLE_ROWS, to = Math.min(shown.length, from + TABLE_ROWS);
    for (let r = from; r < to; r++) {
      const i = shown[r], tr = body.insertRow();
      tr.dataset.record = String(i);
      tr.className = "kind-" + (kinds[i] === TX ? "tx" : kinds[i] === RX ? "rx" : "event") + (i === selected ? " selected" : "");
      for (const cell of cellsOf(i)) tr.insertCell().textContent = cell;
    }
    for (const th of table.tHead.rows[0].cells) th.dataset.sorted = th.dataset.key === sortKey ? (sortUp ? "up" : "down") : "";
    table.dataset.rows = String(shown.length);
    table.dataset.sort = sortKey + ":" + (sortUp ? "up" : "down");
    $("rows-shown").textContent = shown.length ? "rows " + (from + 1) + "–" + to + " of " + shown.length : "no record matches";
    $("rows-prev").disabled = tablePage === 0; $("rows-next").disabled = to >= shown.length;
  }
  function showTableAt(i) {
    const r = shown.indexOf(i);
    if (r >= 0) tablePage = Math.floor(r / TABLE_ROWS);
    renderTable();
  }
  function buildTable() {
    const head = $("record-table").tHead.rows[0];
    for (const key of Object.keys(COLUMNS)) {
      const th = document.createElement("th");
      th.textContent = key; th.dataset.key = key; th.title = "sort by " + key + " (again: the other way)";
      head.appendChild(th);
    }
    head.addEventListener("click", event => {
      const th = event.target.closest("th[data-key]");
      if (!th) return;
      if (sortKey === th.dataset.key) sortUp = !sortUp; else { sortKey = th.dataset.key; sortUp = true; }
      sortRows();
    });
    const kindFilter = $("kind-filter");
    for (const name of ["tx", "rx", "events"].concat(kindNames.filter((k, n) => n !== TX && n !== RX && kinds.includes(n)))) {
      const option = document.createElement("option"); option.value = name; option.textContent = name; kindFilter.appendChild(option);
    }
    const channelFilter = $("channel-filter");
    channelFilter.hidden = !several;
    for (const c of data.channels) {
      const option = document.createElement("option"); option.value = String(c.id); option.textContent = c.name; channelFilter.appendChild(option);
    }
    for (const id of ["kind-filter", "channel-filter"]) $(id).addEventListener("change", applyFilter);
    $("text-filter").addEventListener("input", applyFilter);
    $("rows-prev").addEventListener("click", () => { tablePage--; renderTable(); });
    $("rows-next").addEventListener("click", () => { tablePage++; renderTable(); });
    $("record-table").tBodies[0].addEventListener("click", event => {
      const row = event.target.closest("tr[data-record]");
      if (row) select(Number(row.dataset.record), true);
    });
    tableReady = true;
    applyFilter();
  }

  // ---- the header, the legend, the notes and the lists (after the first paint)
  function summary() {
    const h = data.session.header, total = data.session.records;
    const parts = [total + " records", exchanges.length + " exchanges" + (decimated ? " in detail" : ""), seconds(lastT, 3)];
    if (h.port_type) parts.push(h.port_type + ": " + (h.port_options || ""));
    if (data.session.profile) parts.push("profile " + data.session.profile + " (" + frames.length + " frames)");
    if (h.start_utc) parts.push("started " + h.start_utc);
    $("summary").textContent = parts.join(" · ");
    const meta = Object.entries(h.metadata || {}).sort((a, b) => a[0] < b[0] ? -1 : a[0] > b[0] ? 1 : 0);
    $("meta").textContent = meta.length ? "meta: " + meta.map(([k, v]) => k + "=" + (typeof v === "string" ? v : JSON.stringify(v))).join(" · ") : "";
    const notes = $("notes");
    function note(className, text) { const div = document.createElement("div"); div.className = className; div.textContent = text; notes.appendChild(div); }
    if (decimated) note("warning decimated", decimated.message);
    if (data.session.damage) note("damage", "Damaged: " + data.session.damage + " (the records before it are shown)");
    if (data.mismatch) note("mismatch", "Mismatch (record " + mismatchRecord + ", tx byte " + data.mismatch.tx_offset + "): the client wrote bytes that " + data.mismatch.original + " does not hold\nexpected: " + data.mismatch.expected + "\nactual:   " + data.mismatch.actual);
    if (campaign && !campaign.same_session) note("warning", "The campaign " + campaign.path + " ran on a session whose bytes differ from this one's.");
  }
  function legend() {
    const entries = [["tx: host to device", COLOURS.tx], ["rx: device to host", COLOURS.rx]];
    const present = new Set(kinds);
    kindNames.forEach((name, n) => { if (n !== TX && n !== RX && present.has(n)) entries.push([name, COLOURS.event[name] || COLOURS.axis]); });
    entries.push(["exchange", COLOURS.exchangeB], ["selected", COLOURS.selected], ["cursor A", COLOURS.cursorA], ["cursor B", COLOURS.cursorB]);
    if (gapA.length) entries.push(["idle gap, folded", COLOURS.fold]);
    if (decimated) entries.push(["summary only", COLOURS.summary]);
    if (data.mismatch) entries.push(["mismatch", COLOURS.mismatch]);
    if (campaign) for (const outcome of Object.keys(OUTCOME_RANK)) entries.push(["fault run: " + outcome, COLOURS.outcome[outcome]]);
    const box = $("legend");
    for (const [name, colour] of entries) {
      const item = document.createElement("span"); item.className = "legend-item"; item.dataset.name = name;
      const swatch = document.createElement("span"); swatch.className = "swatch"; swatch.style.background = colour;
      item.appendChild(swatch); item.appendChild(document.createTextNode(name)); box.appendChild(item);
    }
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
    $("lists").appendChild(section);
  }
  function lists() {
    if (campaign) {
      table("runs", "Fault campaign " + campaign.path, ["case", "fault", "outcome", "exit", "seconds", "exchange", "reproduce"],
        campaign.runs.slice(0, LIST_ROWS).map(run => ({
          record: run.exchange !== undefined ? exchanges[run.exchange][1] : -1, className: "outcome-" + run.outcome,
          cells: [run.case, run.kind + "@" + run.where, run.outcome, run.exit === null ? "" : run.exit, run.seconds.toFixed(3),
            run.exchange !== undefined ? "#" + exchanges[run.exchange][0] : "", run.repro] })), campaign.runs.length);
    }
    table("exchange-list", "Exchanges", ["#", "channel", "time", "request", "response bytes", "latency", "faults"],
      exchanges.slice(0, LIST_ROWS).map((e, n) => {
        let request = "";
        for (let i = e[1]; i < e[2] && i < count && request.length < 60; i++) if (kinds[i] === TX) request += escapeText(bytesOf(i));
        const runs = runsByExchange.get(n) || [];
        const worst = worstOutcome(runs);
        return { record: e[1], className: worst ? "outcome-" + worst : "",
          cells: ["#" + e[0], channelName.get(e[10]) || "", "+" + seconds(exchangeStart[n]), request.slice(0, 60), e[8],
            e[11] === null ? "" : duration(e[11]), runs.map(run => run.kind + ":" + run.outcome).join(" ")] };
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
    $("lists").addEventListener("click", event => {
      const row = event.target.closest("tr[data-record]");
      if (row) select(Number(row.dataset.record), true);
    });
    document.documentElement.dataset.listsReady = "true";
  }

  // Where things are drawn, for tests that point at them (CSS pixels from
  // the canvas's left and top edges; times are session times).
  window.wiretapeView = {
    xOf: xOf,
    plotLeft: LABEL_W,
    laneMiddle: name => { const lane = lanes.find(l => l.name === name); return lane.top + lane.height / 2; },
    range: () => [fromD(d0), fromD(d1)],
    folds: () => gapA.map((a, k) => [a, gapB[k]]),
    select: i => select(i, true),
  };

  // ---- start: the first paint, then the rest
  resize();
  fit(); pending = false;
  summary();
  const wanted = /(?:^#|&)record=(\d+)/.exec(location.hash);
  if (wanted && Number(wanted[1]) < count) {
    const i = Number(wanted[1]);
    const around = Math.max((d1 - d0) / 200, 1e6);
    d0 = toD(times[i]) - around; d1 = toD(times[i]) + around;
    selected = i; showRecord(i);
  }
  draw();
  requestAnimationFrame(() => {
    document.documentElement.dataset.firstPaintMs = performance.now().toFixed(1);
    setTimeout(() => { legend(); lists(); buildTable(); document.documentElement.dataset.ready = "true"; }, 0);
  });
})();
