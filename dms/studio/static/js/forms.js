// Forms for the parameters that are structures, so that nobody types JSON: a pose's
// keyframes (a row per keyframe, a number per joint, its seconds), a mapping of names to
// values (userdata), and a concurrence's outcome map (per outcome, what each state must
// have ended with). Each returns what fields.js's field() returns: {element, setMessages}.

const JOINT_ORDER = ["hip", "neck", "head", "left_arm", "right_arm"];

function h(tag, attrs, text) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) node.setAttribute(key, value);
  if (text !== undefined) node.textContent = text;
  return node;
}

function holder(name, title, help) {
  const wrap = h("div", { class: "field form", "data-param": name });
  wrap.appendChild(h("label", {}, title));
  const body = h("div", { class: "form-body" });
  wrap.appendChild(body);
  if (help) wrap.appendChild(h("div", { class: "help" }, help));
  const messages = h("div");
  wrap.appendChild(messages);
  const setMessages = (list) => {
    messages.replaceChildren(...list.map((m) => h("div", { class: `msg ${m.severity}` }, m.text)));
    wrap.classList.toggle("bad", list.some((m) => m.severity === "error"));
  };
  return { wrap, body, setMessages };
}

// A number as typed, or undefined for an empty box (NaN stays text, for the check to flag).
function number(text) {
  if (text.trim() === "") return undefined;
  const value = Number(text);
  return Number.isNaN(value) ? text : value;
}

// A value typed in a box: a number, true or false, else the text itself.
function scalar(text) {
  const trimmed = text.trim();
  if (trimmed === "true" || trimmed === "false") return trimmed === "true";
  if (trimmed !== "" && !Number.isNaN(Number(trimmed))) return Number(trimmed);
  if (/^[[{"]/.test(trimmed)) {
    try {
      return JSON.parse(trimmed);
    } catch (_error) {
      return text;
    }
  }
  return text;
}

function shownScalar(value) {
  return typeof value === "string" ? value : JSON.stringify(value);
}

// keyframes and seconds of a pose: onChange(keyframes, seconds); play(index|null) tries
// them on the simulated Mini; goto(keyframe) poses it there.
export function keyframesForm(keyframes, seconds, limits, { onChange, play, goto }) {
  const { wrap, body, setMessages } = holder("keyframes", "keyframes *",
    "A row per pose, radians per joint (empty: the joint stays); seconds: how long the move takes. "
    + "Pose the Mini with the sliders below and press Record to add one.");
  const frames = Array.isArray(keyframes) ? keyframes.map((frame) => ({ ...frame })) : [];
  const times = Array.isArray(seconds) ? [...seconds] : [];
  const joints = JOINT_ORDER.filter((name) => name in limits);
  // quiet: a value typed in a cell (the table shows it); a row moved or removed: drawn anew
  const emit = (quiet = true) => {
    while (times.length && times[times.length - 1] === undefined) times.pop();
    onChange(frames, times.length ? times.map((t) => (t === undefined ? null : t)) : undefined, quiet);
  };
  const table = h("table", { class: "keyframes" });
  const head = h("tr");
  for (const title of ["#", ...joints, "seconds", ""]) head.appendChild(h("th", {}, title));
  table.appendChild(head);
  frames.forEach((frame, index) => {
    const row = h("tr", { "data-keyframe": String(index) });
    row.appendChild(h("td", {}, String(index + 1)));
    for (const joint of joints) {
      const { low, high } = limits[joint];
      const input = h("input", { type: "number", step: "0.01", min: String(low), max: String(high),
        "data-joint": joint, "aria-label": `keyframe ${index + 1} ${joint}` });
      input.value = frame[joint] ?? "";
      input.addEventListener("change", () => {
        const value = number(input.value);
        if (value === undefined) delete frame[joint];
        else frame[joint] = value;
        emit();
      });
      row.appendChild(h("td")).appendChild(input);
    }
    const time = h("input", { type: "number", step: "0.1", min: "0.1", max: "60", "data-seconds": String(index),
      placeholder: "fast", "aria-label": `keyframe ${index + 1} seconds` });
    time.value = times[index] ?? "";
    time.addEventListener("change", () => {
      times[index] = number(time.value);
      emit();
    });
    row.appendChild(h("td")).appendChild(time);
    const tools = h("td", { class: "tools" });
    const button = (label, title, action, fn) => {
      const made = h("button", { title, "data-action": action }, label);
      made.addEventListener("click", fn);
      tools.appendChild(made);
    };
    button("⇢", "Pose the simulated Mini as this keyframe (the sliders follow)", "goto", () => goto(frame));
    button("↑", "Move it up", "up", () => {
      if (index === 0) return;
      [frames[index - 1], frames[index]] = [frames[index], frames[index - 1]];
      [times[index - 1], times[index]] = [times[index], times[index - 1]];
      emit(false);
    });
    button("✕", "Remove this keyframe", "remove", () => {
      frames.splice(index, 1);
      times.splice(index, 1);
      emit(false);
    });
    row.appendChild(tools);
    table.appendChild(row);
  });
  body.appendChild(table);
  if (!frames.length) body.appendChild(h("div", { class: "help" }, "No keyframe yet."));
  const playButton = h("button", { id: "play-pose", title: "Play this motion on the simulated Mini" }, "▶ Play the motion");
  playButton.addEventListener("click", () => play());
  body.appendChild(playButton);
  return { element: wrap, setMessages };
}

// A mapping of names to values (userdata): a row each, and one empty row to add.
export function mappingForm(name, title, mapping, help, onChange) {
  const { wrap, body, setMessages } = holder(name, title, help);
  const rows = Object.entries(mapping && typeof mapping === "object" && !Array.isArray(mapping) ? mapping : {});
  const emit = () => {
    const out = {};
    for (const [key, value] of rows) if (key) out[key] = value;
    onChange(Object.keys(out).length ? out : undefined);
  };
  const addRow = (entry, index) => {
    const row = h("div", { class: "row" });
    const key = h("input", { type: "text", placeholder: "name", "aria-label": `${name} name ${index + 1}` });
    key.value = entry[0];
    const value = h("input", { type: "text", placeholder: "value (a number, true, text...)",
      "aria-label": `${name} value ${index + 1}` });
    value.value = index < rows.length ? shownScalar(entry[1]) : "";
    const update = () => {
      if (index === rows.length) {
        rows.push(["", ""]);
        addRow(["", ""], rows.length); // a blank row to add the next one
      }
      rows[index] = [key.value.trim(), scalar(value.value)];
      emit();
    };
    key.addEventListener("change", update);
    value.addEventListener("change", update);
    row.append(key, value);
    body.appendChild(row);
  };
  rows.forEach((entry, index) => addRow(entry, index));
  addRow(["", ""], rows.length);
  return { element: wrap, setMessages };
}

// A concurrence's outcome map: for each of its outcomes, what each state must have
// ended with (any: not required). children: [[name, outcomes], ...].
export function outcomeMapForm(map, outcomes, children, onChange) {
  const { wrap, body, setMessages } = holder("outcome_map", "outcome_map",
    "The concurrence ends with an outcome once each state named has ended with the outcome chosen, in order.");
  const current = map && typeof map === "object" ? JSON.parse(JSON.stringify(map)) : {};
  for (const outcome of outcomes) {
    const group = h("div", { class: "map-group" });
    group.appendChild(h("div", { class: "map-outcome" }, `ends “${outcome}” when`));
    for (const [child, childOutcomes] of children) {
      const row = h("div", { class: "row" });
      row.appendChild(h("span", {}, child));
      const select = h("select", { "data-map": `${outcome}/${child}`, "aria-label": `${outcome}: ${child}` });
      select.appendChild(h("option", { value: "" }, "(any)"));
      for (const option of childOutcomes) select.appendChild(h("option", { value: option }, `ended ${option}`));
      select.value = (current[outcome] || {})[child] || "";
      select.addEventListener("change", () => {
        const wanted = { ...(current[outcome] || {}) };
        if (select.value) wanted[child] = select.value;
        else delete wanted[child];
        if (Object.keys(wanted).length) current[outcome] = wanted;
        else delete current[outcome];
        onChange(Object.keys(current).length ? { ...current } : undefined);
      });
      row.appendChild(select);
      group.appendChild(row);
    }
    body.appendChild(group);
  }
  return { element: wrap, setMessages };
}

// The behavior's task frames: a row each (name, the marker it hangs from, its offset
// xyz in metres and rpy in radians), and one empty row to add one.
export function taskFramesForm(frames, onChange) {
  const { wrap, body, setMessages } = holder("frames", "task frames",
    "Places relative to a detected marker or object (of), kept where last known once it is lost; "
    + "look_at, point_at and gesture aim at them by name.");
  const rows = Object.entries(frames && typeof frames === "object" && !Array.isArray(frames) ? frames : {})
    .map(([name, frame]) => [name, { ...frame }]);
  const emit = () => {
    const out = {};
    for (const [name, frame] of rows) {
      if (!name) continue;
      const kept = { of: frame.of || "" };
      for (const key of ["xyz", "rpy"]) {
        if (Array.isArray(frame[key]) && frame[key].some((v) => v !== 0)) kept[key] = frame[key];
      }
      out[name] = kept;
    }
    onChange(Object.keys(out).length ? out : undefined);
  };
  const table = h("table", { class: "task-frames" });
  const head = h("tr");
  for (const title of ["name", "of", "x", "y", "z", "roll", "pitch", "yaw", ""]) head.appendChild(h("th", {}, title));
  table.appendChild(head);
  const addRow = ([name, frame], index) => {
    const row = h("tr", { "data-frame": name });
    const take = () => {
      if (index === rows.length) {
        rows.push(["", { of: "" }]);
        addRow(["", { of: "" }], rows.length); // a blank row to add the next one
      }
      return rows[index];
    };
    const nameBox = h("input", { type: "text", placeholder: "handle", "aria-label": `task frame ${index + 1} name` });
    nameBox.value = name;
    nameBox.addEventListener("change", () => {
      take()[0] = nameBox.value.trim();
      emit();
    });
    row.appendChild(h("td")).appendChild(nameBox);
    const of = h("input", { type: "text", list: "frames", placeholder: "object:tag7", "aria-label": `task frame ${index + 1} of` });
    of.value = frame.of || "";
    of.addEventListener("change", () => {
      take()[1].of = of.value.trim();
      emit();
    });
    row.appendChild(h("td")).appendChild(of);
    for (const [key, unit] of [["xyz", "m"], ["rpy", "rad"]]) {
      [0, 1, 2].forEach((axis) => {
        const box = h("input", { type: "number", step: "0.01", placeholder: "0", "data-axis": `${key}${axis}`,
          "aria-label": `task frame ${index + 1} ${key}[${axis}] (${unit})` });
        const values = Array.isArray(frame[key]) ? frame[key] : null;
        box.value = values ? values[axis] : "";
        box.addEventListener("change", () => {
          const held = take()[1];
          const triple = Array.isArray(held[key]) ? [...held[key]] : [0, 0, 0];
          triple[axis] = number(box.value) ?? 0;
          held[key] = triple;
          emit();
        });
        row.appendChild(h("td")).appendChild(box);
      });
    }
    const remove = h("button", { title: "Remove this task frame", "data-action": "remove" }, "✕");
    remove.addEventListener("click", () => {
      if (index >= rows.length) return;
      rows[index] = ["", { of: "" }]; // emptied, not spliced: the other rows keep their index
      row.remove();
      emit();
    });
    row.appendChild(h("td")).appendChild(remove);
    table.appendChild(row);
  };
  rows.forEach((entry, index) => addRow(entry, index));
  addRow(["", { of: "" }], rows.length);
  body.appendChild(table);
  return { element: wrap, setMessages };
}
