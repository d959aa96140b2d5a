// The canvas: the state machine drawn in SVG, states as boxes (containers hold theirs),
// outcomes as ports under each state, transitions as arrows, left to right. Drag from a
// port (its whole dot) to a state or an end node to draw a transition; drag a state to
// place it by hand (the selected states move together); Shift-click adds a state to the
// selection, Shift-drag on the background selects a rectangle; the wheel zooms,
// dragging the background pans. While a drag is under way the drawing is not remade
// (a check that comes back meanwhile is drawn when it ends), so no drag is lost.

import { blockOf, join, MACHINES, nameOf, parentOf } from "./doc.js";
import { layout } from "./layout.js";
import { el } from "./svg.js";

const PORT_HIT = 11; // the radius a press on a port counts within
const MOVE_PX = 4; // a press that moves less than this is a click

export class Canvas {
  constructor(svg, doc, handlers) {
    this.svg = svg;
    this.doc = doc;
    // {select(path, {add}), selectMany(paths), connect(path, outcome, target),
    //  place(moves), defaultOutcomes(block, params)}
    this.handlers = handlers;
    this.outcomes = {}; // path -> outcomes, from the server's check
    this.selected = null; // the state whose properties are shown
    this.selection = new Set(); // every selected state
    this.lit = new Set();
    this.marks = {}; // path -> "bad" | "warn"
    this.view = { x: 20, y: 20, scale: 1 };
    this.placed = { items: [], w: 0, h: 0 };
    this.drag = null;
    this.pending = false; // a render asked for during a drag
    this.preview = null; // {paths, dx, dy}: states being moved, drawn moved
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

  item(path) {
    return this.placed.items.find((item) => item.kind === "state" && item.path === path) || null;
  }

  // ------------------------------------------------------------ drawing

  render() {
    if (this.drag) {
      this.pending = true;
      return;
    }
    this.draw();
  }

  draw() {
    this.placed = layout(this.doc, (path) => this.outcomesOf(path));
    if (this.preview) this.shift(this.preview);
    this.root.replaceChildren();
    const edges = el("g", { class: "edges" }, this.root); // under the states and their ports
    const positions = {};
    for (const item of this.placed.items) {
      if (item.kind === "end") this.drawEnd(item);
      else positions[item.path] = this.drawState(item);
    }
    this.drawEdges(edges, positions);
    this.applyView();
    this.svg.dataset.drawn = String(Number(this.svg.dataset.drawn || 0) + 1);
  }

  // The states being moved (and what they hold) drawn at their new place.
  shift({ paths, dx, dy }) {
    const inside = (path) => paths.some((moved) => path === moved || path.startsWith(`${moved}/`));
    for (const item of this.placed.items) {
      const path = item.kind === "end" ? item.container : item.path;
      if (path && inside(path)) {
        item.x += dx;
        item.y += dy;
      }
    }
  }

  drawState(item) {
    const state = this.doc.state(item.path);
    const block = blockOf(state);
    const classes = ["state"];
    if (item.container) classes.push("container");
    if (this.selection.has(item.path)) classes.push("selected");
    if (item.pinned) classes.push("pinned");
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
        "data-path": item.path, transform: `translate(${px},${item.h})` }, group);
      el("circle", { class: "hit", r: PORT_HIT }, port); // the whole dot and around it
      el("circle", { class: "dot", r: 6 }, port);
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
        // down out of the port, into the target's left side
        const end = { x: to.x, y: to.y + Math.min(to.h / 2, 23) };
        const reach = Math.max(30, Math.abs(end.x - start.x) / 2);
        const d = `M${start.x},${start.y} C${start.x},${start.y + 40} ${end.x - reach},${end.y} ${end.x},${end.y}`;
        el("path", { class: "edge", d, "data-from": path, "data-outcome": outcome, "data-to": target }, layer);
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
    const xs = this.placed.items.map((item) => item.x);
    const ys = this.placed.items.map((item) => item.y);
    const left = Math.min(0, ...xs);
    const top = Math.min(0, ...ys);
    const w = Math.max(this.placed.w - left, 1);
    const h = Math.max(this.placed.h - top, 1);
    const scale = Math.min(1, Math.max(0.2, Math.min((rect.width - 40) / w, (rect.height - 40) / h)));
    this.view = { x: (rect.width - w * scale) / 2 - left * scale, y: 20 - top * scale, scale };
    this.applyView();
  }

  // Pan (never zoom) so that the state at path is in view, with a margin.
  reveal(path) {
    const item = this.item(path);
    if (!item) return;
    const rect = this.svg.getBoundingClientRect();
    const { x, y, scale } = this.view;
    const margin = 30;
    const left = x + item.x * scale;
    const top = y + item.y * scale;
    const right = left + item.w * scale;
    const bottom = top + (item.h + 20) * scale;
    let dx = 0;
    let dy = 0;
    if (right > rect.width - margin) dx = rect.width - margin - right;
    if (left + dx < margin) dx = margin - left;
    if (bottom > rect.height - margin) dy = rect.height - margin - bottom;
    if (top + dy < margin) dy = margin - top;
    this.view = { x: x + dx, y: y + dy, scale };
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

  press(event) {
    const port = event.target.closest(".port");
    if (port && this.inMachine(port.dataset.path)) {
      const item = this.item(port.dataset.path);
      const outcomes = this.outcomesOf(port.dataset.path);
      const index = outcomes.indexOf(port.dataset.port);
      const start = { x: item.x + ((index + 0.5) * item.w) / outcomes.length, y: item.y + item.h };
      const line = el("path", { class: "dragline" }, this.root);
      return { kind: "connect", path: port.dataset.path, outcome: port.dataset.port, start, line, over: null };
    }
    const state = event.target.closest(".state");
    const at = { x: event.clientX, y: event.clientY };
    if (state) return { kind: "press", path: state.dataset.path, at, add: event.shiftKey, moved: false };
    if (event.shiftKey) {
      const band = el("rect", { class: "band" }, this.root);
      return { kind: "band", from: this.toCanvas(event), band };
    }
    return { kind: "pan", at, view: { ...this.view }, moved: false };
  }

  bindPointer() {
    this.svg.addEventListener("pointerdown", (event) => {
      if (event.button !== 0) return;
      this.drag = this.press(event);
      this.svg.setPointerCapture(event.pointerId);
      event.preventDefault();
    });
    this.svg.addEventListener("pointermove", (event) => {
      const drag = this.drag;
      if (!drag) return;
      if (drag.kind === "connect") {
        const at = this.toCanvas(event);
        drag.line.setAttribute("d", `M${drag.start.x},${drag.start.y} L${at.x},${at.y}`);
        const found = this.dropTarget(event, drag.path);
        if (drag.over && drag.over !== (found && found.element)) drag.over.classList.remove("target");
        drag.over = found ? found.element : null;
        if (drag.over) drag.over.classList.add("target");
      } else if (drag.kind === "press") {
        const dx = event.clientX - drag.at.x;
        const dy = event.clientY - drag.at.y;
        if (!drag.moved && Math.abs(dx) + Math.abs(dy) < MOVE_PX) return;
        if (!drag.moved) this.startMove(drag);
        this.preview = { paths: drag.paths, dx: dx / this.view.scale, dy: dy / this.view.scale };
        this.draw();
      } else if (drag.kind === "band") {
        const at = this.toCanvas(event);
        const x = Math.min(at.x, drag.from.x);
        const y = Math.min(at.y, drag.from.y);
        Object.assign(drag, { to: at });
        for (const [key, value] of Object.entries({ x, y, width: Math.abs(at.x - drag.from.x),
          height: Math.abs(at.y - drag.from.y) })) drag.band.setAttribute(key, value);
      } else if (drag.kind === "pan") {
        const dx = event.clientX - drag.at.x;
        const dy = event.clientY - drag.at.y;
        if (Math.abs(dx) + Math.abs(dy) > 3) drag.moved = true;
        this.view = { ...drag.view, x: drag.view.x + dx, y: drag.view.y + dy };
        this.applyView();
      }
    });
    const release = (event) => {
      const done = this.drag;
      if (!done) return;
      this.drag = null;
      this.finish(done, event);
      if (this.pending || done.kind === "press") {
        this.pending = false;
        this.draw();
      }
    };
    this.svg.addEventListener("pointerup", release);
    this.svg.addEventListener("pointercancel", () => {
      // the browser took the pointer away: the drag is dropped, nothing changes
      const done = this.drag;
      if (!done) return;
      this.drag = null;
      this.preview = null;
      if (done.line) done.line.remove();
      if (done.band) done.band.remove();
      this.pending = false;
      this.draw();
    });
    this.svg.addEventListener("wheel", (event) => {
      event.preventDefault();
      const rect = this.svg.getBoundingClientRect();
      this.zoom(event.deltaY < 0 ? 1.1 : 1 / 1.1, event.clientX - rect.left, event.clientY - rect.top);
    }, { passive: false });
  }

  // A state pressed starts to move: it, and the other selected states with it.
  startMove(drag) {
    drag.moved = true;
    if (!this.selection.has(drag.path)) this.handlers.select(drag.path, { add: drag.add });
    const chosen = [...this.selection];
    drag.paths = chosen.filter((path) => !chosen.some((other) => path.startsWith(`${other}/`)));
  }

  finish(done, event) {
    if (done.kind === "connect") {
      done.line.remove();
      if (done.over) done.over.classList.remove("target");
      const found = this.dropTarget(event, done.path);
      if (found) this.handlers.connect(done.path, done.outcome, found.target);
    } else if (done.kind === "press" && done.moved) {
      const { dx, dy } = this.preview;
      this.preview = null;
      const moves = {};
      for (const path of done.paths) {
        const item = this.item(path); // drawn moved: placed holds the new place
        const floor = parentOf(path) ? 4 : -1e5; // inside a container: not out of its box
        if (item) moves[path] = [Math.max(item.x - item.ox, floor), Math.max(item.y - item.oy, floor)];
      }
      if (Object.keys(moves).length && (dx || dy)) this.handlers.place(moves);
    } else if (done.kind === "press") {
      this.handlers.select(done.path, { add: done.add });
    } else if (done.kind === "band") {
      done.band.remove();
      const to = done.to || done.from;
      const [x0, x1] = [Math.min(to.x, done.from.x), Math.max(to.x, done.from.x)];
      const [y0, y1] = [Math.min(to.y, done.from.y), Math.max(to.y, done.from.y)];
      const inside = this.placed.items.filter((item) => item.kind === "state"
        && item.x >= x0 && item.x + item.w <= x1 && item.y >= y0 && item.y + item.h <= y1);
      this.handlers.selectMany(inside.map((item) => item.path));
    } else if (!done.moved) {
      this.handlers.select(null);
    }
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
