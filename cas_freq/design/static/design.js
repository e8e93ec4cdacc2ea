// cas-freq design: the page's controls, requests and plots (uPlot, vendored and served by the
// page's own server: no network but that server). window.casDesign.setValue(key, text) is the one way a value
// changes (sliders, typed entries, undo/redo, the URL's #key=value&... all call it); it
// returns a promise of the state shown after it.
"use strict";
(function () {
  const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"];
  const DEBOUNCE_MS = 60;
  // a session per page load (a duplicated tab or a reload is a session of its own; the URL's
  // #key=value&... carries the values over)
  const session = Math.random().toString(36).slice(2, 12) + Date.now().toString(36);

  let controls = [];
  let values = {};          // key -> text, the values asked for (not yet accepted maybe)
  let accepted = {};        // the values of the state shown
  const undo = [], redo = [];
  let seq = 0, timer = null, waiting = [];
  let shown = null, previous = null, variantState = null;

  const $ = (id) => document.getElementById(id);
  const el = (tag, attrs, text) => {
    const node = document.createElement(tag);
    Object.entries(attrs || {}).forEach(([k, v]) => node.setAttribute(k, v));
    if (text !== undefined) node.textContent = text;
    return node;
  };

  // The per-launch token of the URL cas-freq design printed: the server answers no API
  // request without it (a page of another site cannot send it).
  const token = new URLSearchParams(location.search).get("token") || "";
  async function api(path, body) {
    const headers = {"X-Cas-Freq-Token": token};
    const options = body === undefined ? {headers} : {method: "POST",
      headers: Object.assign(headers, {"Content-Type": "application/json"}),
      body: JSON.stringify(body)};
    const response = await fetch(path, options);
    const data = await response.json();
    if (!response.ok) {
      const error = new Error(data.error || response.statusText);
      error.status = response.status;
      throw error;
    }
    return data;
  }

  // ---- controls ---------------------------------------------------------------------------
  // A slider's log scale spans the magnitudes c.lower..c.upper (the server's controls()):
  // "log" on one side of zero (c.sign), "zero-log" with zero at its start (a key at zero),
  // "signed-log" with zero at its centre and both signs either side.
  const SLIDER_STEPS = 1000;
  function logPosition(c, magnitude) {  // 0..1 along the log scale
    const p = Math.log(magnitude / c.lower) / Math.log(c.upper / c.lower);
    return Number.isNaN(p) ? 0 : Math.min(1, Math.max(0, p));  // NaN: a magnitude < 0
  }
  function toSlider(c, value) {
    if (c.slider === "log") return Math.round(logPosition(c, value * c.sign) * SLIDER_STEPS);
    if (!(value !== 0 && (c.slider === "signed-log" || value > 0))) return 0;
    return Math.sign(value) *
      (1 + Math.round(logPosition(c, Math.abs(value)) * (SLIDER_STEPS - 1)));
  }
  function fromSlider(c, position) {
    if (c.slider === "log") {
      return c.sign * c.lower * Math.pow(c.upper / c.lower, position / SLIDER_STEPS);
    }
    if (position === 0) return 0;
    return Math.sign(position) * c.lower *
      Math.pow(c.upper / c.lower, (Math.abs(position) - 1) / (SLIDER_STEPS - 1));
  }
  const groups = {};
  function buildControls() { controls.forEach(addControl); }
  function addControl(c) {
    const box = $("controls");
    if (!groups[c.group]) {
      groups[c.group] = el("fieldset");
      groups[c.group].appendChild(el("legend", {}, c.group.replace(/_/g, " ")));
      box.appendChild(groups[c.group]);
    }
    const row = el("div", {class: "control", title: c.meaning});
    const label = el("label");
    label.appendChild(el("span", {class: "name"}, c.key.split(".").slice(1).join(".") + " "));
    row.appendChild(label);
    if (c.choices) {  // a word of a few (sampling.method): a choice, no slider
      const choice = el("select", {id: "entry-" + c.key});
      c.choices.forEach((word) => choice.appendChild(el("option", {value: word}, word)));
      choice.value = c.value;
      label.appendChild(choice);
      choice.addEventListener("change", () => setValue(c.key, choice.value));
    } else {
      const entry = el("input", {type: "text", size: 10, id: "entry-" + c.key});
      entry.value = formatValue(c.value);
      label.appendChild(entry);
      label.appendChild(el("span", {}, " " + c.unit));
      const slider = el("input", {type: "range", min: c.slider === "signed-log" ?
        -SLIDER_STEPS : 0, max: SLIDER_STEPS, id: "slider-" + c.key});
      slider.value = toSlider(c, c.value);
      row.appendChild(slider);
      slider.addEventListener("input", () =>
        setValue(c.key, formatValue(fromSlider(c, +slider.value))));
      entry.addEventListener("change", () => setValue(c.key, entry.value));
    }
    row.appendChild(el("span", {class: "error", id: "error-" + c.key}));
    groups[c.group].appendChild(row);
  }
  async function addKey() {
    const key = $("add-key").value.trim();
    $("error-add").textContent = "";
    if (controls.some((c) => c.key === key)) return;
    try {
      const c = await api("/api/control", {session, key});
      controls.push(c);
      addControl(c);
      showValues(values);
    } catch (error) {
      $("error-add").textContent = String(error.message || error);
    }
  }
  function formatValue(v) {
    return typeof v === "number" ? Number(v.toPrecision(4)).toString() : String(v);
  }
  function showValues(which) {
    controls.forEach((c) => {
      const text = which[c.key] !== undefined ? which[c.key] : formatValue(c.value);
      $("entry-" + c.key).value = text;
      const number = Number(text);
      if (!c.choices && text.trim() !== "" && Number.isFinite(number)) {
        $("slider-" + c.key).value = toSlider(c, number);
      }
    });
  }

  // ---- requests: debounced, only the newest counts ----------------------------------------
  let lastChange = {key: null, time: 0};
  function setValue(key, text, record) {
    // one undo step per gesture: a slider drag's many moves of one key within a moment are one
    const now = Date.now();
    const sameGesture = lastChange.key === key && now - lastChange.time < 700;
    lastChange = {key, time: now};
    if (record !== false && !sameGesture) {
      undo.push(Object.assign({}, values));
      redo.length = 0;
    }
    values = Object.assign({}, values, {[key]: String(text)});
    showValues(values);
    return schedule();
  }
  function setValues(all) {
    values = Object.assign({}, all);
    showValues(values);
    return schedule();
  }
  function schedule() {
    clearTimeout(timer);
    timer = setTimeout(send, DEBOUNCE_MS);
    return new Promise((resolve) => waiting.push(resolve));
  }
  async function send() {
    const mine = ++seq;
    setStatus("computing", "busy");
    let data;
    try {
      data = await api("/api/state", {session, seq: mine, values,
        step: $("step").value, nonlinear: $("nonlinear").checked});
    } catch (error) {
      data = {errors: {_: String(error.message || error)}, seq: mine};
    }
    if (data.stale || mine !== seq) return;   // a newer request is on its way
    clearErrors();
    if (data.errors) {
      Object.entries(data.errors).forEach(([key, message]) => {
        const spot = $("error-" + key) || ($("status"));
        spot.textContent = message;
      });
      if (!$("error-" + Object.keys(data.errors)[0])) setStatus(Object.values(data.errors)[0], "bad");
      else setStatus("bad input", "bad");
    } else {
      accepted = Object.assign({}, values);
      previous = shown;
      shown = data;
      render();
      setStatus(`${data.stability} · ${Object.keys(accepted).length} changed key(s)`, "");
      history.replaceState(null, "", "#" + Object.entries(accepted)
        .map(([k, v]) => encodeURIComponent(k) + "=" + encodeURIComponent(v)).join("&"));
    }
    document.body.dataset.seq = String(mine);
    const done = waiting; waiting = [];
    done.forEach((resolve) => resolve(data));
  }
  function clearErrors() {
    document.querySelectorAll(".error").forEach((node) => { node.textContent = ""; });
  }
  function setStatus(text, kind) {
    const node = $("status");
    node.textContent = text;
    node.className = "status " + (kind || "");
  }

  // ---- plots: uPlot (vendored in static/vendor/uplot, served by the page's own server) -----
  // Every chart is uPlot's faceted mode (mode 2): each series carries its own x, so the
  // previous state and the variant (each on its own frequency grid) and the Nichols chart
  // (phase, not monotonic) are series like the others. Marker lines, their labels and the
  // shaded spans are drawn by the chart's hooks, in the chart's scales.
  const HEIGHT = 220;
  const charts = {};  // name -> the uPlot instance shown (replaced at each render)
  const finite = (v) => v !== null && v !== undefined && Number.isFinite(v);

  // [x, y] of a series for uPlot: x kept where it can be drawn (> 0 on a log axis), y null
  // where not finite (a gap: above a sampled loop's Nyquist frequency)
  function xy(s, xlog) {
    const x = [], y = [];
    s.x.forEach((xv, i) => {
      if (!finite(xv) || (xlog && xv <= 0)) return;
      x.push(xv);
      y.push(finite(s.y[i]) ? s.y[i] : null);
    });
    return [x, y];
  }
  // the scale's range: the data's (and the lines', for the y axis) within clip, padded 5 %
  function range(lines, clip, pad) {
    return (u, min, max) => {
      lines.forEach((v) => { if (finite(v)) { min = Math.min(min, v); max = Math.max(max, v); } });
      if (clip) { min = Math.max(min, clip[0]); max = Math.min(max, clip[1]); }
      if (!finite(min) || !finite(max)) { min = clip ? clip[0] : 0; max = clip ? clip[1] : 1; }
      if (max - min < 1e-9) { min -= 1; max += 1; }
      const margin = pad ? 0.05 * (max - min) : 0;
      return [min - margin, max + margin];
    };
  }
  // spec: {title, xlog, xlabel, ylabel, series: [{x, y, color, faint, dash, label, points}],
  //        vlines: [{x, color, label, dash, row}], hlines: [{y, color, dash}],
  //        bars: [{x, y0, y1, color}] (a margin), spans: [{from, to, color}] (shaded),
  //        yclip: [lo, hi], xclip: [lo, hi], xsorted (x ascending in every series)}
  function chart(name, spec) {
    if (charts[name]) charts[name].destroy();
    const px = uPlot.pxRatio;
    const inPlot = (u, x) => finite(x) && x >= u.scales.x.min && x <= u.scales.x.max;
    const X = (u, x) => u.valToPos(x, "x", true), Y = (u, y) => u.valToPos(y, "y", true);
    const line = (u, x0, y0, x1, y1, color, dash) => {
      const ctx = u.ctx;
      ctx.save();
      ctx.strokeStyle = color; ctx.lineWidth = px;
      ctx.setLineDash((dash || []).map((d) => d * px));
      ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
      ctx.restore();
    };
    const under = (u) => {  // the shaded spans, under the grid and the curves
      const {top, height} = u.bbox, ctx = u.ctx;
      (spec.spans || []).forEach((b) => {
        const a = X(u, Math.max(b.from, u.scales.x.min)), z = X(u, Math.min(b.to, u.scales.x.max));
        if (!(z >= a)) return;
        ctx.save();
        ctx.fillStyle = b.color; ctx.globalAlpha = 0.15;
        ctx.fillRect(a, top, Math.max(z - a, px), height);
        ctx.restore();
      });
    };
    const over = (u) => {  // the marker lines and their labels
      const {left, top, width, height} = u.bbox, ctx = u.ctx;
      (spec.hlines || []).forEach((h) => {
        if (h.y >= u.scales.y.min && h.y <= u.scales.y.max) {
          line(u, left, Y(u, h.y), left + width, Y(u, h.y), h.color, h.dash);
        }
      });
      (spec.bars || []).forEach((b) => {
        if (!inPlot(u, b.x)) return;
        const y0 = Math.min(Math.max(b.y0, u.scales.y.min), u.scales.y.max);
        const y1 = Math.min(Math.max(b.y1, u.scales.y.min), u.scales.y.max);
        ctx.save();
        ctx.strokeStyle = b.color; ctx.lineWidth = 3 * px; ctx.lineCap = "butt";
        ctx.beginPath(); ctx.moveTo(X(u, b.x), Y(u, y0)); ctx.lineTo(X(u, b.x), Y(u, y1));
        ctx.stroke(); ctx.restore();
      });
      (spec.vlines || []).forEach((v) => {
        if (!inPlot(u, v.x)) return;
        const x = X(u, v.x);
        line(u, x, top, x, top + height, v.color, v.dash || [4, 3]);
        if (!v.label) return;
        ctx.save();
        ctx.fillStyle = v.color; ctx.font = `${11 * px}px sans-serif`; ctx.textBaseline = "top";
        // right of the line, or left of it where the label would leave the plot
        const right = x + (3 * px) + ctx.measureText(v.label).width <= left + width;
        ctx.textAlign = right ? "left" : "right";
        ctx.fillText(v.label, x + (right ? 3 : -3) * px, top + (3 + 13 * (v.row || 0)) * px);
        ctx.restore();
      });
    };
    const series = spec.series.map((s) => ({
      label: s.label, stroke: s.color, width: s.faint ? 1 : 1.6, alpha: s.faint ? 0.3 : 1,
      dash: s.dash, points: s.points ? {show: true, size: 6, fill: s.color, stroke: s.color}
        : {show: false},
      paths: s.points ? () => null : undefined,
      facets: [{scale: "x", auto: true, sorted: spec.xsorted ? 1 : 0}, {scale: "y", auto: true}],
    }));
    const box = $("figures");
    const opts = {
      mode: 2, title: spec.title, width: Math.max(360, Math.min(box.clientWidth - 8, 760)),
      height: HEIGHT, cursor: {points: {show: false}},
      legend: {live: false, markers: {dash: (u, i) => u.series[i].dash ? "dashed" : "solid"}},
      scales: {
        x: {time: false, distr: spec.xlog ? 3 : 1, log: 10,
            range: spec.xlog ? undefined : range([], spec.xclip, false)},
        y: {range: range((spec.hlines || []).map((h) => h.y), spec.yclip, true)},
      },
      axes: [{label: spec.xlabel, size: 34, labelSize: 16},
             {label: spec.ylabel, size: 48, labelSize: 16}],
      series: [{}, ...series],
      hooks: {drawClear: [under], draw: [over]},
    };
    const holder = el("div", {class: "chart", id: "chart-" + name});
    const u = new uPlot(opts, [null, ...spec.series.map((s) => xy(s, spec.xlog))], holder);
    charts[name] = u;
    return holder;
  }

  // ---- rendering --------------------------------------------------------------------------
  function faint(state) { return $("overlay").checked && state ? state : null; }
  function text(t) { return t === null || t === undefined ? "–" : t; }

  function render() {
    const s = shown, p = faint(previous), v = $("compare").checked ? variantState : null;
    renderMargins(s);
    const DASH = [6, 3];
    const mag = [], phase = [], vm = [], vp = [], sm = [], sp = [], nichols = [];
    s.loops.forEach((loop, k) => {
      const color = COLORS[k % COLORS.length];
      mag.push({x: s.omega_rad_s, y: loop.magnitude_db, color,
                label: `${loop.symbol} (broken at ${loop.breaks_at})`});
      phase.push({x: s.omega_rad_s, y: loop.phase_deg, color, label: loop.symbol});
      nichols.push({x: loop.phase_deg, y: loop.magnitude_db, color, label: loop.symbol});
      // the same loop in the previous state (faint) and in the variant (dashed)
      [[p, {faint: true}, "previous"], [v, {dash: DASH}, "variant"]].forEach(([other, look, name]) => {
        const same = other && other.loops.find((l) => l.name === loop.name);
        if (!same) return;
        const label = `${loop.symbol} ${name}`;
        mag.push({x: other.omega_rad_s, y: same.magnitude_db, color, ...look, label});
        phase.push({x: other.omega_rad_s, y: same.phase_deg, color, ...look, label});
        nichols.push({x: same.phase_deg, y: same.magnitude_db, color, ...look, label});
      });
      // the margins: a dashed line at each crossover, labelled, and the margin itself as a
      // bar (the phase margin from -180 deg at the gain crossover, the gain margin below
      // 0 dB at the phase crossover)
      const m = loop.margins || {}, t = m.text || {};
      // the figures' short names from the figure table (s.margin_columns)
      const short = (name) => s.margin_columns.find((c) => c.name === name).short;
      vm.push({x: m.crossover_rad_s, color, row: k,
               label: `${loop.symbol} ${short("crossover_rad_s")} ${text(t.crossover_rad_s)}, ` +
                      `${short("phase_margin_deg")} ${text(t.phase_margin_deg)}°`});
      vp.push({x: m.phase_crossover_rad_s, color, row: k,
               label: `${loop.symbol} ${short("gain_margin_db")} ${text(t.gain_margin_db)} dB`});
      if (finite(m.crossover_rad_s) && finite(m.phase_margin_deg)) {
        sp.push({x: m.crossover_rad_s, y0: -180, y1: -180 + m.phase_margin_deg, color});
      }
      if (finite(m.phase_crossover_rad_s) && finite(m.gain_margin_db)) {
        sm.push({x: m.phase_crossover_rad_s, y0: 0, y1: -m.gain_margin_db, color});
      }
    });
    $("bode").replaceChildren(
      chart("magnitude", {title: "Open loops |L| [dB]", xlog: true, xsorted: true,
        xlabel: "ω [rad/s]", series: mag, vlines: vm, bars: sm,
        hlines: [{y: 0, color: "#888"}], yclip: [-80, 80]}),
      chart("phase", {title: "Open loops phase [deg]", xlog: true, xsorted: true,
        xlabel: "ω [rad/s]", series: phase, vlines: vp, bars: sp,
        hlines: [{y: -180, color: "#888"}], yclip: [-720, 90]}));
    $("nichols").replaceChildren(chart("nichols", {title: "Nichols: |L| [dB] against phase [deg]",
      xlabel: "phase [deg]", series: nichols, vlines: [{x: -180, color: "#888", dash: [2, 2]}],
      hlines: [{y: 0, color: "#888", dash: [2, 2]}], yclip: [-60, 60], xclip: [-540, 0]}));

    const c = s.closed_loop;
    const cs = [{x: s.omega_rad_s, y: c.magnitude_db, color: "#000", label: "T"}];
    if (p) cs.push({x: p.omega_rad_s, y: p.closed_loop.magnitude_db, color: "#000", faint: true,
                    label: "T previous"});
    if (v) cs.push({x: v.omega_rad_s, y: v.closed_loop.magnitude_db, color: "#000", dash: DASH,
                    label: "T variant"});
    const lines = [{x: c.bandwidth_rad_s, color: "#000", label: `ω_BW ${text(c.bandwidth_text)} rad/s`}];
    if (c.required_bandwidth_rad_s) lines.push({x: c.required_bandwidth_rad_s, color: "#b00", row: 1,
      label: `required ≥ ${c.required_bandwidth_rad_s} rad/s`, dash: [2, 2]});
    $("closed").replaceChildren(chart("closed", {title: "Closed loop |T| [dB]", xlog: true,
      xsorted: true, xlabel: "ω [rad/s]", series: cs, vlines: lines,
      hlines: [{y: -3, color: "#888", dash: [3, 3]}], yclip: [-60, 30]}));

    const st = s.step, ss = [];
    const steps = [["linear", "#1f77b4"], ["nonlinear", "#d62728"]];
    steps.forEach(([kind, color]) => {
      if (st[kind]) ss.push({x: st[kind].t, y: st[kind].y, color, label: kind});
    });
    steps.forEach(([kind, color]) => {
      if (p && p.step[kind]) ss.push({x: p.step[kind].t, y: p.step[kind].y, color, faint: true,
                                      label: `${kind} previous`});
    });
    steps.forEach(([kind, color]) => {
      if (v && v.step[kind]) ss.push({x: v.step[kind].t, y: v.step[kind].y, color, dash: DASH,
                                      label: `${kind} variant`});
    });
    const f = st.figure_texts;  // label, value and unit of the figure table
    const title = `Step of ${+st.amplitude.toPrecision(4)} ${st.unit}` + (f ?
      ` (nonlinear: ${f.overshoot_pct}, ${f.settling_time_s})` : "");
    const spans = [];
    const shades = {current: "#ff7f0e", voltage: "#9467bd"};
    Object.entries(st.limited || {}).forEach(([name, list]) => list.forEach(([from, to]) =>
      spans.push({from, to, color: shades[name]})));
    const limitedWords = Object.entries(st.limited || {}).filter(([, l]) => l.length)
      .map(([name]) => `${name} limit (${name === "current" ? "orange" : "purple"})`);
    $("steps").replaceChildren(chart("step", {title: title + (limitedWords.length ? "; shaded: " +
      limitedWords.join(", ") : ""), xlabel: "t [s]", ylabel: st.unit, xsorted: true,
      series: ss, spans, hlines: [{y: st.amplitude, color: "#888", dash: [3, 3]}]}));
    renderVerdicts(s);
    $("notes").replaceChildren(...s.notes.map((n) => el("li", {}, n)));
  }

  // the ids of the cells the tests and the page read, by view and figure
  const MARGIN_IDS = {"margins crossover_rad_s": "wc-", "margins phase_margin_deg": "pm-",
                      "margins gain_margin_db": "gm-",
                      "loop_at_a_time phase_margin_deg": "pm-at-a-time-"};

  function renderMargins(s) {
    // the columns' headings are the figure table's labels and units (s.margin_columns)
    const table = el("table", {id: "margin-table"});
    const head = el("tr");
    ["loop", "broken at", ...s.margin_columns.map((c) => c.heading)]
      .forEach((h) => head.appendChild(el("th", {}, h)));
    table.appendChild(head);
    s.loops.forEach((loop) => {
      const row = el("tr", {id: "row-" + loop.name});
      row.appendChild(el("td", {class: "text"}, loop.symbol));
      row.appendChild(el("td", {class: "text"}, loop.breaks_at));
      s.margin_columns.forEach((c) => {
        const shown = (loop[c.view] || {}).text || {};
        const id = MARGIN_IDS[`${c.view} ${c.name}`];
        row.appendChild(el("td", id ? {id: id + loop.name} : {}, text(shown[c.name])));
      });
      table.appendChild(row);
    });
    const bw = el("p", {}, `ω_BW = `);
    bw.appendChild(el("span", {id: "bandwidth"}, text(s.closed_loop.bandwidth_text)));
    bw.appendChild(document.createTextNode(` rad/s; closed loop ${s.stability}`));
    $("margins").replaceChildren(table, bw);
  }

  function renderVerdicts(s) {
    const table = el("table", {id: "verdict-table"});
    const head = el("tr");
    ["requirement", "figure", "value", "needs", "verdict"].forEach((h) => head.appendChild(el("th", {}, h)));
    table.appendChild(head);
    s.verdicts.forEach((v) => {
      const row = el("tr");
      const needs = v.min !== null && v.max !== null ? `in [${v.min}, ${v.max}]`
        : v.min !== null ? `≥ ${v.min}` : `≤ ${v.max}`;
      [[v.id, "text"], [v.metric, "text"],
       [v.value === null ? "–" : `${+v.value.toPrecision(4)} ${v.unit}`, ""],
       [`${needs} ${v.unit}`, ""], [v.status, v.status]].forEach(([t, cls]) =>
        row.appendChild(el("td", {class: cls}, t)));
      row.title = v.message;
      table.appendChild(row);
    });
    $("verdicts").replaceChildren(el("h3", {}, "Requirements (analyze-kind, as verify measures them)"), table);
  }

  // ---- undo, redo, save, start ------------------------------------------------------------
  function back(from, to) {
    if (!from.length) return Promise.resolve(null);
    to.push(Object.assign({}, values));
    return setValues(from.pop());
  }
  async function save(overwrite) {
    const request = {session, name: $("save-name").value, file: $("save-file").value || null,
                     overwrite: overwrite === true};
    try {
      const data = await api("/api/save", request);
      $("save-result").textContent = `wrote ${data.written}\ncheck it with:\n${data.command}`;
    } catch (error) {
      // 409 for an existing file: replaced only when the user confirms
      if (error.status === 409 && !request.overwrite && / exists;/.test(error.message) &&
          window.confirm(`${error.message.replace(/;.*/, "")}. Replace it?`)) {
        return save(true);
      }
      $("save-result").textContent = String(error.message || error);
    }
    return null;
  }
  async function compare() {
    if ($("compare").checked && !variantState) {
      // the variant as the config gives it: a session of its own with no values
      variantState = await api("/api/state", {session: session + "-variant", seq: 0, values: {},
        step: $("step").value, nonlinear: $("nonlinear").checked});
    }
    if (shown) render();
  }
  async function tune(options) {  // options: {candidates, rounds}, as cas-freq tune's
    $("tune-status").textContent = "tuning (a few seconds)";
    try {
      const data = await api("/api/tune", Object.assign({session}, options || {}));
      $("tune-status").textContent = `${data.feasible ? "feasible" : "INFEASIBLE"}, ` +
        `${data.feasible_candidates} of ${data.candidates} candidates feasible; ` +
        `objective ${data.objective.name}`;
      const keys = data.free.map((f) => f.key);
      const table = el("table", {id: "tune-table"});
      const head = el("tr");
      [...keys.map((k) => k.split(".").pop()), "ω_BW", "PM", "OS %", ""].forEach((h) =>
        head.appendChild(el("th", {}, h)));
      table.appendChild(head);
      const rows = [Object.assign({label: "tuned"}, data.tuned.values), ...data.pareto];
      rows.forEach((row) => {
        const tr = el("tr");
        keys.forEach((k) => tr.appendChild(el("td", {}, formatValue(row[k]))));
        ["closed_loop.bandwidth_rad_s", "position_loop.phase_margin_deg", "step.overshoot_pct"]
          .forEach((m, i) => tr.appendChild(el("td", {}, row[m] === undefined
            ? (i === 0 ? row.label : "") : row[m] === null ? "–" : +row[m].toPrecision(4))));
        const use = el("button", {type: "button"}, "use");
        use.addEventListener("click", () => {
          undo.push(Object.assign({}, values)); redo.length = 0;
          const next = Object.assign({}, values);
          keys.forEach((k) => { next[k] = formatValue(row[k]); });
          setValues(next);
        });
        const cell = el("td"); cell.appendChild(use); tr.appendChild(cell);
        table.appendChild(tr);
      });
      const bw = "closed_loop.bandwidth_rad_s", pm = "position_loop.phase_margin_deg";
      const front = chart("pareto", {title: "Pareto front: phase margin [deg] against ω_BW",
        xlabel: "ω_BW [rad/s]", ylabel: "PM [deg]", series: [{x: data.pareto.map((r) => r[bw]),
          y: data.pareto.map((r) => r[pm]), color: "#2ca02c", points: true, label: "feasible"}]});
      $("tune-result").replaceChildren(front, table);
    } catch (error) {
      $("tune-status").textContent = String(error.message || error);
    }
  }
  function parseHash() {
    const fromUrl = {};
    location.hash.slice(1).split("&").filter(Boolean).forEach((part) => {
      const [k, v] = part.split("=");
      fromUrl[decodeURIComponent(k)] = decodeURIComponent(v || "");
    });
    return fromUrl;
  }
  async function start() {
    $("session").textContent = session;
    const init = await api("/api/init?session=" + encodeURIComponent(session));
    controls = init.controls;
    const unknown = Object.keys(Object.assign({}, init.values, parseHash()))
      .filter((key) => !controls.some((c) => c.key === key));
    $("title").textContent = `${init.config} / ${init.variant}`;
    $("save-dir").textContent = init.save_dir;
    $("step").value = init.step;
    buildControls();
    $("undo").addEventListener("click", () => back(undo, redo));
    $("redo").addEventListener("click", () => back(redo, undo));
    $("save").addEventListener("click", () => save(false));
    $("tune").addEventListener("click", () => tune());
    $("add").addEventListener("click", addKey);
    $("compare").addEventListener("change", compare);
    ["step", "nonlinear"].forEach((id) => $(id).addEventListener("change", () => {
      variantState = null;
      if ($("compare").checked) compare();
      schedule();
    }));
    $("overlay").addEventListener("change", () => shown && render());
    let resized = null;  // the charts' width follows the window's
    window.addEventListener("resize", () => {
      clearTimeout(resized);
      resized = setTimeout(() => shown && render(), 200);
    });
    document.addEventListener("keydown", (e) => {
      if (!(e.ctrlKey || e.metaKey) || e.target.tagName === "INPUT" && e.target.type === "text") return;
      if (e.key === "z") back(undo, redo); else if (e.key === "y") back(redo, undo);
    });
    for (const key of unknown) {  // a key of the URL or of the session gets its control
      $("add-key").value = key;
      await addKey();
    }
    return setValues(Object.assign({}, init.values, parseHash()));
  }

  window.casDesign = {setValue, setValues, session, ready: null, tune, compare, addKey,
                      slider: {toSlider, fromSlider, controls: () => controls},
                      undo: () => back(undo, redo), redo: () => back(redo, undo),
                      state: () => shown, charts};
  window.casDesign.ready = start();
})();
