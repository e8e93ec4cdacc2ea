// cas-freq design: the page's controls, requests and SVG plots (no library, no network but
// the page's own server). window.casDesign.setValue(key, text) is the one way a value
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

  async function api(path, body) {
    const options = body === undefined ? {} :
      {method: "POST", headers: {"Content-Type": "application/json"}, body: JSON.stringify(body)};
    const response = await fetch(path, options);
    const data = await response.json();
    if (!response.ok) throw new Error(data.error || response.statusText);
    return data;
  }

  // ---- controls ---------------------------------------------------------------------------
  const SLIDER_STEPS = 1000;
  function toSlider(c, value) {
    const p = Math.log(value / c.lower) / Math.log(c.upper / c.lower);
    return Math.round(Math.min(1, Math.max(0, p)) * SLIDER_STEPS);
  }
  function fromSlider(c, position) {
    return c.lower * Math.pow(c.upper / c.lower, position / SLIDER_STEPS);
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
    const entry = el("input", {type: "text", size: 10, id: "entry-" + c.key});
    entry.value = formatValue(c.value);
    label.appendChild(entry);
    label.appendChild(el("span", {}, " " + c.unit));
    const slider = el("input", {type: "range", min: 0, max: SLIDER_STEPS,
                                id: "slider-" + c.key});
    slider.value = toSlider(c, c.value);
    row.appendChild(label);
    row.appendChild(slider);
    row.appendChild(el("span", {class: "error", id: "error-" + c.key}));
    groups[c.group].appendChild(row);
    slider.addEventListener("input", () =>
      setValue(c.key, formatValue(fromSlider(c, +slider.value))));
    entry.addEventListener("change", () => setValue(c.key, entry.value));
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
  function formatValue(v) { return Number(v.toPrecision(4)).toString(); }
  function showValues(which) {
    controls.forEach((c) => {
      const text = which[c.key] !== undefined ? which[c.key] : formatValue(c.value);
      $("entry-" + c.key).value = text;
      const number = Number(text);
      if (Number.isFinite(number) && number > 0) $("slider-" + c.key).value = toSlider(c, number);
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

  // ---- plots ------------------------------------------------------------------------------
  const W = 640, H = 210, M = {l: 52, r: 12, t: 20, b: 30};
  const SVG = "http://www.w3.org/2000/svg";
  function svgEl(tag, attrs, text) {
    const node = document.createElementNS(SVG, tag);
    Object.entries(attrs).forEach(([k, v]) => node.setAttribute(k, v));
    if (text !== undefined) node.textContent = text;
    return node;
  }
  function niceTicks(lo, hi, n) {
    const span = hi - lo || 1, raw = span / n;
    const step = [1, 2, 5, 10].map((m) => m * Math.pow(10, Math.floor(Math.log10(raw))))
      .find((s) => s >= raw);
    const ticks = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * span; v += step) ticks.push(v);
    return ticks;
  }
  // spec: {title, xlog, xlabel, ylabel, series: [{x, y, color, faint, dash, label}],
  //        vlines: [{x, color, label, dash}], hlines: [{y, color, dash}]}
  function plot(spec) {
    const svg = svgEl("svg", {class: "plot", viewBox: `0 0 ${W} ${H}`});
    const fx = spec.xlog ? Math.log10 : (v) => v;
    let xs = [], ys = [];
    const inX = (x) => x !== null && x > (spec.xlog ? 0 : -Infinity) &&
      (!spec.xclip || (x >= spec.xclip[0] && x <= spec.xclip[1]));
    spec.series.forEach((s) => s.x.forEach((x, i) => {
      if (s.y[i] !== null && Number.isFinite(s.y[i]) && inX(x)) {
        xs.push(fx(x)); ys.push(s.y[i]);
      }
    }));
    (spec.hlines || []).forEach((h) => ys.push(h.y));
    if (!xs.length) { svg.appendChild(svgEl("text", {x: W / 2, y: H / 2}, "no data")); return svg; }
    let [x0, x1] = [Math.min(...xs), Math.max(...xs)];
    let [y0, y1] = [Math.min(...ys), Math.max(...ys)];
    if (spec.yclip) { y0 = Math.max(y0, spec.yclip[0]); y1 = Math.min(y1, spec.yclip[1]); }
    if (y1 - y0 < 1e-9) { y0 -= 1; y1 += 1; }
    const pad = 0.05 * (y1 - y0); y0 -= pad; y1 += pad;
    const X = (v) => M.l + (fx(v) - x0) / (x1 - x0 || 1) * (W - M.l - M.r);
    const Y = (v) => H - M.b - (Math.min(Math.max(v, y0), y1) - y0) / (y1 - y0) * (H - M.t - M.b);
    const grid = "#e4e4e4";
    const xticks = spec.xlog
      ? Array.from({length: Math.floor(x1) - Math.ceil(x0) + 1}, (_, i) => Math.pow(10, Math.ceil(x0) + i))
      : niceTicks(x0, x1, 6);
    xticks.forEach((t) => {
      svg.appendChild(svgEl("line", {x1: X(t), x2: X(t), y1: M.t, y2: H - M.b, stroke: grid}));
      svg.appendChild(svgEl("text", {x: X(t), y: H - M.b + 13, "text-anchor": "middle"},
        spec.xlog ? "1e" + Math.round(Math.log10(t)) : +t.toPrecision(3)));
    });
    niceTicks(y0, y1, 5).forEach((t) => {
      svg.appendChild(svgEl("line", {x1: M.l, x2: W - M.r, y1: Y(t), y2: Y(t), stroke: grid}));
      svg.appendChild(svgEl("text", {x: M.l - 4, y: Y(t) + 4, "text-anchor": "end"},
        +t.toPrecision(3)));
    });
    svg.appendChild(svgEl("text", {x: M.l, y: 13, "font-weight": "bold"}, spec.title));
    svg.appendChild(svgEl("text", {x: W - M.r, y: H - 3, "text-anchor": "end"}, spec.xlabel || ""));
    (spec.spans || []).forEach((b) => {
      const a = Math.max(fx(b.from), x0), z = Math.min(fx(b.to), x1);
      if (z < a) return;
      const left = M.l + (a - x0) / (x1 - x0 || 1) * (W - M.l - M.r);
      const right = M.l + (z - x0) / (x1 - x0 || 1) * (W - M.l - M.r);
      svg.appendChild(svgEl("rect", {x: left, y: M.t, width: Math.max(right - left, 1),
        height: H - M.t - M.b, fill: b.color, "fill-opacity": 0.15}));
    });
    (spec.hlines || []).forEach((h) => svg.appendChild(svgEl("line",
      {x1: M.l, x2: W - M.r, y1: Y(h.y), y2: Y(h.y), stroke: h.color, "stroke-dasharray": h.dash || ""})));
    (spec.vlines || []).forEach((v) => {
      if (v.x === null || v.x === undefined || (spec.xlog && !(v.x > 0)) ||
          fx(v.x) < x0 || fx(v.x) > x1) return;
      svg.appendChild(svgEl("line", {x1: X(v.x), x2: X(v.x), y1: M.t, y2: H - M.b,
        stroke: v.color, "stroke-dasharray": v.dash || "4 3"}));
      if (v.label) svg.appendChild(svgEl("text", {x: X(v.x) + 3, y: M.t + 10 + (v.row || 0) * 12,
        fill: v.color}, v.label));
    });
    spec.series.filter((s) => s.points).forEach((s) => s.x.forEach((x, i) => {
      if (s.y[i] === null || !Number.isFinite(s.y[i]) || !inX(x)) return;
      svg.appendChild(svgEl("circle", {cx: X(x), cy: Y(s.y[i]), r: 3, fill: s.color}));
    }));
    spec.series.filter((s) => !s.points).forEach((s) => {
      let d = "", pen = "M";
      s.x.forEach((x, i) => {
        const y = s.y[i];
        if (y === null || !Number.isFinite(y) || !inX(x) ||
            (spec.yclip && (y < spec.yclip[0] || y > spec.yclip[1]))) { pen = "M"; return; }
        d += `${pen}${X(x).toFixed(1)},${Y(y).toFixed(1)}`; pen = "L";
      });
      svg.appendChild(svgEl("path", {d, fill: "none", stroke: s.color, "stroke-width": s.faint ? 1 : 1.6,
        "stroke-opacity": s.faint ? 0.25 : 1, "stroke-dasharray": s.dash || ""}));
    });
    let lx = M.l;  // the legend, under the plot on the left (the axis label is on the right)
    spec.series.filter((s) => s.label && !s.faint).forEach((s) => {
      svg.appendChild(svgEl("text", {x: lx, y: H - 3, fill: s.color}, s.label));
      lx += 6.5 * s.label.length + 14;
    });
    return svg;
  }

  // ---- rendering --------------------------------------------------------------------------
  function faint(state) { return $("overlay").checked && state ? state : null; }
  function text(t) { return t === null || t === undefined ? "–" : t; }

  function render() {
    const s = shown, p = faint(previous), v = $("compare").checked ? variantState : null;
    renderMargins(s);
    const bode = $("bode"); bode.replaceChildren();
    const mag = [], phase = [], vm = [], vp = [], nichols = [];
    s.loops.forEach((loop, k) => {
      const color = COLORS[k % COLORS.length];
      mag.push({x: s.omega_rad_s, y: loop.magnitude_db, color,
                label: `${loop.symbol} (broken at ${loop.breaks_at})`});
      phase.push({x: s.omega_rad_s, y: loop.phase_deg, color, label: loop.symbol});
      const old = p && p.loops.find((l) => l.name === loop.name);
      if (old) {
        mag.push({x: p.omega_rad_s, y: old.magnitude_db, color, faint: true});
        phase.push({x: p.omega_rad_s, y: old.phase_deg, color, faint: true});
      }
      const base = v && v.loops.find((l) => l.name === loop.name);
      if (base) {
        mag.push({x: v.omega_rad_s, y: base.magnitude_db, color, dash: "6 3"});
        phase.push({x: v.omega_rad_s, y: base.phase_deg, color, dash: "6 3"});
        nichols.push({x: base.phase_deg, y: base.magnitude_db, color, dash: "6 3"});
      }
      nichols.push({x: loop.phase_deg, y: loop.magnitude_db, color, label: loop.symbol});
      if (old) nichols.push({x: old.phase_deg, y: old.magnitude_db, color, faint: true});
      const m = loop.margins || {}, t = m.text || {};
      vm.push({x: m.crossover_rad_s, color, row: k,
               label: `${loop.symbol} ωc ${text(t.crossover_rad_s)}, PM ${text(t.phase_margin_deg)}°`});
      vp.push({x: m.phase_crossover_rad_s, color, row: k,
               label: `${loop.symbol} GM ${text(t.gain_margin_db)} dB`});
    });
    bode.appendChild(plot({title: "Open loops |L| [dB]",
      xlog: true, xlabel: "ω [rad/s]", series: mag, vlines: vm, hlines: [{y: 0, color: "#888"}],
      yclip: [-80, 80]}));
    bode.appendChild(plot({title: "Open loops phase [deg]", xlog: true, xlabel: "ω [rad/s]",
      series: phase, vlines: vp, hlines: [{y: -180, color: "#888"}], yclip: [-720, 90]}));
    $("nichols").replaceChildren(plot({title: "Nichols: |L| [dB] against phase [deg]",
      xlabel: "phase [deg]", series: nichols, vlines: [{x: -180, color: "#888", dash: "2 2"}],
      hlines: [{y: 0, color: "#888", dash: "2 2"}], yclip: [-60, 60], xclip: [-540, 0]}));

    const c = s.closed_loop;
    const cs = [{x: s.omega_rad_s, y: c.magnitude_db, color: "#000", label: "T"}];
    if (p) cs.push({x: p.omega_rad_s, y: p.closed_loop.magnitude_db, color: "#000", faint: true});
    if (v) cs.push({x: v.omega_rad_s, y: v.closed_loop.magnitude_db, color: "#000", dash: "6 3"});
    const lines = [{x: c.bandwidth_rad_s, color: "#000", label: `ω_BW ${text(c.bandwidth_text)} rad/s`}];
    if (c.required_bandwidth_rad_s) lines.push({x: c.required_bandwidth_rad_s, color: "#b00", row: 1,
      label: `required ≥ ${c.required_bandwidth_rad_s} rad/s`, dash: "2 2"});
    $("closed").replaceChildren(plot({title: "Closed loop |T| [dB]", xlog: true,
      xlabel: "ω [rad/s]", series: cs, vlines: lines, hlines: [{y: -3, color: "#888", dash: "3 3"}],
      yclip: [-60, 30]}));

    const st = s.step, ss = [];
    if (st.linear) ss.push({x: st.linear.t, y: st.linear.y, color: "#1f77b4", label: "linear"});
    if (st.nonlinear) ss.push({x: st.nonlinear.t, y: st.nonlinear.y, color: "#d62728", label: "nonlinear"});
    if (p && p.step.linear) ss.push({x: p.step.linear.t, y: p.step.linear.y, color: "#1f77b4", faint: true});
    if (p && p.step.nonlinear) ss.push({x: p.step.nonlinear.t, y: p.step.nonlinear.y, color: "#d62728", faint: true});
    if (v && v.step.linear) ss.push({x: v.step.linear.t, y: v.step.linear.y, color: "#1f77b4", dash: "6 3"});
    if (v && v.step.nonlinear) ss.push({x: v.step.nonlinear.t, y: v.step.nonlinear.y, color: "#d62728", dash: "6 3"});
    const f = st.figures;
    const title = `Step of ${+st.amplitude.toPrecision(4)} ${st.unit}` + (f ?
      ` (nonlinear: overshoot ${text(f.overshoot_pct && +f.overshoot_pct.toPrecision(3))} %, ` +
      `settling ${f.settling_time_s ? +(f.settling_time_s * 1e3).toPrecision(3) : "–"} ms)` : "");
    const spans = [];
    const shades = {current: "#ff7f0e", voltage: "#9467bd"};
    Object.entries(st.limited || {}).forEach(([name, list]) => list.forEach(([from, to]) =>
      spans.push({from, to, color: shades[name]})));
    const limitedWords = Object.entries(st.limited || {}).filter(([, l]) => l.length)
      .map(([name]) => `${name} limit (${name === "current" ? "orange" : "purple"})`);
    $("steps").replaceChildren(plot({title: title + (limitedWords.length ? "; shaded: " +
      limitedWords.join(", ") : ""), xlabel: "t [s]", series: ss, spans,
      hlines: [{y: st.amplitude, color: "#888", dash: "3 3"}]}));
    renderVerdicts(s);
    $("notes").replaceChildren(...s.notes.map((n) => el("li", {}, n)));
  }

  function renderMargins(s) {
    const table = el("table", {id: "margin-table"});
    const head = el("tr");
    ["loop", "broken at", "ωc [rad/s]", "PM [deg]", "GM [dB]", "lower GM [dB]",
     "delay margin [ms]", "loop at a time: PM [deg]", "GM [dB]", "ωc [rad/s]"]
      .forEach((h) => head.appendChild(el("th", {}, h)));
    table.appendChild(head);
    s.loops.forEach((loop) => {
      const t = (loop.margins || {}).text || {}, a = (loop.loop_at_a_time || {}).text || {};
      const row = el("tr", {id: "row-" + loop.name});
      row.appendChild(el("td", {class: "text"}, loop.symbol));
      row.appendChild(el("td", {class: "text"}, loop.breaks_at));
      row.appendChild(el("td", {id: "wc-" + loop.name}, text(t.crossover_rad_s)));
      row.appendChild(el("td", {id: "pm-" + loop.name}, text(t.phase_margin_deg)));
      row.appendChild(el("td", {id: "gm-" + loop.name}, text(t.gain_margin_db)));
      row.appendChild(el("td", {}, text(t.gain_margin_low_db)));
      const dm = loop.margins && loop.margins.delay_margin_s;
      row.appendChild(el("td", {}, dm === null || dm === undefined ? "–" : +(dm * 1e3).toPrecision(4)));
      row.appendChild(el("td", {id: "pm-at-a-time-" + loop.name}, text(a.phase_margin_deg)));
      row.appendChild(el("td", {}, text(a.gain_margin_db)));
      row.appendChild(el("td", {}, text(a.crossover_rad_s)));
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
  async function save() {
    try {
      const data = await api("/api/save", {session, name: $("save-name").value,
                                           file: $("save-file").value || null});
      $("save-result").textContent = `wrote ${data.written}\ncheck it with:\n${data.command}`;
    } catch (error) {
      $("save-result").textContent = String(error.message || error);
    }
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
      const front = plot({title: "Pareto front: phase margin [deg] against ω_BW [rad/s]",
        xlabel: "ω_BW [rad/s]", series: [{x: data.pareto.map((r) => r[bw]),
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
    $("step").value = init.step;
    buildControls();
    $("undo").addEventListener("click", () => back(undo, redo));
    $("redo").addEventListener("click", () => back(redo, undo));
    $("save").addEventListener("click", save);
    $("tune").addEventListener("click", () => tune());
    $("add").addEventListener("click", addKey);
    $("compare").addEventListener("change", compare);
    ["step", "nonlinear"].forEach((id) => $(id).addEventListener("change", () => {
      variantState = null;
      if ($("compare").checked) compare();
      schedule();
    }));
    $("overlay").addEventListener("change", () => shown && render());
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
                      undo: () => back(undo, redo), redo: () => back(redo, undo),
                      state: () => shown};
  window.casDesign.ready = start();
})();
