// The behavior being edited: plain JSON as the file writes it, changed only through
// these functions, each change kept for undo. A state's path is its names from the
// top, joined by "/"; the behavior itself is the container at path "". Beside it, the
// states placed by hand (layout: path -> [x, y] inside its container) and the file it
// came from; a load is one more undoable change, so Undo reaches back past an Open.

const STATE_KEYS = ["transitions", "input_keys", "output_keys", "remapping"];
export const MACHINES = ["state_machine", "sequence"];
const GROUPS = ["state_machine", "sequence", "concurrence"];
const HISTORY = 200;

export function blockOf(state) {
  const kinds = Object.keys(state || {}).filter((key) => !STATE_KEYS.includes(key));
  return kinds.length === 1 ? kinds[0] : null;
}

export function childKey(block) {
  if (GROUPS.includes(block)) return "states";
  if (block === "iterator" || block === "guard") return "state";
  return null;
}

export function parentOf(path) {
  const at = path.lastIndexOf("/");
  return at === -1 ? "" : path.slice(0, at);
}

export function nameOf(path) {
  return path.slice(path.lastIndexOf("/") + 1);
}

export function join(parent, name) {
  return parent ? `${parent}/${name}` : name;
}

// A value with its mappings' keys in order, to tell whether two documents say the same:
// a parameter removed and put back is not a change. The order of states is kept (the
// first is the initial state, a sequence runs them in order).
export function canonical(value, key = null) {
  if (Array.isArray(value)) return value.map((item) => canonical(item));
  if (!value || typeof value !== "object") return value;
  const names = key === "states" ? Object.keys(value) : Object.keys(value).sort();
  return names.map((name) => [name, canonical(value[name], name)]);
}

export class Doc {
  constructor(data, file, layout = {}) {
    this.data = data;
    this.layout = layout; // path -> [x, y]: the states placed by hand
    this.file = file; // {name, hash}: the file it was opened from (hash null: new)
    this.saved = this.contentKey(); // what the file holds, to tell a modified document
    this.undoStack = [];
    this.redoStack = [];
    this.lastKey = null;
    this.listeners = [];
  }

  onChange(listener) {
    this.listeners.push(listener);
  }

  // kind: "edit" (typing: no structural change), "change", "load" (another document)
  emit(structural, kind = structural ? "change" : "edit") {
    for (const listener of this.listeners) listener(structural, kind);
  }

  contentKey() {
    return JSON.stringify(canonical([this.data, this.layout]));
  }

  get modified() {
    return this.contentKey() !== this.saved;
  }

  snapshot() {
    return JSON.stringify({ data: this.data, layout: this.layout, file: this.file, saved: this.saved });
  }

  restore(text) {
    const before = JSON.stringify(this.file);
    const kept = JSON.parse(text);
    Object.assign(this, { data: kept.data, layout: kept.layout, file: kept.file, saved: kept.saved });
    return JSON.stringify(this.file) !== before;
  }

  keep() {
    this.undoStack.push(this.snapshot());
    if (this.undoStack.length > HISTORY) this.undoStack.shift();
  }

  // Apply fn to the data, kept for undo; changes with the same key in a row (typing in
  // one field) are one step.
  change(fn, { key = null, structural = true } = {}) {
    if (key === null || key !== this.lastKey) this.keep();
    this.lastKey = key;
    this.redoStack = [];
    const result = fn(this.data);
    this.emit(structural);
    return result;
  }

  // Another behavior (an Open, a New, a reload from disk), as one undoable step.
  load(data, file, layout = {}) {
    this.keep();
    this.redoStack = [];
    this.lastKey = null;
    Object.assign(this, { data, layout, file });
    this.saved = this.contentKey();
    this.emit(true, "load");
  }

  // The file now holds what is in the page (after a save).
  markSaved(file) {
    this.file = file;
    this.saved = this.contentKey();
    this.emit(false, "saved");
  }

  undo() {
    return this.travel(this.undoStack, this.redoStack);
  }

  redo() {
    return this.travel(this.redoStack, this.undoStack);
  }

  travel(from, to) {
    if (!from.length) return false;
    to.push(this.snapshot());
    const otherFile = this.restore(from.pop());
    this.lastKey = null;
    this.emit(true, otherFile ? "load" : "change");
    return true;
  }

  // ------------------------------------------------------------ placement

  // Place states by hand: moves is path -> [x, y] (inside its container), one step.
  place(moves) {
    this.change(() => {
      this.layout = { ...this.layout };
      for (const [path, at] of Object.entries(moves)) this.layout[path] = at.map((v) => Math.round(v));
    });
  }

  // Forget where paths (all: null) were placed by hand: laid out again, one step.
  unplace(paths = null) {
    const dropped = Object.keys(this.layout).filter((path) => !paths || paths.includes(path));
    if (!dropped.length) return false;
    this.change(() => {
      this.layout = Object.fromEntries(Object.entries(this.layout).filter(([path]) => !dropped.includes(path)));
    });
    return true;
  }

  // The placements of path and the states inside it: dropped, or moved to newPath.
  movePins(path, newPath) {
    const moved = {};
    for (const [pinned, at] of Object.entries(this.layout)) {
      if (pinned === path || pinned.startsWith(`${path}/`)) {
        if (newPath) moved[newPath + pinned.slice(path.length)] = at;
      } else {
        moved[pinned] = at;
      }
    }
    this.layout = moved;
  }

  // ------------------------------------------------------------ reading

  state(path) {
    if (!path) return null;
    let states = this.data.states || {};
    let state = null;
    for (const name of path.split("/")) {
      state = states[name];
      if (!state) return null;
      const block = blockOf(state);
      const key = childKey(block);
      states = (key && state[block] && state[block][key]) || {};
    }
    return state;
  }

  // The states mapping of the container at path ("" is the behavior's).
  statesOf(path, create = false) {
    if (!path) {
      if (!this.data.states && create) this.data.states = {};
      return this.data.states || {};
    }
    const state = this.state(path);
    const block = blockOf(state);
    const key = childKey(block);
    if (!key) return null;
    state[block] = state[block] || {};
    if (!state[block][key] && create) state[block][key] = {};
    return state[block][key] || {};
  }

  containerKind(path) {
    if (!path) return "state_machine";
    return blockOf(this.state(path));
  }

  isContainer(path) {
    return childKey(blockOf(this.state(path))) !== null;
  }

  // The outcomes of the container at path (a machine's transitions may end in them).
  containerOutcomes(path) {
    if (!path) return this.data.outcomes || [];
    const state = this.state(path);
    const block = blockOf(state);
    return (state && state[block] && state[block].outcomes) || [];
  }

  // ------------------------------------------------------------ changing

  uniqueName(parent, base) {
    const states = this.statesOf(parent) || {};
    const root = base.toUpperCase().replace(/[^A-Z0-9_]/g, "_");
    let name = root;
    for (let n = 2; name in states; n += 1) name = `${root}_${n}`;
    return name;
  }

  addState(parent, name, state) {
    return this.change((data) => {
      const states = this.statesOf(parent, true);
      const kind = this.containerKind(parent);
      if (childKey(kind) === "state") {
        for (const old of Object.keys(states)) delete states[old]; // one state only
      }
      states[name] = state;
      return join(parent, name);
    });
  }

  deleteState(path) {
    this.deleteStates([path]);
  }

  // Delete states (one undo step); a state inside another deleted one goes with it.
  deleteStates(paths) {
    const outer = paths.filter((path) => !paths.some((other) => path.startsWith(`${other}/`)));
    this.change(() => {
      for (const path of outer) this.removeState(path);
    });
  }

  removeState(path) {
    {
      const parent = parentOf(path);
      const name = nameOf(path);
      const states = this.statesOf(parent);
      delete states[name];
      for (const other of Object.values(states)) {
        const transitions = other.transitions || {};
        for (const [outcome, target] of Object.entries(transitions)) {
          if (target === name) delete transitions[outcome];
        }
      }
      this.fixInitial(parent, name, null);
      this.movePins(path, null);
    }
  }

  fixInitial(parent, oldName, newName) {
    const holder = parent ? this.state(parent)[this.containerKind(parent)] : this.data;
    if (holder && holder.initial === oldName) {
      if (newName === null) delete holder.initial;
      else holder.initial = newName;
    }
  }

  // Rename a state, and every reference to it: its siblings' transitions, the
  // container's initial state and a concurrence's outcome map.
  rename(path, newName) {
    const parent = parentOf(path);
    const oldName = nameOf(path);
    const states = this.statesOf(parent);
    if (!newName || newName === oldName || newName in states) return null;
    return this.change(() => {
      const rebuilt = {};
      for (const [name, state] of Object.entries(states)) {
        rebuilt[name === oldName ? newName : name] = state;
        const transitions = state.transitions || {};
        for (const [outcome, target] of Object.entries(transitions)) {
          if (target === oldName) transitions[outcome] = newName;
        }
      }
      for (const name of Object.keys(states)) delete states[name];
      Object.assign(states, rebuilt);
      this.fixInitial(parent, oldName, newName);
      this.movePins(path, join(parent, newName));
      if (this.containerKind(parent) === "concurrence") {
        const map = this.state(parent).concurrence.outcome_map || {};
        for (const wanted of Object.values(map)) {
          if (wanted && oldName in wanted) {
            wanted[newName] = wanted[oldName];
            delete wanted[oldName];
          }
        }
      }
      return join(parent, newName);
    });
  }

  setParam(path, key, value, typing) {
    this.change(
      () => {
        const holder = path ? this.state(path)[blockOf(this.state(path))] : this.data;
        if (value === undefined) delete holder[key];
        else holder[key] = value;
      },
      { key: typing ? `${path}:${key}` : null, structural: !typing },
    );
  }

  // Several parameters of one state in one undo step (undefined removes one); quiet: a
  // form that shows the change already (the properties are not made again under it).
  setParams(path, values, quiet = false) {
    this.change(() => {
      const holder = path ? this.state(path)[blockOf(this.state(path))] : this.data;
      for (const [key, value] of Object.entries(values)) {
        if (value === undefined) delete holder[key];
        else holder[key] = value;
      }
    }, { structural: !quiet });
  }

  setTransition(path, outcome, target) {
    this.change(() => {
      const state = this.state(path);
      const transitions = { ...(state.transitions || {}) };
      if (target) transitions[outcome] = target;
      else delete transitions[outcome];
      if (Object.keys(transitions).length) state.transitions = transitions;
      else delete state.transitions;
    });
  }

  paste(parent, name, state) {
    return this.pasteMany(parent, [{ name, state }])[0];
  }

  // Copies of states (items: [{name, state}]) in the container at parent, one step: a
  // transition between two of them goes to the other's copy, one to a state or an end
  // of the container stays, any other is dropped. The new paths, in order.
  pasteMany(parent, items) {
    if (childKey(this.containerKind(parent)) === "state") {
      // an iterator or a guard holds one state: the first copy takes the place
      return [this.addState(parent, this.uniqueName(parent, items[0].name), JSON.parse(JSON.stringify(items[0].state)))];
    }
    return this.change(() => {
      const siblings = this.statesOf(parent, true);
      const ends = this.containerOutcomes(parent);
      const renamed = {};
      for (const { name } of items) {
        renamed[name] = this.uniqueName(parent, name);
        siblings[renamed[name]] = null; // taken, so that the next copy gets another name
      }
      return items.map(({ name, state }) => {
        const copy = JSON.parse(JSON.stringify(state));
        const transitions = copy.transitions || {};
        for (const [outcome, target] of Object.entries(transitions)) {
          if (target in renamed) transitions[outcome] = renamed[target];
          else if (!(target in siblings) && !ends.includes(target)) delete transitions[outcome];
        }
        siblings[renamed[name]] = copy;
        return join(parent, renamed[name]);
      });
    });
  }
}
