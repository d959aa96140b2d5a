// The canvas: the state machine drawn in SVG, states as boxes (containers hold theirs),
// outcomes as ports under each state, transitions as arrows. Drag from a port to a state
// or an end node to draw a transition; the wheel zooms, dragging the background pans.

import { blockOf, join, MACHINES, nameOf, parentOf } from "./doc.js";
import { layout } from "./layout.js";

const SVG = "http://www.w3.org/2000/svg";
const PORT_Y = 0; // ports sit on the bottom edge

function el(name, attrs, parent) {
  const node = document.createElementNS(SVG, name);
  for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, value);
  if (parent) parent.appendChild(node);
  return node;
}

export class Canvas {
  constructor(svg, doc, handlers) {
    this.svg = svg;
    this.doc = doc;
    this.handlers = handlers; // {select(path), connect(path, outcome, target)}
    this.outcomes = {}; // path -> outcomes, from the server's check
    this.selected = null;
    this.lit = new Set();
    this.marks = {}; // path -> "bad" | "warn"
    this.view = { x: 20, y: 20, scale: 1 };
    this.placed = { items: [], w: 0, h: 0 };
    const defs = el("defs", {}, svg);
    const marker = el("marker", { id: "arrow", viewBox: "0 0 10 10", refX: 9, refY: 5,
      markerWidth: 7, markerHeight: 7, orient: "auto-start-reverse" }, defs);
    el("path", { d: "M0,0 L10,5 L0,10 z", fill: "#78909c" }, marker);
    this.root = el("g", { id: "viewport" }, svg);
    this.bindPointer();
  }

  setDoc(doc) {
    this.doc = doc;
  }

  outcomesOf(path) {
    if (path in this.outcomes) return this.outcomes[path];
    const state = this.doc.state(path);
    const block = blockOf(state);
    const params = (state && state[block]) || {};
    return this.handlers.defaultOutcomes(block, params);
  }

  // ------------------------------------------------------------ drawing

  render() {
    this.placed = layout(this.doc, (path) => this.outcomesOf(path));
    this.root.replaceChildren();
    const positions = {};
    const edges = el("g", { class: "edges" });
    for (const item of this.placed.items) {
      if (item.kind === "end") this.drawEnd(item);
      else positions[item.path] = this.drawState(item);
    }
    this.root.appendChild(edges);
    this.drawEdges(edges, positions);
    this.applyView();
  }

  drawState(item) {
    const state = this.doc.state(item.path);
    const block = blockOf(state);
    const classes = ["state"];
    if (item.container) classes.push("container");
    if (item.path === this.selected) classes.push("selected");
    if (this.marks[item.path]) classes.push(this.marks[item.path]);
    if (this.lit.has(item.path)) classes.push(item.container ? "on-path" : "lit");
    const group = el("g", { class: classes.join(" "), "data-path": item.path,
      transform: `translate(${item.x},${item.y})` }, this.root);
    el("rect", { width: item.w, height: item.h, rx: 6 }, group);
    const name = el("text", { class: "name", x: 10, y: 18 }, group);
    name.textContent = nameOf(item.path);
    const kind = el("text", { class: "block", x: 10, y: 33 }, group);
    kind.textContent = block || "?";
    if (this.isInitial(item.path)) el("circle", { class: "initial", cx: -6, cy: 12, r: 5 }, group);
    const outcomes = this.outcomesOf(item.path);
    const transitions = (state && state.transitions) || {};
    const inMachine = this.inMachine(item.path);
    const ends = this.doc.containerOutcomes(parentOf(item.path));
    const ports = {};
    outcomes.forEach((outcome, index) => {
      const px = ((index + 0.5) * item.w) / outcomes.length;
      const free = inMachine && !(outcome in transitions) && !ends.includes(outcome);
      const port = el("g", { class: `port${free ? " free" : ""}`, "data-port": outcome,
        "data-path": item.path, transform: `translate(${px},${item.h + PORT_Y})` }, group);
      el("circle", { r: 6 }, port);
      const label = el("text", { x: 8, y: 14 }, port);
      label.textContent = outcome;
      ports[outcome] = { x: item.x + px, y: item.y + item.h };
    });
    return { ...item, ports };
  }

  drawEnd(item) {
    const group = el("g", { class: "terminal", "data-end": item.outcome,
      "data-container": item.container, transform: `translate(${item.x},${item.y})` }, this.root);
    el("rect", { width: item.w, height: item.h, rx: 10 }, group);
    const text = el("text", { x: item.w / 2, y: 15, "text-anchor": "middle" }, group);
    text.textContent = item.outcome;
    item.group = group;
  }

  drawEdges(layer, positions) {
    const ends = {};
    for (const item of this.placed.items) {
      if (item.kind === "end") ends[`${item.container}\u0000${item.outcome}`] = item;
    }
    for (const [path, from] of Object.entries(positions)) {
      if (!this.inMachine(path)) continue;
      const state = this.doc.state(path);
      const parent = parentOf(path);
      const transitions = (state && state.transitions) || {};
      for (const outcome of this.outcomesOf(path)) {
        const start = from.ports[outcome];
        if (!start) continue;
        const target = transitions[outcome] ?? outcome;
        const to = positions[join(parent, target)] || ends[`${parent}\u0000${target}`];
        if (!to) continue;
        const end = { x: to.x + to.w / 2, y: to.y };
        const back = end.y <= start.y;
        const bend = back ? 60 : Math.max(20, (end.y - start.y) / 2);
        const d = back
          ? `M${start.x},${start.y} C${start.x},${start.y + bend} ${end.x + to.w / 2 + 30},${end.y - bend} ${end.x},${end.y}`
          : `M${start.x},${start.y} C${start.x},${start.y + bend} ${end.x},${end.y - bend} ${end.x},${end.y}`;
        el("path", { class: "edge", d, "data-from": path, "data-outcome": outcome }, layer);
      }
    }
  }

  isInitial(path) {
    const parent = parentOf(path);
    const kind = this.doc.containerKind(parent);
    if (!MACHINES.includes(kind)) return false;
    const holder = parent ? this.doc.state(parent)[kind] : this.doc.data;
    const names = Object.keys(this.doc.statesOf(parent) || {});
    return (holder.initial || names[0]) === nameOf(path);
  }

  inMachine(path) {
    return MACHINES.includes(this.doc.containerKind(parentOf(path)));
  }

  // ------------------------------------------------------------ view

  applyView() {
    const { x, y, scale } = this.view;
    this.root.setAttribute("transform", `translate(${x},${y}) scale(${scale})`);
  }

  zoom(factor, cx, cy) {
    const rect = this.svg.getBoundingClientRect();
    const px = cx ?? rect.width / 2;
    const py = cy ?? rect.height / 2;
    const scale = Math.min(3, Math.max(0.2, this.view.scale * factor));
    const k = scale / this.view.scale;
    this.view = { x: px - (px - this.view.x) * k, y: py - (py - this.view.y) * k, scale };
    this.applyView();
  }

  fit() {
    const rect = this.svg.getBoundingClientRect();
    const w = Math.max(this.placed.w, 1);
    const h = Math.max(this.placed.h, 1);
    const scale = Math.min(1.4, Math.max(0.2, Math.min((rect.width - 40) / w, (rect.height - 40) / h)));
    this.view = { x: (rect.width - w * scale) / 2, y: 20, scale };
    this.applyView();
  }

  // ------------------------------------------------------------ pointer

  toCanvas(event) {
    const rect = this.svg.getBoundingClientRect();
    return {
      x: (event.clientX - rect.left - this.view.x) / this.view.scale,
      y: (event.clientY - rect.top - this.view.y) / this.view.scale,
    };
  }

  // The state or end node a transition from `source` may go to, under the pointer.
  dropTarget(event, source) {
    const hit = document.elementFromPoint(event.clientX, event.clientY);
    if (!hit) return null;
    const parent = parentOf(source);
    const end = hit.closest(".terminal");
    if (end && end.dataset.container === parent) return { element: end, target: end.dataset.end };
    const node = hit.closest(".state");
    if (!node) return null;
    let path = node.dataset.path;
    while (path && parentOf(path) !== parent) path = parentOf(path);
    if (!path || path === source) return null;
    const element = this.root.querySelector(`.state[data-path="${CSS.escape(path)}"]`);
    return { element, target: nameOf(path) };
  }

  bindPointer() {
    let drag = null;
    this.svg.addEventListener("pointerdown", (event) => {
      const port = event.target.closest(".port");
      if (port && this.inMachine(port.dataset.path)) {
        const start = this.toCanvas(event);
        const line = el("path", { class: "dragline" }, this.root);
        drag = { kind: "connect", path: port.dataset.path, outcome: port.dataset.port, start, line, over: null };
      } else if (event.target.closest(".state")) {
        drag = { kind: "click", path: event.target.closest(".state").dataset.path };
      } else {
        drag = { kind: "pan", x: event.clientX, y: event.clientY, view: { ...this.view }, moved: false };
      }
      this.svg.setPointerCapture(event.pointerId);
      event.preventDefault();
    });
    this.svg.addEventListener("pointermove", (event) => {
      if (!drag) return;
      if (drag.kind === "connect") {
        const at = this.toCanvas(event);
        drag.line.setAttribute("d", `M${drag.start.x},${drag.start.y} L${at.x},${at.y}`);
        const found = this.dropTarget(event, drag.path);
        if (drag.over && drag.over !== (found && found.element)) drag.over.classList.remove("target");
        drag.over = found ? found.element : null;
        if (drag.over) drag.over.classList.add("target");
      } else if (drag.kind === "pan") {
        const dx = event.clientX - drag.x;
        const dy = event.clientY - drag.y;
        if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
        this.view = { ...drag.view, x: drag.view.x + dx, y: drag.view.y + dy };
        this.applyView();
      }
    });
    this.svg.addEventListener("pointerup", (event) => {
      if (!drag) return;
      const done = drag;
      drag = null;
      if (done.kind === "connect") {
        done.line.remove();
        const found = this.dropTarget(event, done.path);
        if (found) this.handlers.connect(done.path, done.outcome, found.target);
      } else if (done.kind === "click") {
        this.handlers.select(done.path);
      } else if (!done.moved) {
        this.handlers.select(null);
      }
    });
    this.svg.addEventListener("wheel", (event) => {
      event.preventDefault();
      const rect = this.svg.getBoundingClientRect();
      this.zoom(event.deltaY < 0 ? 1.1 : 1 / 1.1, event.clientX - rect.left, event.clientY - rect.top);
    }, { passive: false });
  }
}

// Which states a trial's state path lights: "DANCE/MUSIC,MOVES/STEP" lights DANCE,
// DANCE/MUSIC, DANCE/MOVES and DANCE/MOVES/STEP (the branches of a concurrence).
export function litPaths(statePath) {
  const lit = new Set();
  if (!statePath) return lit;
  let prefix = "";
  for (const segment of statePath.split("/")) {
    const names = segment.split(",");
    for (const name of names) lit.add(prefix ? `${prefix}/${name}` : name);
    prefix = prefix ? `${prefix}/${names[names.length - 1]}` : names[names.length - 1];
  }
  return lit;
}

