// One form field per parameter, made from the parameter's JSON Schema: its type, its
// choices, its default and its unit (from the name: timeout_s is in seconds). A value
// may be a placeholder ({answer}) where the format allows it: such text is kept as text.

const UNITS = [
  [/_per_s$/, "per second"],
  [/_s$/, "seconds"],
  [/_rad$/, "radians"],
  [/_m$/, "metres"],
];
let frames = ["user", "face:<id>", "object:<name>"];
let taskFrames = []; // the behavior's own (frames: at its top)
const FRAME_PARAMS = ["frame", "toward", "attend"];
const LONG_TEXT = ["text", "question", "description"];
const SINGLE = /^\s*\{[A-Za-z_][\w.]*(\|[^{}]*)?\}\s*$/;

// The kinds a schema allows, placeholders aside: {types, choices}.
export function kinds(schema) {
  const options = schema.anyOf || [schema];
  const types = new Set();
  let choices = null;
  for (const option of options) {
    if (option.pattern && option.type === "string" && option.pattern.includes("[A-Za-z_]")) continue;
    if (option.enum) choices = option.enum;
    if (option.const !== undefined) choices = [...(choices || []), option.const];
    if (option.type) types.add(option.type);
    else if (!option.enum && option.const === undefined) types.add("any");
  }
  if (schema.choices) choices = schema.choices; // the robot's repertoire (the palette's)
  return { types, choices };
}

function unitOf(name) {
  for (const [pattern, unit] of UNITS) if (pattern.test(name)) return unit;
  return "";
}

function shown(value, types) {
  if (value === undefined || value === null) return "";
  if (typeof value === "string") return value;
  if (Array.isArray(value) && types.has("array") && value.every((item) => typeof item !== "object")) {
    return value.join("\n");
  }
  if (typeof value === "object") return JSON.stringify(value);
  return String(value);
}

// The value a person typed, as the file would hold it (undefined: left empty).
export function parseValue(text, types) {
  if (text.trim() === "") return undefined;
  if (SINGLE.test(text)) return text.trim();
  if ((types.has("number") || types.has("integer")) && !types.has("string")) {
    const number = Number(text);
    return Number.isNaN(number) ? text : number;
  }
  if (types.has("array") && !types.has("string")) {
    const trimmed = text.trim();
    if (trimmed.startsWith("[")) {
      try {
        return JSON.parse(trimmed);
      } catch (_error) {
        return text;
      }
    }
    return text.split(/\n/).map((line) => line.trim()).filter(Boolean).map((item) => {
      const number = Number(item);
      return types.has("any") && item !== "" && !Number.isNaN(number) ? number : item;
    });
  }
  if ((types.has("object") || types.has("any")) && !types.has("string")) {
    try {
      return JSON.parse(text);
    } catch (_error) {
      return text;
    }
  }
  return text;
}

// A field for parameter `name`: {element, setMessages(list)}; onInput(value, typing).
export function field(name, schema, value, required, onInput) {
  const { types, choices } = kinds(schema);
  const wrap = document.createElement("div");
  wrap.className = "field";
  wrap.dataset.param = name;
  const label = document.createElement("label");
  const unit = unitOf(name);
  label.innerHTML = `${name}${required ? " *" : ""}${unit ? ` <span class="unit">(${unit})</span>` : ""}`;
  wrap.appendChild(label);
  const id = `param-${name}`;
  label.htmlFor = id;
  let input;
  if (choices) {
    input = document.createElement("select");
    const empty = document.createElement("option");
    empty.value = "";
    empty.textContent = schema.default !== undefined ? `(default: ${schema.default})` : "(none)";
    input.appendChild(empty);
    const listed = value === undefined || choices.some((choice) => JSON.stringify(choice) === JSON.stringify(value));
    for (const choice of listed ? choices : [value, ...choices]) {
      const option = document.createElement("option");
      option.value = JSON.stringify(choice);
      option.textContent = String(choice);
      if (value !== undefined && JSON.stringify(value) === option.value) option.selected = true;
      input.appendChild(option);
    }
    input.addEventListener("change", () => onInput(input.value ? JSON.parse(input.value) : undefined, false));
  } else if (types.size === 1 && types.has("boolean")) {
    input = document.createElement("input");
    input.type = "checkbox";
    input.checked = value === undefined ? schema.default === true : value === true;
    input.addEventListener("change", () => onInput(input.checked, false));
  } else {
    const multi = LONG_TEXT.includes(name) || (types.has("array") && !types.has("string"))
      || ((types.has("object") || types.has("any")) && !types.has("string"));
    input = document.createElement(multi ? "textarea" : "input");
    if (!multi) input.type = "text";
    input.value = shown(value, types);
    if (schema.default !== undefined && schema.default !== null) {
      input.placeholder = `default: ${shown(schema.default, types) || "(empty)"}`;
    }
    if (types.has("array") && !types.has("string")) input.placeholder = "one per line";
    if (FRAME_PARAMS.includes(name)) {
      input.setAttribute("list", "frames");
      ensureFrames();
    }
    if (schema.suggestions) {
      // names to pick from (the media the content lists); another may still be typed
      input.setAttribute("list", suggestionList(name, schema.suggestions));
    }
    // every keystroke is an edit (one undo step per field); no re-render on blur, so a
    // click elsewhere is never lost to a form made again under it
    input.addEventListener("input", () => onInput(parseValue(input.value, types), true));
  }
  input.id = id;
  input.name = name;
  wrap.appendChild(input);
  if (schema.description) {
    const help = document.createElement("div");
    help.className = "help";
    help.textContent = schema.description;
    wrap.appendChild(help);
  }
  const messages = document.createElement("div");
  wrap.appendChild(messages);
  return {
    element: wrap,
    input,
    setMessages(list) {
      messages.replaceChildren();
      wrap.classList.remove("bad", "warn");
      for (const message of list) {
        const line = document.createElement("div");
        line.className = `msg ${message.severity}`;
        line.textContent = message.text;
        messages.appendChild(line);
        wrap.classList.add(message.severity === "error" ? "bad" : "warn");
      }
    },
  };
}

// A datalist of `names` for parameter `name` (made once per parameter); its id.
function suggestionList(name, names) {
  const id = `suggest-${name}`;
  let list = document.getElementById(id);
  if (!list) {
    list = document.createElement("datalist");
    list.id = id;
    document.body.appendChild(list);
  }
  list.replaceChildren();
  for (const each of names) {
    const option = document.createElement("option");
    option.value = each;
    list.appendChild(option);
  }
  return id;
}

// The frame picker's suggestions, for look_at, point_at, attend and gestures toward:
// the frames the daemon sees now when the studio is connected to one.
function ensureFrames() {
  let list = document.getElementById("frames");
  if (!list) {
    list = document.createElement("datalist");
    list.id = "frames";
    document.body.appendChild(list);
  }
  list.replaceChildren();
  for (const frame of [...taskFrames, ...frames]) {
    const option = document.createElement("option");
    option.value = frame;
    list.appendChild(option);
  }
}

export function setFrames(list) {
  frames = list;
  ensureFrames();
}

// The task frames the behavior declares, offered first by the frame picker.
export function setTaskFrames(names) {
  if (JSON.stringify(names) === JSON.stringify(taskFrames)) return;
  taskFrames = names;
  ensureFrames();
}
