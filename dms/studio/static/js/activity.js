// The Activity form (docs/studio.md, "Making it an activity"): declares the behavior an
// activity the robot offers, starts on request and chooses by itself. Its fields come
// from the `activity` schema of the behavior format (the manager's and the features'
// choices are the loader's), and what it writes is the file's `activity:` key.

import { field } from "./fields.js";

const NUMBERS = ["age"];
const BOOLEANS = ["lives_alone"];

function h(tag, attrs, text) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, value);
  if (text !== undefined) node.textContent = text;
  return node;
}

// A feature's values as the file holds them: whole years for age, true/false for
// lives_alone, the words as typed for the others.
function featureValues(name, value) {
  if (!Array.isArray(value)) return value;
  if (NUMBERS.includes(name)) return value.map((item) => (Number.isNaN(Number(item)) ? item : Number(item)));
  if (BOOLEANS.includes(name)) return value.map((item) => (item === "true" ? true : item === "false" ? false : item));
  return value;
}

// The form for `declared` (the `activity:` mapping, or undefined); onChange(value, typing)
// gets the new mapping, or undefined when the behavior is no longer an activity.
// Returns {element, setMessages(list)} as a field does.
export function activityForm(declared, schema, onChange) {
  const box = h("fieldset", { class: "field activity", "data-param": "activity" });
  box.appendChild(h("legend", {}, "Activity"));
  const toggle = h("input", { type: "checkbox", id: "activity-declared" });
  toggle.checked = declared !== undefined && declared !== null;
  const label = h("label", { for: "activity-declared" }, " offer it as an activity");
  const line = h("div", { class: "row" });
  line.append(toggle, label);
  box.appendChild(line);
  const help = h("div", { class: "help" },
    "Its manager, menu name and picture, expected length, the user features that suggest "
    + "someone likes it (the robot's first guess), and whether it may be paused.");
  box.appendChild(help);
  const current = { ...(declared || {}) };
  const features = { ...(current.features || {}) };
  const props = (schema && schema.properties) || {};

  function emit(typing) {
    const out = {};
    for (const key of ["manager", "menu", "picture", "expected_s"]) {
      if (current[key] !== undefined && current[key] !== "") out[key] = current[key];
    }
    const chosen = Object.fromEntries(Object.entries(features).filter(([, v]) => v !== undefined));
    if (Object.keys(chosen).length) out.features = chosen;
    if (current.pausable === false) out.pausable = false;
    onChange(out, typing);
  }

  const fields = h("div", { class: "activity-fields" });
  for (const key of ["manager", "menu", "picture", "expected_s", "pausable"]) {
    const required = (schema.required || []).includes(key);
    const made = field(key, props[key] || {}, current[key], required, (value, typing) => {
      current[key] = value;
      emit(typing);
    });
    fields.appendChild(made.element);
  }
  const featureProps = (props.features && props.features.properties) || {};
  for (const [name, prop] of Object.entries(featureProps)) {
    const choices = (prop.items && prop.items.enum) || null;
    const shown = { ...prop, description: choices ? `one per line: ${choices.join(", ")}` : prop.description };
    const made = field(name, shown, features[name], false, (value, typing) => {
      features[name] = featureValues(name, value);
      emit(typing);
    });
    fields.appendChild(made.element);
  }
  fields.hidden = !toggle.checked;
  box.appendChild(fields);
  toggle.addEventListener("change", () => {
    fields.hidden = !toggle.checked;
    if (toggle.checked) emit(false);
    else onChange(undefined, false);
  });

  const messages = h("div");
  box.appendChild(messages);
  return {
    element: box,
    input: toggle,
    setMessages(list) {
      messages.replaceChildren(...list.map((m) => h("div", { class: `msg ${m.severity}` }, m.text)));
      box.classList.toggle("bad", list.some((m) => m.severity === "error"));
    },
  };
}
