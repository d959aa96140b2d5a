// The studio page: the palette, the canvas, the properties and the trial, wired to the
// behavior being edited; it is checked by the server after each change.

import { get, post } from "./api.js";
import { Canvas } from "./canvas.js";
import { blockOf, Doc, nameOf, parentOf } from "./doc.js";
import { setFrames, setTaskFrames } from "./fields.js";
import { Files } from "./files.js";
import { Posing } from "./pose.js";
import { Props } from "./props.js";
import { RulesPane } from "./rules.js";
import { Trial } from "./trial.js";

const CHECK_MS = 250;
const POSE_PARAMS = ["joints", "pose", "keyframes"];
const FIRST_VALUES = {
  outcomes: ["done"], continue_on: ["done"], default_outcome: "done",
  connector_outcome: "done", states: {}, state: {},
};

const app = {
  doc: new Doc({ name: "new_behavior", outcomes: ["done"], states: {} }, { name: null, hash: null }),
  folder: "",
  blocks: {},
  top: {},
  selected: null,
  clipboard: null,
  checkTimer: null,
  checkSeq: 0,
  lastPose: null,
};

function status(text, kind = "") {
  const box = document.getElementById("status");
  box.textContent = text;
  box.className = kind;
}

// The outcomes of a block before the server has said (its defaults).
function defaultOutcomes(block, params) {
  if (params && Array.isArray(params.outcomes)) return params.outcomes;
  return (app.blocks[block] && app.blocks[block].outcomes) || [];
}

function firstParams(block) {
  const schema = app.blocks[block].schema;
  const params = {};
  for (const name of schema.required || []) {
    if (name in FIRST_VALUES) params[name] = JSON.parse(JSON.stringify(FIRST_VALUES[name]));
    else {
      const prop = schema.properties[name] || {};
      const types = (prop.anyOf || [prop]).map((option) => option.type);
      params[name] = types.includes("array") ? [] : types.includes("string") ? "" : null;
    }
  }
  return params;
}

// ------------------------------------------------------------ palette

function renderPalette(categories) {
  const box = document.getElementById("palette");
  box.replaceChildren();
  for (const category of categories) {
    const title = document.createElement("h3");
    title.textContent = category.title;
    box.appendChild(title);
    for (const block of category.blocks) {
      app.blocks[block.name] = block;
      const button = document.createElement("button");
      button.className = "block";
      button.dataset.block = block.name;
      button.textContent = block.name;
      button.title = block.doc;
      button.addEventListener("click", () => addBlock(block.name));
      box.appendChild(button);
    }
  }
}

// A new state of `block`: inside the selected container, else beside the selected state.
function addBlock(block) {
  const doc = app.doc;
  let parent = "";
  if (app.selected) parent = doc.isContainer(app.selected) ? app.selected : parentOf(app.selected);
  const name = doc.uniqueName(parent, block);
  const path = doc.addState(parent, name, { [block]: firstParams(block) });
  select(path);
  canvas.reveal(path);
}

// ------------------------------------------------------------ selection and edits

const canvas = new Canvas(document.getElementById("canvas"), app.doc, {
  select: (path, { add = false } = {}) => select(path, add),
  selectMany: (paths) => selectMany(paths),
  connect: (path, outcome, target) => app.doc.setTransition(path, outcome, target),
  place: (moves) => app.doc.place(moves),
  defaultOutcomes,
});

const props = new Props(document.getElementById("props"), {
  doc: () => app.doc,
  get blocks() { return app.blocks; },
  get top() { return app.top; },
  outcomesOf: (path) => canvas.outcomesOf(path),
  get limits() { return posing.limits; },
  setParam: (path, name, value, typing) => app.doc.setParam(path, name, value, typing),
  setParams: (path, values, quiet) => app.doc.setParams(path, values, quiet),
  play: (path) => trial.start(path, true),
  goto: (joints) => posing.pose(joints),
  rename: (path, name) => {
    const renamed = app.doc.rename(path, name);
    if (renamed) select(renamed);
    else status(`cannot rename to ${name}: a state of that name exists`, "bad");
  },
  connect: (path, outcome, target) => app.doc.setTransition(path, outcome, target),
  select: (path) => select(path),
  action: (action, path) => act(action, path),
});

// Select a state (add: toggle it in the selection, as Shift-click does); null: none.
function select(path, add = false) {
  const found = path && app.doc.state(path) ? path : null;
  if (add && found) {
    if (canvas.selection.has(found)) canvas.selection.delete(found);
    else canvas.selection.add(found);
  } else {
    canvas.selection = new Set(found ? [found] : []);
  }
  showSelection();
}

function selectMany(paths) {
  canvas.selection = new Set(paths.filter((path) => app.doc.state(path)));
  showSelection();
}

function showSelection() {
  for (const path of [...canvas.selection]) if (!app.doc.state(path)) canvas.selection.delete(path);
  const chosen = [...canvas.selection];
  app.selected = chosen.length === 1 ? chosen[0] : null;
  canvas.selected = app.selected;
  canvas.render();
  if (chosen.length > 1) props.renderMany(chosen);
  else props.render(app.selected);
  document.body.dataset.selected = String(chosen.length);
}

function act(action, path) {
  if (action === "delete" && canvas.selection.size > 1) {
    app.doc.deleteStates([...canvas.selection]);
    select(null);
  } else if (action === "delete" && path) {
    app.doc.deleteState(path);
    select(null);
  } else if (action === "copy" && canvas.selection.size) {
    // the selected states of one container (those of the first one's, if several)
    const chosen = [...canvas.selection].filter((one) => parentOf(one) === parentOf([...canvas.selection][0]));
    app.clipboard = chosen.map((one) => ({ name: nameOf(one), state: JSON.parse(JSON.stringify(app.doc.state(one))) }));
    status(`copied ${chosen.map(nameOf).join(", ")}`);
  } else if (action === "paste" && app.clipboard) {
    const parent = path ? (app.doc.isContainer(path) ? path : parentOf(path)) : "";
    const pasted = app.doc.pasteMany(parent, app.clipboard);
    selectMany(pasted);
    if (pasted.length === 1) select(pasted[0]);
  } else if (action === "run-state" && path) {
    trial.runState();
  }
}

function watch(doc) {
  doc.onChange((structural, kind) => {
    if (kind === "load") {
      canvas.outcomes = {};
      canvas.selection = new Set();
      app.selected = null;
      canvas.selected = null;
      canvas.render();
      canvas.fit();
      props.render(null);
      document.getElementById("open-select").value = doc.file.name || "";
    } else if (kind !== "saved") {
      canvas.render();
      if (structural) showSelection();
    }
    if (kind !== "saved") {
      scheduleCheck();
      files.edited();
      const declared = doc.data.frames;
      setTaskFrames(declared && typeof declared === "object" ? Object.keys(declared) : []);
    }
    updateTitle();
  });
}

function updateTitle() {
  const doc = app.doc;
  const file = doc.file.name ? `${doc.file.name}.yaml` : "new, not saved";
  const title = document.getElementById("doc-title");
  title.textContent = `${doc.data.name || "?"} (${file})`;
  title.classList.toggle("modified", doc.modified);
  title.title = doc.modified ? "modified: not saved yet" : "as saved";
  document.body.dataset.modified = doc.modified ? "1" : "0";
  document.title = `${doc.modified ? "● " : ""}${doc.data.name || "?"} — dms studio`;
}

// ------------------------------------------------------------ checking

function scheduleCheck() {
  clearTimeout(app.checkTimer);
  app.checkTimer = setTimeout(check, CHECK_MS);
}

async function check() {
  const seq = (app.checkSeq += 1);
  const reply = await post("/api/check", { doc: app.doc.data });
  if (seq !== app.checkSeq || !reply.ok) return;
  const report = reply.data;
  const changedPorts = JSON.stringify(report.outcomes) !== JSON.stringify(canvas.outcomes);
  canvas.outcomes = report.outcomes;
  canvas.marks = {};
  for (const message of report.messages) {
    if (!message.path) continue;
    if (message.severity === "error") canvas.marks[message.path] = "bad";
    else if (!canvas.marks[message.path]) canvas.marks[message.path] = "warn";
  }
  canvas.render();
  if (changedPorts) rerenderKeepingFocus();
  props.showMessages(report.messages);
  const errors = report.messages.filter((m) => m.severity === "error").length;
  const warnings = report.messages.length - errors;
  document.body.dataset.checked = String(seq);
  status(errors ? `${errors} problem(s): it does not load yet` : warnings ? `loads; ${warnings} warning(s)` : "loads",
    errors ? "bad" : "good");
}

// After the ports changed (a branch added outcomes), the form is made again with the
// new transitions: the field being typed in keeps the focus and the caret.
function rerenderKeepingFocus() {
  const active = document.activeElement;
  const id = active && active.id;
  const caret = active && "selectionStart" in active ? [active.selectionStart, active.selectionEnd] : null;
  if (canvas.selection.size > 1) props.renderMany([...canvas.selection]);
  else props.render(app.selected);
  const again = id && document.getElementById(id);
  if (!again) return;
  again.focus();
  if (caret && caret[0] !== null) again.setSelectionRange(caret[0], caret[1]);
}

// ------------------------------------------------------------ files

async function refreshList(selectName) {
  const reply = await get("/api/behaviors");
  if (!reply.ok) return status(reply.data.error, "bad");
  const select = document.getElementById("open-select");
  select.replaceChildren(new Option("…", ""));
  for (const name of reply.data.names) select.appendChild(new Option(name, name));
  select.value = selectName || "";
  select.title = reply.data.folder;
  app.folder = reply.data.folder;
  document.querySelector('#try-on option[value="daemon"]').disabled = !reply.data.daemon;
}

const files = new Files(app, { status, refreshList });

// ------------------------------------------------------------ record

function record(joints) {
  app.lastPose = joints;
  const path = app.selected;
  const state = path && app.doc.state(path);
  const block = blockOf(state);
  const props = (block && app.blocks[block].schema.properties) || {};
  const param = POSE_PARAMS.find((name) => name in props);
  const shown = Object.entries(joints).map(([k, v]) => `${k} ${v.toFixed(2)}`).join(", ");
  if (!param) {
    status(`recorded pose: ${shown} (select a pose state to keep it as a keyframe)`);
    return;
  }
  const type = (props[param].anyOf || [props[param]]).map((option) => option.type);
  const old = state[block][param];
  const value = type.includes("array") ? [...(Array.isArray(old) ? old : []), joints] : joints;
  app.doc.setParam(path, param, value, false);
  const count = Array.isArray(value) ? ` (keyframe ${value.length})` : "";
  status(`recorded pose into ${param}${count}: ${shown}`, "good");
}

new RulesPane();
const posing = new Posing({ status });

const trial = new Trial({
  doc: () => app.doc,
  selected: () => app.selected,
  lit: (paths) => {
    canvas.lit = paths;
    canvas.render();
  },
  status,
  record,
  moved: (joints) => posing.show(joints),
});

// ------------------------------------------------------------ start

function bindKeys() {
  document.addEventListener("keydown", (event) => {
    const typing = ["INPUT", "TEXTAREA", "SELECT"].includes(event.target.tagName);
    const mod = event.ctrlKey || event.metaKey;
    if (mod && event.key === "s") {
      event.preventDefault();
      files.save();
    } else if (typing) {
      return;
    } else if (mod && event.key === "z") {
      app.doc.undo();
    } else if (mod && (event.key === "y" || (event.shiftKey && event.key === "Z"))) {
      app.doc.redo();
    } else if (mod && event.key === "c") {
      act("copy", app.selected);
    } else if (mod && event.key === "v") {
      act("paste", app.selected);
    } else if (event.key === "Delete" && canvas.selection.size) {
      act("delete", app.selected);
    } else if (mod && event.key === "a" && !document.body.classList.contains("rules-open")) {
      event.preventDefault();
      selectMany(Object.keys(app.doc.statesOf("") || {}));
    }
  });
  const on = (id, fn) => document.getElementById(id).addEventListener("click", fn);
  on("new-button", () => files.newDoc());
  on("save-button", () => files.save());
  on("undo-button", () => app.doc.undo());
  on("redo-button", () => app.doc.redo());
  on("zoom-in", () => canvas.zoom(1.2));
  on("zoom-out", () => canvas.zoom(1 / 1.2));
  on("zoom-fit", () => canvas.fit());
  on("arrange", () => {
    const chosen = canvas.selection.size ? [...canvas.selection] : null;
    if (!app.doc.unplace(chosen)) status("nothing placed by hand to lay out again");
  });
  document.getElementById("open-select").addEventListener("change", (event) => files.open(event.target.value));
}

async function start() {
  bindKeys();
  // asked together: each answer is small, the round trips are what the page waits for
  const [reply, frames] = await Promise.all([get("/api/palette"), get("/api/frames"),
    refreshList(""), posing.start()]);
  if (!reply.ok) {
    status(reply.data.error || "the studio refused the page: open the URL it printed", "bad");
    return;
  }
  renderPalette(reply.data.categories);
  app.top = reply.data.top;
  if (frames.ok) setFrames(frames.data.frames);
  watch(app.doc);
  canvas.render();
  canvas.fit();
  props.render(null);
  updateTitle();
  scheduleCheck();
  const wanted = new URLSearchParams(location.search).get("open");
  const loaded = wanted ? await files.load(wanted) : true;
  document.body.dataset.ready = "1";
  if (loaded) await files.offerDraft(wanted || null); // edits this browser kept, if any
}

start();
