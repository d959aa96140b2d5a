// dms viewer: the page's side. Server-sent events from /events keep `robots` up to date;
// render() draws the selected robot. Every text from the bus goes through textContent
// (never innerHTML): an error may quote a hostile input.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const COLORS = ["#2563eb", "#dc2626", "#16a34a", "#9333ea", "#ea580c", "#0891b2", "#be185d", "#4d7c0f"];
const SHOWN_DECISIONS = 100;
const SHOWN_ERRORS = 100;

let robots = {};          // robot id -> view (the snapshot's shape)
let historyS = 3600;
let selected = decodeURIComponent(location.hash.slice(1)) || null;
let scheduled = false;
const dirty = new Set(); // parts to redraw: "robots", "state", "structure", "chart", "decisions", "errors", "agenda", "body", "all"

function $(id) { return document.getElementById(id); }

function el(tag, attrs, text) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs || {})) node.setAttribute(name, value);
  if (text !== undefined && text !== null) node.textContent = String(text);
  return node;
}

function svg(tag, attrs, text) {
  const node = document.createElementNS(SVG, tag);
  for (const [name, value] of Object.entries(attrs || {})) node.setAttribute(name, String(value));
  if (text !== undefined && text !== null) node.textContent = String(text);
  return node;
}

function clock(seconds) {
  if (typeof seconds !== "number") return "";
  return new Date(seconds * 1000).toLocaleTimeString([], { hour12: false });
}

function isoClock(iso) {
  if (typeof iso !== "string") return "";
  const t = Date.parse(iso);
  return Number.isNaN(t) ? iso : clock(t / 1000);
}

function num(value, digits) {
  return typeof value === "number" && Number.isFinite(value) ? value.toFixed(digits) : "–";
}

function obj(value) { return value && typeof value === "object" && !Array.isArray(value) ? value : null; }

// ------------------------------------------------------------------ events

function blank(robot) {
  return { robot, alive: false, since: null, tokens: [], state: null, structure: null, agenda: null,
           joints: null, aim: null, thresholds: {}, thresholds_source: "none", samples: [], decisions: [], errors: [] };
}

function view(robot) {
  if (!robots[robot]) { robots[robot] = blank(robot); dirty.add("robots"); }
  return robots[robot];
}

function trim(list, max) { if (list.length > max) list.splice(0, list.length - max); }

const handlers = {
  snapshot(data) {
    historyS = data.history_s || historyS;
    robots = {};
    for (const [robot, v] of Object.entries(data.robots || {})) robots[robot] = Object.assign(blank(robot), v);
    dirty.add("all");
  },
  robot(data) {
    Object.assign(view(data.robot), { alive: data.alive, since: data.since, tokens: data.tokens || [] });
    dirty.add("robots"); dirty.add("state");
  },
  state(data) {
    const v = view(data.robot);
    v.state = data.state;
    v.thresholds = data.thresholds || {};
    v.thresholds_source = data.thresholds_source;
    if (data.sample) {
      v.samples.push(data.sample);
      const oldest = data.sample[0] - historyS;
      while (v.samples.length && v.samples[0][0] < oldest) v.samples.shift();
      dirty.add("chart");
    }
    dirty.add("state");
  },
  decision(data) {
    const v = view(data.robot);
    v.decisions.push(data.decision);
    trim(v.decisions, 200);
    dirty.add("decisions"); dirty.add("state");
  },
  decisions(data) { // the daemon's recent decisions joined the viewer's: the whole list again
    view(data.robot).decisions = data.decisions || [];
    dirty.add("decisions"); dirty.add("state"); dirty.add("chart");
  },
  report(data) { // a dms/errors message ("error" would be taken for the stream's own error event)
    const v = view(data.robot);
    v.errors.push(data.error);
    trim(v.errors, 100);
    dirty.add("errors");
  },
  structure(data) { view(data.robot).structure = data.structure; dirty.add("structure"); },
  agenda(data) { view(data.robot).agenda = data.agenda; dirty.add("agenda"); },
  body(data) { Object.assign(view(data.robot), { joints: data.joints, aim: data.aim }); dirty.add("body"); },
};

function connect() {
  const source = new EventSource("events");
  source.onopen = () => { $("link").textContent = "live"; $("link").className = "link live"; };
  source.onerror = () => { $("link").textContent = "reconnecting…"; $("link").className = "link connecting"; };
  for (const name of Object.keys(handlers)) {
    source.addEventListener(name, (event) => {
      try { handlers[name](JSON.parse(event.data)); } catch (error) { console.error(name, error); }
      schedule();
    });
  }
}

function schedule() {
  if (scheduled) return;
  scheduled = true;
  setTimeout(() => { scheduled = false; render(); }, 50);
}

// ------------------------------------------------------------------ render

function current() {
  const ids = Object.keys(robots).sort();
  if (!selected || !robots[selected]) {
    selected = ids.find((id) => robots[id].alive) || ids[0] || null;
    if (selected) dirty.add("all");
  }
  return selected ? robots[selected] : null;
}

function render() {
  const v = current();
  const all = dirty.has("all");
  if (all || dirty.has("robots")) renderRobots();
  if (v) {
    if (all || dirty.has("structure")) renderMachine(v);
    if (all || dirty.has("state") || dirty.has("structure")) renderState(v);
    if (all || dirty.has("chart") || dirty.has("state")) renderCharts(v, all);
    if (all || dirty.has("chart") || dirty.has("decisions")) renderStrip(v);
    if (all || dirty.has("decisions")) renderDecisions(v);
    if (all || dirty.has("errors")) renderErrors(v);
    if (all || dirty.has("agenda")) renderAgenda(v);
    if (all || dirty.has("body")) renderBody(v);
  }
  dirty.clear();
}

function renderRobots() {
  const nav = $("robots");
  nav.replaceChildren();
  const ids = Object.keys(robots).sort();
  if (!ids.length) nav.append(el("span", { class: "muted" }, "no robot seen yet"));
  for (const id of ids) {
    const v = robots[id];
    const button = el("button", { class: "robot" + (v.alive ? " alive" : "") + (id === selected ? " selected" : ""),
                                  "data-robot": id, title: v.alive ? "alive" : "not alive" });
    button.append(el("span", { class: "dot" }), document.createTextNode(id + (v.alive ? "" : " (gone)")));
    button.onclick = () => { selected = id; location.hash = encodeURIComponent(id); dirty.add("all"); schedule(); };
    nav.append(button);
  }
}

function lastModeWhy(v) {
  for (let i = v.decisions.length - 1; i >= 0; i--) {
    const why = obj(v.decisions[i].why);
    if (why && obj(why.mode)) return why.mode;
  }
  return null;
}

function renderState(v) {
  const s = v.state || {};
  // The daemon's own start time when its state says it; otherwise when the viewer saw
  // the robot come or go (which, for a daemon already running, is when the viewer started).
  const started = v.alive && typeof s.started === "string" ? s.started : null;
  $("robot-name").textContent = v.robot + (v.alive ? " · alive" : " · not alive") +
    (started ? " since " + isoClock(started) : v.since ? " since " + clock(v.since) + " (seen by the viewer)" : "");
  $("robot-name").title = started ? "the daemon started at " + started : "";
  const activity = obj(s.activity);
  $("activity-name").textContent = activity ? activity.name : "none";
  $("activity-manager").textContent = activity ? activity.manager : "";
  const status = $("activity-status");
  status.textContent = activity ? activity.status : "";
  status.className = "badge " + (activity ? activity.status : "");
  $("activity-state").textContent = activity ? activity.state || "" : "";
  const suspended = obj(s.suspended);
  $("suspended").textContent = suspended ? `${suspended.name} (${suspended.manager}) at ${suspended.state || "–"}` : "–";
  const user = obj(s.user);
  $("user").textContent = user ? `${user.id}${user.ready ? " (ready)" : " (not ready)"}` : "nobody";
  $("mode").textContent = s.mode || "–";
  const mode = lastModeWhy(v);
  const parts = [];
  if (user && typeof user.proactivity === "string") parts.push(user.proactivity);
  const pUser = user && typeof user.p_user === "number" ? user.p_user : mode ? mode.p_user : null;
  if (typeof pUser === "number") parts.push(`user initiative p = ${num(pUser, 2)}`);
  if (mode && typeof mode.draw === "number") parts.push(`last draw ${num(mode.draw, 2)}`);
  $("proactivity").textContent = parts.length ? parts.join(" · ") : "–";
  const link = $("robot-link");
  link.textContent = s.robot_link || "–";
  link.className = "badge " + (s.robot_link || "");
  $("tick").textContent = s.tick !== undefined ? `${s.tick} at ${isoClock(s.time)}` : "–";
  $("reloads").textContent = s.reloads !== undefined ? String(s.reloads) : "–";
  const motivation = obj(s.motivation) || {};
  $("dominant").textContent = "dominant: " + (motivation.dominant || "none");
  $("wellbeing").textContent = "wellbeing: " + num(motivation.wellbeing, 1);
  renderInputs(v);
  highlight(v);
}

function renderInputs(v) {
  const inputs = obj((v.state || {}).inputs) || {};
  const body = $("inputs").tBodies[0];
  body.replaceChildren();
  const names = new Set(Object.keys(inputs));
  for (const token of v.tokens) names.add(token);
  for (const name of [...names].sort()) {
    const row = el("tr", { "data-input": name });
    row.append(el("td", {}, name));
    const health = inputs[name];
    const cell = el("td");
    cell.append(el("span", { class: "badge " + (health || "") }, health || "not an input"));
    row.append(cell, el("td", {}, v.tokens.includes(name) ? "declared" : "–"));
    body.append(row);
  }
}

// ------------------------------------------------------------------ the body

// Radians from robot/joints: a positive hip or neck turn looks left, a positive head tilt
// looks down, an arm at 0 hangs down and at 90° points forward. Where the head points is
// the hip's turn plus the neck's.

function angle(rad) { return typeof rad === "number" && Number.isFinite(rad) ? rad : null; }

function degrees(rad) { return Math.round((rad * 180) / Math.PI); }

function side(rad, positive, negative, zero) {
  const d = degrees(rad);
  return d === 0 ? zero : `${Math.abs(d)}° ${d > 0 ? positive : negative}`;
}

function gazeText(p) {
  const hip = angle(p.hip), neck = angle(p.neck), head = angle(p.head);
  if (hip === null && neck === null && head === null) return "–";
  const parts = [side((hip || 0) + (neck || 0), "left", "right", "straight ahead")];
  if (head !== null && degrees(head) !== 0) parts.push(side(head, "down", "up", ""));
  return `looking ${parts.join(", ")}; hip ${hip === null ? "–" : side(hip, "left", "right", "0°")}`;
}

function armText(rad) {
  if (rad === null) return "–";
  const d = degrees(rad);
  return `${d}° ${d < 15 ? "down" : d < 60 ? "raised a little" : d <= 120 ? "forward" : "up"}`;
}

function renderBody(v) {
  const joints = obj(v.joints);
  const p = joints ? obj(joints.positions) || {} : {};
  const gaze = $("gaze");
  gaze.textContent = joints ? gazeText(p) : "no joints reported";
  gaze.title = joints ? Object.entries(p).map(([n, r]) => `${n} ${num((angle(r) ?? NaN) * 180 / Math.PI, 1)}°`).join(", ") +
                        (joints.time ? ` at ${isoClock(joints.time)}` : "") : "";
  const left = angle(p.left_arm), right = angle(p.right_arm);
  $("arms").textContent = left === null && right === null ? "–" : `left ${armText(left)} · right ${armText(right)}`;
  const aim = obj(v.aim);
  $("aim").textContent = aim ? `${aim.action} ${aim.frame === null ? "(back to neutral)" : aim.frame} at ${clock(aim.time)}`
                             : "no aim command seen";
  // The dial, seen from above (forward is up): the hip's turn grey, the head's blue.
  const yaw = (angle(p.hip) || 0) + (angle(p.neck) || 0), hip = angle(p.hip) || 0;
  const dial = $("gaze-dial");
  dial.classList.toggle("none", !joints);
  for (const [id, a, r] of [["dial-gaze", yaw, 28], ["dial-hip", hip, 20]]) {
    $(id).setAttribute("x2", (-r * Math.sin(a)).toFixed(1));
    $(id).setAttribute("y2", (-r * Math.cos(a)).toFixed(1));
  }
}

// ------------------------------------------------------------------ the state machine
// Each container lays its states out top to bottom in layers (the longest path from its
// initial state, cycles set aside), draws a transition downwards as a curve from the
// bottom of one state to the top of the next, and one that goes back up in a lane on its
// right. Outcomes of a state machine that leave it are pills at its bottom.

const BOX_H = 26, GAP_X = 18, GAP_Y = 30, PAD = 10, HEAD = 22, PILL_H = 16, LANE = 34, MAX_H = 720;
const measurer = document.createElement("canvas").getContext("2d");

function textWidth(text, size) {
  measurer.font = `${size || 12}px system-ui, -apple-system, "Segoe UI", sans-serif`;
  return measurer.measureText(String(text)).width;
}

function kids(node) { return Array.isArray(node.states) ? node.states.filter(obj) : []; }
function isMachine(node) { return !!obj(node.transitions) || node.initial !== undefined; }

function targetsOf(parent, child) {
  // Where each outcome of `child` leads inside the state machine `parent`: a sibling's
  // name, or an outcome of `parent` (an unmapped outcome passes through).
  const mapped = obj((obj(parent.transitions) || {})[child.name]) || {};
  const outcomes = new Set([...(Array.isArray(child.outcomes) ? child.outcomes : []), ...Object.keys(mapped)]);
  return [...outcomes].map((o) => [o, mapped[o] !== undefined ? String(mapped[o]) : o]);
}

function layers(node) {
  const children = kids(node);
  if (!isMachine(node)) return node.kind === "concurrence" ? [children] : children.map((c) => [c]);
  const byName = new Map(children.map((c) => [c.name, c]));
  const edges = new Map(children.map((c) => [c.name, targetsOf(node, c).map(([, t]) => t).filter((t) => byName.has(t))]));
  const back = new Set(), seen = new Set(), stack = new Set(), order = [];
  const visit = (name) => {
    seen.add(name); stack.add(name);
    for (const t of edges.get(name)) {
      if (stack.has(t)) back.add(name + "\u0000" + t);
      else if (!seen.has(t)) visit(t);
    }
    stack.delete(name); order.push(name);
  };
  const start = byName.has(node.initial) ? [node.initial] : [];
  for (const name of [...start, ...children.map((c) => c.name)]) if (!seen.has(name)) visit(name);
  const depth = new Map(children.map((c) => [c.name, 0]));
  for (const name of order.reverse()) {
    for (const t of edges.get(name)) {
      if (!back.has(name + "\u0000" + t)) depth.set(t, Math.max(depth.get(t), depth.get(name) + 1));
    }
  }
  const rows = [];
  for (const c of children) (rows[depth.get(c.name)] = rows[depth.get(c.name)] || []).push(c);
  return rows.filter(Boolean);
}

function pills(node) {
  if (!isMachine(node)) return [];
  const names = new Set(kids(node).map((c) => c.name));
  const used = [];
  for (const c of kids(node)) {
    for (const [, target] of targetsOf(node, c)) if (!names.has(target) && !used.includes(target)) used.push(target);
  }
  return used;
}

function measure(node) {
  const children = kids(node);
  const title = textWidth(node.name) + 6 + textWidth(node.kind || "", 10) + 2 * PAD;
  if (!children.length) { node._w = title; node._h = BOX_H; return; }
  children.forEach(measure);
  node._rows = layers(node);
  node._rowW = node._rows.map((r) => r.reduce((w, c) => w + c._w, 0) + GAP_X * (r.length - 1));
  node._rowH = node._rows.map((r) => Math.max(...r.map((c) => c._h)));
  node._pills = pills(node);
  const pillsW = node._pills.reduce((w, p) => w + textWidth(p, 10) + 14 + 8, -8);
  node._w = Math.max(title, Math.max(...node._rowW, pillsW) + 2 * PAD + LANE);
  node._h = HEAD + node._rowH.reduce((a, b) => a + b, 0) + GAP_Y * (node._rows.length - 1) +
            (node._pills.length ? GAP_Y + PILL_H : 0) + PAD;
}

function place(node, x, y) {
  node._x = x; node._y = y;
  if (!node._rows) return;
  const inner = node._w - 2 * PAD - LANE;
  let top = y + HEAD;
  node._rows.forEach((row, i) => {
    let left = x + PAD + (inner - node._rowW[i]) / 2;
    for (const c of row) { place(c, left, top + (node._rowH[i] - c._h) / 2); left += c._w + GAP_X; }
    top += node._rowH[i] + GAP_Y;
  });
  const pillsW = node._pills.reduce((w, p) => w + textWidth(p, 10) + 22, -8);
  let left = x + PAD + (inner - pillsW) / 2;
  node._pillAt = {};
  for (const p of node._pills) {
    const w = textWidth(p, 10) + 14;
    node._pillAt[p] = { x: left, y: y + node._h - PAD - PILL_H, w, h: PILL_H };
    left += w + 8;
  }
}

function draw(node, path, boxes, lines) {
  const container = kids(node).length > 0;
  const g = svg("g", { class: "state" + (container ? " container" : ""), "data-path": path, "data-name": node.name });
  g.append(svg("rect", { x: node._x, y: node._y, width: node._w, height: node._h, rx: 6 }));
  g.append(svg("text", { x: node._x + PAD, y: node._y + 17 }, node.name));
  if (node.kind) g.append(svg("text", { class: "kind", x: node._x + PAD + textWidth(node.name) + 6, y: node._y + 17 }, node.kind));
  boxes.append(g);
  if (!container) return;
  for (const p of node._pills) {
    const at = node._pillAt[p];
    const pill = svg("g", { class: "outcome" });
    pill.append(svg("rect", { x: at.x, y: at.y, width: at.w, height: at.h, rx: 8 }));
    pill.append(svg("text", { x: at.x + 7, y: at.y + 12 }, p));
    boxes.append(pill);
  }
  const byName = new Map(kids(node).map((c) => [c.name, c]));
  const lane = node._x + node._w - LANE / 2;
  for (const c of kids(node)) {
    draw(c, path ? path + "/" + c.name : c.name, boxes, lines);
    if (!isMachine(node)) continue;
    for (const [outcome, target] of targetsOf(node, c)) {
      const to = byName.get(target) || null;
      const at = to ? { x: to._x, y: to._y, w: to._w, h: to._h } : node._pillAt[target];
      if (at) edge(lines, { x: c._x, y: c._y, w: c._w, h: c._h }, at, outcome, lane);
    }
  }
}

function edge(lines, a, b, label, lane) {
  // A cubic curve; its label sits on it, a little past the middle (fan-outs spread there).
  let p;
  if (b.y >= a.y + a.h) { // downwards: bottom centre to top centre
    const x1 = a.x + a.w / 2, y1 = a.y + a.h, x2 = b.x + b.w / 2, y2 = b.y, my = (y1 + y2) / 2;
    p = [[x1, y1], [x1, my], [x2, my], [x2, y2]];
  } else { // back up, or sideways: through the lane on the container's right
    const x1 = a.x + a.w, y1 = a.y + a.h / 2, x2 = b.x + b.w, y2 = b.y + b.h / 2;
    p = [[x1, y1], [lane, y1], [lane, y2], [x2, y2]];
  }
  const d = `M${p[0]} C${p[1]} ${p[2]} ${p[3]}`;
  const t = 0.6, u = 1 - t;
  const at = (i) => u * u * u * p[0][i] + 3 * u * u * t * p[1][i] + 3 * u * t * t * p[2][i] + t * t * t * p[3][i];
  lines.append(svg("path", { class: "edge", d, "marker-end": "url(#arrow)" }));
  lines.append(svg("text", { class: "edge-label", x: at(0), y: at(1) + 3, "text-anchor": "middle" }, label));
}

function renderMachine(v) {
  const host = $("machine");
  const structure = obj(v.structure);
  const root = structure && obj(structure.structure) ? obj(structure.structure.root) : null;
  host.replaceChildren();
  if (!root) {
    const activity = obj((v.state || {}).activity);
    const why = structure && structure.error ? `: ${structure.error}` : "";
    host.append(el("p", { class: "muted" }, activity ? `the state machine of ${activity.name} is not known yet${why}` : "no activity"));
    return;
  }
  measure(root);
  place(root, 2, 2);
  const width = root._w + 4, height = root._h + 4;
  const scale = Math.min(1, MAX_H / height, Math.max(200, host.clientWidth - 4) / width);
  const drawing = svg("svg", { width: Math.round(width * scale), height: Math.round(height * scale),
                               viewBox: `0 0 ${width} ${height}`, role: "img",
                               "aria-label": `state machine of ${structure.activity}` });
  const defs = svg("defs");
  const marker = svg("marker", { id: "arrow", viewBox: "0 0 10 10", refX: 9, refY: 5, markerWidth: 7, markerHeight: 7, orient: "auto-start-reverse" });
  marker.append(svg("path", { d: "M0,0 L10,5 L0,10 z", fill: "#9ca3af" }));
  defs.append(marker);
  const boxes = svg("g"), lines = svg("g");
  drawing.append(defs, boxes, lines);
  draw(root, "", boxes, lines);
  host.append(drawing);
}

function naivePaths(path) {
  // Every branch read from the root: right for a path without a nested concurrence.
  const onPath = new Set(), active = new Set();
  for (const branch of path.split(",").filter(Boolean)) {
    const parts = branch.split("/");
    for (let i = 1; i <= parts.length; i++) onPath.add(parts.slice(0, i).join("/"));
    active.add(branch);
  }
  return { onPath, active };
}

function activePaths(root, path) {
  // The running states of an active path, as drawn: "/" goes one level down and ","
  // starts the next running branch, which belongs to the innermost open container that
  // has that name among its states, a concurrence first (a state machine runs one state
  // at a time). "DANCE/MUSIC,MOVES/STEP" is DANCE/MUSIC and DANCE/MOVES/STEP.
  const onPath = new Set(), active = new Set();
  if (!root || !path) return naivePaths(path || "");
  const tokens = path.split(/([/,])/);
  const open = [{ node: root, path: "" }];
  let last = null;
  const childOf = (node, name) => kids(node).find((c) => c.name === name) || null;
  for (let i = 0; i < tokens.length; i += 2) {
    const name = tokens[i], sep = i > 0 ? tokens[i - 1] : "";
    if (sep === "/") open.push(last);
    else if (sep === ",") {
      active.add(last.path);
      let at = -1;
      for (let j = open.length - 1; j >= 0; j--) {
        if (!childOf(open[j].node, name)) continue;
        if (!isMachine(open[j].node)) { at = j; break; }
        if (at < 0) at = j;
      }
      if (at < 0) return naivePaths(path);
      open.length = at + 1;
    }
    const parent = open[open.length - 1];
    const child = childOf(parent.node, name);
    if (!child) return naivePaths(path);
    last = { node: child, path: parent.path ? parent.path + "/" + name : name };
    onPath.add(last.path);
  }
  if (last) active.add(last.path);
  return { onPath, active };
}

function highlight(v) {
  const host = $("machine");
  const activity = obj((v.state || {}).activity);
  const path = activity && typeof activity.state === "string" ? activity.state : "";
  host.classList.toggle("paused", !!activity && activity.status === "paused");
  const structure = obj(v.structure);
  const root = structure && obj(structure.structure) ? obj(structure.structure.root) : null;
  const { onPath, active } = activePaths(root, path);
  for (const g of host.querySelectorAll("g.state")) {
    const p = g.getAttribute("data-path");
    const isActive = p !== "" && active.has(p);
    g.classList.toggle("active", isActive);
    g.classList.toggle("on-path", p === "" ? !!activity : onPath.has(p) && !isActive);
  }
}

// ------------------------------------------------------------------ charts

const charts = { drives: null, motivation: null };

function seriesNames(v, field) {
  const names = new Set();
  for (const sample of v.samples) for (const name of Object.keys(obj(sample[field]) || {})) names.add(name);
  return [...names].sort();
}

function colorOf(name) {
  let hash = 0;
  for (const ch of String(name)) hash = (hash * 31 + ch.charCodeAt(0)) >>> 0;
  return COLORS[hash % COLORS.length];
}

function renderStrip(v) {
  // The activity of each chart point as runs, and each decision as a tick, over the
  // chart's hour: what the robot did beside how its drives went.
  const host = $("timeline-strip");
  host.replaceChildren();
  const samples = v.samples;
  if (samples.length < 2) return;
  const t0 = samples[0][0], t1 = samples[samples.length - 1][0], span = Math.max(1, t1 - t0);
  let start = 0;
  for (let i = 1; i <= samples.length; i++) {
    if (i < samples.length && samples[i][4] === samples[start][4]) continue;
    const name = samples[start][4] || null, end = samples[Math.min(i, samples.length - 1)][0];
    const run = el("div", { class: "run" + (name ? "" : " none"), "data-activity": name || "",
                            title: `${name || "no activity"} ${clock(samples[start][0])}–${clock(end)}` }, name || "");
    run.style.flexGrow = String(Math.max(0.001, end - samples[start][0]));
    if (name) run.style.background = colorOf(name);
    host.append(run);
    start = i;
  }
  for (const d of v.decisions) {
    const t = Date.parse(d.time) / 1000;
    if (!(t >= t0 && t <= t1)) continue;
    const tick = el("span", { class: "tick", title: `${isoClock(d.time)} ${d.action} ${d.activity || ""} [${d.reason}]` });
    tick.style.left = `${((t - t0) / span) * 100}%`;
    host.append(tick);
  }
}

function renderCharts(v, rebuild) {
  if (typeof uPlot === "undefined") return;
  const drives = seriesNames(v, 1), motivations = seriesNames(v, 2);
  const thresholds = Object.keys(v.thresholds || {}).filter((n) => drives.includes(n)).sort();
  const xs = v.samples.map((s) => s[0]);
  const driveData = [xs, ...drives.map((n) => v.samples.map((s) => (obj(s[1]) || {})[n] ?? null)),
                     ...thresholds.map((n) => xs.map(() => v.thresholds[n]))];
  const motivationData = [xs, ...motivations.map((n) => v.samples.map((s) => (obj(s[2]) || {})[n] ?? null)),
                          v.samples.map((s) => (typeof s[3] === "number" ? s[3] : null))];
  const driveKey = "d:" + drives.join(",") + "|t:" + thresholds.join(",");
  const motivationKey = "m:" + motivations.join(",");
  const note = { state: "dashed: thresholds", config: "dashed: thresholds (the daemon's configuration)",
                 defaults: "dashed: thresholds (the shipped defaults: the daemon did not say its own)" }[v.thresholds_source] || "";
  $("thresholds-note").textContent = note;
  charts.drives = chart(charts.drives, $("chart-drives"), driveKey, rebuild, driveData, () => [
    {},
    ...drives.map((n, i) => ({ label: n, stroke: COLORS[i % COLORS.length], width: 2 })),
    ...thresholds.map((n) => ({ label: n + " threshold", stroke: COLORS[drives.indexOf(n) % COLORS.length], width: 1, dash: [6, 4] })),
  ], "drives (deficit, 0–100)", [0, 100]);
  charts.motivation = chart(charts.motivation, $("chart-motivation"), motivationKey, rebuild, motivationData, () => [
    {},
    ...motivations.map((n, i) => ({ label: n + " motivation", stroke: COLORS[i % COLORS.length], width: 2 })),
    { label: "wellbeing", stroke: "#111827", width: 2, dash: [2, 2] },
  ], "motivations and wellbeing", null);
}

function chart(existing, host, key, rebuild, data, series, title, range) {
  if (existing && existing._key === key && !rebuild) { existing.setData(data); return existing; }
  if (existing) existing.destroy();
  host.replaceChildren();
  const opts = {
    title, width: Math.max(300, host.clientWidth || 600), height: 220,
    scales: { x: { time: true }, y: range ? { range: () => range } : { auto: true } },
    series: series(),
    axes: [{ space: 70, values: (_u, ticks) => ticks.map((t) => clock(t)) }, { size: 44 }],
    legend: { live: false },
  };
  const made = new uPlot(opts, data, host);
  made._key = key;
  return made;
}

window.addEventListener("resize", () => {
  for (const [name, c] of Object.entries(charts)) {
    if (c) c.setSize({ width: Math.max(300, $("chart-" + name).clientWidth), height: 220 });
  }
});

// ------------------------------------------------------------------ lists

function whyText(why) {
  why = obj(why);
  if (!why) return "";
  const parts = [];
  const rule = obj(why.rule);
  if (rule) parts.push(`rule ${rule.component}${rule.file ? " " + String(rule.file).split("/").pop() + ":" + rule.line : ""}`);
  const mode = obj(why.mode);
  if (mode && typeof mode.draw === "number" && typeof mode.p_user === "number") {
    parts.push(`draw ${num(mode.draw, 2)} vs p_user ${num(mode.p_user, 2)}${mode.mode ? " → " + mode.mode : ""}`);
  }
  if (Array.isArray(why.preferences) && why.preferences.length) {
    parts.push("likes " + why.preferences.filter(obj).map((p) => `${p.activity} ${num(p.score, 2)}`).join(", "));
  }
  const motivation = obj(why.motivation);
  if (motivation) parts.push(`dominant ${motivation.dominant || "none"}`);
  if (why.evidence) parts.push(String(why.evidence));
  return parts.join("; ");
}

function renderDecisions(v) {
  const list = $("decisions");
  list.replaceChildren();
  if (!v.decisions.length) list.append(el("li", { class: "muted" }, "no decision yet"));
  for (const d of v.decisions.slice(-SHOWN_DECISIONS).reverse()) {
    const item = el("li", { "data-action": d.action || "", "data-activity": d.activity || "" });
    item.append(el("span", { class: "when" }, isoClock(d.time)), el("span", { class: "badge " + d.action }, d.action), " ");
    item.append(el("b", {}, d.activity || ""), " ", el("span", { class: "reason" }, `[${d.reason}${d.chosen_by ? " by " + d.chosen_by : ""}]`));
    if (d.detail) item.append(" ", el("span", { class: "muted" }, d.detail));
    if (typeof d.oversized === "number") {
      item.classList.add("oversized");
      item.append(" ", el("span", { class: "badge oversized" },
        `${Math.round(d.oversized / 1024)} kB: too large for the viewer, only its short fields kept`));
    }
    const why = whyText(d.why);
    if (why) item.append(el("div", { class: "why" }, "why: " + why));
    if (obj(d.why)) {
      const details = el("details");
      details.append(el("summary", { class: "muted" }, "why (all)"), el("pre", {}, JSON.stringify(d.why, null, 2)));
      item.append(details);
    }
    list.append(item);
  }
}

function renderErrors(v) {
  const list = $("errors");
  list.replaceChildren();
  if (!v.errors.length) list.append(el("li", { class: "muted" }, "no error"));
  for (const e of v.errors.slice(-SHOWN_ERRORS).reverse()) {
    const item = el("li");
    item.append(el("span", { class: "when" }, isoClock(e.time)), el("span", { class: "key" }, e.key), el("span", {}, e.error));
    list.append(item);
  }
}

function renderAgenda(v) {
  const host = $("agenda");
  host.replaceChildren();
  const agenda = obj(v.agenda);
  if (!agenda) { host.textContent = "not read yet"; return; }
  if (agenda.error) { host.append(el("span", { class: "muted" }, "not available: " + agenda.error)); return; }
  const items = Array.isArray(agenda.items) ? agenda.items.filter(obj) : [];
  if (!items.length) host.append(el("span", { class: "muted" }, "nothing upcoming"));
  for (const item of items.slice(0, 10)) {
    const when = item.next_fire ? new Date(Date.parse(item.next_fire)).toLocaleString([], { hour12: false }) : "–";
    host.append(el("div", { class: "agenda-item" }, `${when} · ${item.user_id} · ${item.kind}${item.activity ? " " + item.activity : ""}${item.text ? ": " + item.text : ""}`));
  }
}

connect();
