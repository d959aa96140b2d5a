// Automatic layout with dagre (vendor/dagre.min.js, MIT), left to right as the
// behavior runs: each container's states are laid out inside it, innermost first, and
// the container becomes a box of that size in its parent. A state machine's transitions
// are the edges; a container's outcomes are end nodes (pills) inside its box. A state
// placed by hand (doc.layout[path] = [x, y], its top left inside its container) stays
// where it was put; the others are laid out around it.

import { blockOf, childKey, join, MACHINES } from "./doc.js";

const LEAF_H = 46;
const PORT_W = 72;
const MIN_W = 150;
const PAD = 16;
const HEADER = 34;
const END_W = 74;
const END_H = 22;

function leafWidth(name, outcomes) {
  return Math.max(MIN_W, outcomes.length * PORT_W, name.length * 8 + 24);
}

// Lay out the states of the container at `path` (kind: its block; "" is the behavior).
// Returns {w, h, items}: items with x, y relative to the box's top left.
function box(doc, path, kind, outcomesOf) {
  const states = doc.statesOf(path) || {};
  const machine = !path || MACHINES.includes(kind);
  const graph = new dagre.graphlib.Graph();
  graph.setGraph({ rankdir: "LR", nodesep: 30, ranksep: 60, marginx: PAD, marginy: PAD });
  graph.setDefaultEdgeLabel(() => ({}));
  const inner = {};
  for (const [name, state] of Object.entries(states)) {
    const here = join(path, name);
    const block = blockOf(state);
    const outcomes = outcomesOf(here);
    if (childKey(block)) {
      const laid = box(doc, here, block, outcomesOf);
      const w = Math.max(laid.w, leafWidth(name, outcomes));
      inner[name] = { items: laid.items, innerW: laid.w, w, h: laid.h + HEADER + 18 };
    } else {
      inner[name] = { items: [], innerW: 0, w: leafWidth(name, outcomes), h: LEAF_H };
    }
    graph.setNode(name, { width: inner[name].w, height: inner[name].h });
  }
  const ends = machine ? doc.containerOutcomes(path) : [];
  for (const outcome of ends) graph.setNode(`\u0000${outcome}`, { width: END_W, height: END_H });
  if (machine) {
    for (const [name, state] of Object.entries(states)) {
      const seen = new Set();
      for (const target of Object.values(state.transitions || {})) {
        const to = target in states ? target : ends.includes(target) ? `\u0000${target}` : null;
        if (to && !seen.has(to) && to !== name) graph.setEdge(name, to);
        seen.add(to);
      }
      // an outcome that passes through to the container's outcome of the same name
      for (const outcome of outcomesOf(join(path, name))) {
        const written = (state.transitions || {})[outcome];
        if (written === undefined && ends.includes(outcome)) graph.setEdge(name, `\u0000${outcome}`);
      }
    }
    // a state nothing leads to yet (just added, say) goes right of the one written
    // before it, not into a pile in the first column: a hint to the layout, not drawn
    const names = Object.keys(states);
    const reached = new Set(graph.edges().map((edge) => edge.w));
    names.forEach((name, index) => {
      if (index > 0 && !reached.has(name) && !graph.hasEdge(names[index - 1], name)) {
        graph.setEdge(names[index - 1], name, { weight: 0 });
      }
    });
  }
  dagre.layout(graph);
  const items = [];
  let right = MIN_W;
  let bottom = 40;
  for (const id of graph.nodes()) {
    const node = graph.node(id);
    let x = node.x - node.width / 2;
    let y = node.y - node.height / 2;
    if (id.startsWith("\u0000")) {
      items.push({ kind: "end", container: path, outcome: id.slice(1), x, y, w: END_W, h: END_H });
    } else {
      const here = join(path, id);
      const pin = doc.layout[here];
      if (Array.isArray(pin)) [x, y] = pin;
      items.push({ kind: "state", path: here, x, y, w: node.width, h: node.height, inner: inner[id], pinned: !!pin });
    }
    right = Math.max(right, x + node.width + PAD);
    bottom = Math.max(bottom, y + node.height + PAD);
  }
  return { w: right, h: bottom, items };
}

// Every state and end node with absolute coordinates: [{kind, path, x, y, w, h, ox, oy},
// ...]; (ox, oy) is the origin of its container, where a placement by hand is counted from.
export function layout(doc, outcomesOf) {
  const placed = [];
  function place(items, dx, dy) {
    for (const item of items) {
      const x = item.x + dx;
      const y = item.y + dy;
      if (item.kind === "end") {
        placed.push({ ...item, x, y });
        continue;
      }
      const container = item.inner.items.length > 0 || childKey(blockOf(doc.state(item.path)));
      placed.push({ kind: "state", path: item.path, x, y, w: item.w, h: item.h, ox: dx, oy: dy,
        container: !!container, pinned: item.pinned });
      if (container) place(item.inner.items, x + (item.w - item.inner.innerW) / 2, y + HEADER);
    }
  }
  const top = box(doc, "", "state_machine", outcomesOf);
  place(top.items, 0, 0);
  return { items: placed, w: top.w, h: top.h };
}

export const LEAF_HEIGHT = LEAF_H;
