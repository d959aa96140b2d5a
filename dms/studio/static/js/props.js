// The properties panel: the selected state's name, its block's parameters (a form made
// from the block's schema), its transitions, and the loader's messages at their field.
// With nothing selected it shows the behavior's own settings.

import { blockOf, childKey, join, MACHINES, nameOf, parentOf } from "./doc.js";
import { activityForm } from "./activity.js";
import { field } from "./fields.js";
import { keyframesForm, mappingForm, outcomeMapForm, taskFramesForm } from "./forms.js";

const HIDDEN = ["states", "state"];
const SET_DATA = {
  values: "Keys set to these values.",
  add: "Numbers added to these keys.",
  append: "Values appended to these lists.",
};

function h(tag, attrs, text) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, value);
  if (text !== undefined) node.textContent = text;
  return node;
}

export class Props {
  constructor(panel, handlers) {
    this.panel = panel;
    // {doc(), blocks, top, limits, rename, select, outcomesOf, action, setParam, setParams,
    //  play(path), goto(joints)}
    this.handlers = handlers;
    this.fields = {};
    this.messages = [];
    this.path = null;
  }

  render(path) {
    this.path = path;
    this.fields = {};
    this.panel.replaceChildren();
    const doc = this.handlers.doc();
    const state = path ? doc.state(path) : null;
    if (path && !state) this.path = null;
    if (!this.path) this.renderBehavior(doc);
    else this.renderState(doc, this.path, state);
    this.showMessages(this.messages);
  }

  renderBehavior(doc) {
    this.panel.appendChild(h("h2", {}, "Behavior"));
    this.panel.appendChild(h("div", { class: "doc" },
      "Click a block on the left to add a state; click a state to edit it."));
    const top = this.handlers.top;
    for (const name of ["name", "description", "outcomes", "userdata", "attend", "frames"]) {
      const schema = top[name] || {};
      const required = ["name", "outcomes"].includes(name);
      const set = (value) => this.handlers.setParams("", { [name]: value }, true);
      let made;
      if (name === "userdata") {
        made = mappingForm(name, "userdata", doc.data.userdata, "The keys the behavior starts with, and their values.", set);
      } else if (name === "frames") {
        made = taskFramesForm(doc.data.frames, set);
      } else {
        made = field(name, schema, doc.data[name], required, (value, typing) => {
          this.handlers.setParam("", name, value, typing);
        });
      }
      this.fields[name] = made;
      this.panel.appendChild(made.element);
    }
    const names = Object.keys(doc.statesOf("") || {});
    if (names.length) {
      const initial = field("initial", { enum: names, default: names[0], description: "The first state." },
        doc.data.initial, false, (value) => this.handlers.setParam("", "initial", value, false));
      this.fields.initial = initial;
      this.panel.appendChild(initial.element);
    }
    this.fields.activity = activityForm(doc.data.activity, top.activity || {},
      (value, typing) => this.handlers.setParam("", "activity", value, typing));
    this.panel.appendChild(this.fields.activity.element);
    this.addProblems();
  }

  renderState(doc, path, state) {
    const block = blockOf(state);
    const info = this.handlers.blocks[block] || { schema: { properties: {} }, doc: "" };
    this.panel.appendChild(h("h2", {}, `${nameOf(path)} (${block})`));
    this.panel.appendChild(h("div", { class: "doc" }, info.doc));
    const rename = field("state name", { type: "string", description:
      "Renaming follows the transitions that name this state." }, nameOf(path), true, () => {});
    rename.input.id = "state-name";
    rename.input.addEventListener("change", () => {
      const value = rename.input.value.trim();
      if (value && value !== nameOf(path)) this.handlers.rename(path, value);
    });
    this.panel.appendChild(rename.element);
    const params = state[block] || {};
    const schema = info.schema || { properties: {} };
    const required = schema.required || [];
    for (const [name, prop] of Object.entries(schema.properties || {})) {
      if (HIDDEN.includes(name)) continue;
      const made = this.structured(doc, path, block, name, params)
        || field(name, prop, params[name], required.includes(name), (value, typing) => {
          this.handlers.setParam(path, name, value, typing);
        });
      if (made === "none") continue;
      this.fields[name] = made;
      if (block === "pose" && name === "keyframes") this.fields.seconds = made;
      this.panel.appendChild(made.element);
    }
    if (MACHINES.includes(doc.containerKind(parentOf(path)))) this.renderTransitions(doc, path, state);
    const actions = h("div", { class: "actions" });
    const buttons = [["Run this state", "run-state"], ["Copy", "copy"], ["Paste", "paste"],
      ["Delete", "delete"]];
    if (childKey(block)) buttons.unshift(["Add inside: pick a block", "noop"]);
    for (const [label, action] of buttons) {
      if (action === "noop") {
        actions.appendChild(h("div", { class: "help" }, "A block clicked now goes inside this container."));
        continue;
      }
      const button = h("button", { "data-action": action }, label);
      button.addEventListener("click", () => this.handlers.action(action, path));
      actions.appendChild(button);
    }
    this.panel.appendChild(actions);
    this.addProblems();
  }

  // A form for a parameter that is a structure (null: an ordinary field; "none": shown
  // by another one's form, as a pose's seconds are by its keyframes).
  structured(doc, path, block, name, params) {
    if (block === "pose" && name === "seconds") return "none";
    if (block === "pose" && name === "keyframes" && !(typeof params.keyframes === "string")) {
      return keyframesForm(params.keyframes, params.seconds, this.handlers.limits, {
        onChange: (keyframes, seconds, quiet) => this.handlers.setParams(path, { keyframes, seconds }, quiet),
        play: () => this.handlers.play(path),
        goto: (joints) => this.handlers.goto(joints),
      });
    }
    if (name === "userdata") {
      return mappingForm(name, "userdata", params.userdata, "This container's own keys and their values.",
        (value) => this.handlers.setParams(path, { [name]: value }, true));
    }
    if (block === "set_data" && SET_DATA[name] && (params[name] === undefined || typeof params[name] === "object")) {
      return mappingForm(name, name, params[name], SET_DATA[name],
        (value) => this.handlers.setParams(path, { [name]: value }, true));
    }
    if (block === "concurrence" && name === "outcome_map") {
      const children = Object.keys(doc.statesOf(path) || {})
        .map((child) => [child, this.handlers.outcomesOf(join(path, child))]);
      return outcomeMapForm(params.outcome_map, params.outcomes || [], children,
        (value) => this.handlers.setParams(path, { [name]: value }, true));
    }
    return null;
  }

  // Several states selected: what can be done to them together.
  renderMany(paths) {
    this.path = null;
    this.fields = {};
    this.panel.replaceChildren();
    this.panel.appendChild(h("h2", {}, `${paths.length} states selected`));
    this.panel.appendChild(h("div", { class: "doc" },
      "Drag one of them to move them all; Delete removes them (Undo brings them back). "
      + "Shift-click adds or removes a state; Shift-drag on the background selects a rectangle."));
    const list = h("ul", { class: "selection" });
    for (const path of paths) {
      const item = h("li", {}, path);
      item.addEventListener("click", () => this.handlers.select(path));
      list.appendChild(item);
    }
    this.panel.appendChild(list);
    const remove = h("button", { "data-action": "delete" }, `Delete ${paths.length} states`);
    remove.addEventListener("click", () => this.handlers.action("delete", null));
    this.panel.appendChild(remove);
    this.addProblems();
    this.showMessages(this.messages);
  }

  renderTransitions(doc, path, state) {
    const box = h("div", { class: "field", "data-param": "transitions" });
    box.appendChild(h("label", {}, "transitions"));
    const parent = parentOf(path);
    const siblings = Object.keys(doc.statesOf(parent) || {}).filter((n) => n !== nameOf(path));
    const ends = doc.containerOutcomes(parent);
    const transitions = state.transitions || {};
    for (const outcome of this.handlers.outcomesOf(path)) {
      const row = h("div", { class: "row" });
      row.appendChild(h("span", {}, outcome));
      const select = h("select", { "data-outcome": outcome, "aria-label": `after ${outcome}` });
      const passes = ends.includes(outcome) ? ` (ends: ${outcome})` : "";
      select.appendChild(h("option", { value: "" }, `— none${passes} —`));
      for (const name of siblings) select.appendChild(h("option", { value: name }, `→ ${name}`));
      for (const end of ends) select.appendChild(h("option", { value: end }, `ends: ${end}`));
      select.value = transitions[outcome] || "";
      select.addEventListener("change", () => this.handlers.connect(path, outcome, select.value || null));
      row.appendChild(select);
      box.appendChild(row);
    }
    const messages = h("div");
    box.appendChild(messages);
    this.panel.appendChild(box);
    this.fields.transitions = {
      element: box,
      setMessages(list) {
        messages.replaceChildren(...list.map((m) => h("div", { class: `msg ${m.severity}` }, m.text)));
        box.classList.toggle("bad", list.some((m) => m.severity === "error"));
      },
    };
  }

  addProblems() {
    this.panel.appendChild(h("h2", {}, "Problems"));
    this.problemList = h("ul", { class: "problems" });
    this.panel.appendChild(this.problemList);
  }

  // The checker's messages: at their field for this state, all of them in the list.
  showMessages(messages) {
    this.messages = messages;
    const here = this.path || "";
    const byField = {};
    for (const message of messages) {
      if (message.path === here && message.param && this.fields[message.param]) {
        (byField[message.param] = byField[message.param] || []).push(message);
      }
    }
    for (const [name, made] of Object.entries(this.fields)) made.setMessages(byField[name] || []);
    if (!this.problemList) return;
    this.problemList.replaceChildren();
    for (const message of messages) {
      const where = message.path || "behavior";
      const item = h("li", { class: message.severity }, `${where}: ${message.text}`);
      item.addEventListener("click", () => this.handlers.select(message.path || null));
      this.problemList.appendChild(item);
    }
    if (!messages.length) this.problemList.appendChild(h("li", { class: "ok" }, "none: it loads"));
  }
}
