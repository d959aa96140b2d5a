// Trying the behavior on the simulated Mini: run it all (a state every STEP_MS, pausing
// at a question for the user's answer), step state by state, or run the selected state
// alone. The active state is lit on the canvas; the userdata, what the robot says and
// shows and its joints are shown beside it. On the daemon's robot (the studio started
// with --connect) it runs in real time: the page asks for its states every POLL_MS; when
// stepping, the daemon holds still at each new state until the next Step.

import { get, post } from "./api.js";
import { litPaths } from "./canvas.js";

const STEP_MS = 600;
const POLL_MS = 250;
const LIT_MIN_MS = 150; // states that came in one poll are each lit this long, in turn
const VALUE_CHARS = 160;

function h(tag, text, cls) {
  const node = document.createElement(tag);
  if (text !== undefined) node.textContent = text;
  if (cls) node.className = cls;
  return node;
}

export class Trial {
  constructor(handlers) {
    this.handlers = handlers; // {doc(), selected(), lit(paths), status(text, kind), record(joints), moved(joints)}
    this.running = false; // the run goes on by itself
    this.active = false; // a trial was started and has not finished
    this.timer = null;
    this.seen = 0; // the daemon try's states shown so far
    this.polls = 0; // which daemon try the polling loop belongs to
    this.paused = false; // the daemon's try holds still at a state, for Step
    const on = (id, fn) => document.getElementById(id).addEventListener("click", fn);
    on("run-button", () => this.start(null, true));
    on("step-button", () => (this.active ? this.step(false) : this.start(null, false)));
    on("run-state-button", () => this.runState());
    on("stop-button", () => this.stop());
    on("answer-button", () => this.answer());
    on("skip-button", () => this.step(this.running));
    on("record-button", () => this.record());
    const marker = document.getElementById("marker-seen");
    marker.addEventListener("change", async () => {
      const reply = await post("/api/try/marker", { seen: marker.checked });
      if (!reply.ok) {
        marker.checked = !marker.checked;
        this.handlers.status(reply.data.error, "bad");
        return;
      }
      this.log(reply.data.seen ? "the marker is seen again" : "the marker is hidden");
    });
    document.getElementById("answer-input").addEventListener("keydown", (event) => {
      if (event.key === "Enter") this.answer();
    });
  }

  onDaemon() {
    return document.getElementById("try-on").value === "daemon";
  }

  runState() {
    const path = this.handlers.selected();
    if (!path) {
      this.handlers.status("select a state to run it alone", "bad");
      return;
    }
    this.start(path, true);
  }

  async start(state, running) {
    clearTimeout(this.timer);
    if (this.onDaemon()) return this.startOnDaemon(state, running);
    this.running = running;
    const body = { doc: this.handlers.doc().data };
    if (state) body.state = state;
    const reply = await post("/api/try/start", body);
    if (!reply.ok) {
      this.running = false;
      this.handlers.status(reply.data.error, "bad");
      return;
    }
    this.active = true;
    document.getElementById("marker-seen").checked = true; // each trial starts with it seen
    this.prefix = state && state.includes("/") ? state.slice(0, state.lastIndexOf("/")) : "";
    this.show(reply.data);
  }

  async startOnDaemon(state, running) {
    const polls = ++this.polls;
    const where = document.getElementById("trial-state");
    where.dataset.path = "";
    where.textContent = "starting on the daemon's robot…";
    const body = { doc: this.handlers.doc().data, step: !running };
    if (state) body.state = state;
    const reply = await post("/api/daemon/try", body);
    if (!reply.ok) {
      this.handlers.status(reply.data.error, "bad");
      document.getElementById("trial-state").textContent = "refused";
      return;
    }
    this.active = true;
    this.paused = false;
    this.prefix = state && state.includes("/") ? state.slice(0, state.lastIndexOf("/")) : "";
    this.seen = 0;
    const what = state ? `the state ${state} of ${reply.data.trying}` : reply.data.trying;
    this.log(`trying ${what} on the daemon's robot${running ? "" : ", state by state"}`);
    this.poll(polls);
  }

  async poll(polls) {
    if (polls !== this.polls) return; // a later try polls for itself
    const reply = await get(`/api/daemon/try?since=${this.seen}`);
    if (polls !== this.polls) return;
    if (!reply.ok) {
      this.handlers.status(reply.data.error, "bad");
      return;
    }
    for (const [index, state] of reply.data.states.entries()) {
      if (index) await new Promise((resolve) => setTimeout(resolve, LIT_MIN_MS));
      this.seen += 1;
      this.showDaemon(state);
    }
    if (this.active) this.timer = setTimeout(() => this.poll(polls), POLL_MS);
  }

  showDaemon(state) {
    const path = state.path && this.prefix ? `${this.prefix}/${state.path}` : state.path;
    this.handlers.lit(state.finished ? new Set() : litPaths(path));
    const where = document.getElementById("trial-state");
    where.dataset.path = path || "";
    const why = state.detail ? ` (${state.detail})` : "";
    this.paused = Boolean(state.paused);
    where.textContent = state.finished
      ? `ended: ${state.outcome || state.status}${state.error ? ` (${state.error})` : why}`
      : `on the robot  ${path || "-"}${this.paused ? "  (held: Step goes on)" : ""}`;
    this.showUserdata(state.userdata, state.changed);
    if (state.finished) this.active = false;
  }

  async step(running) {
    if (this.onDaemon()) {
      // the polling loop goes on by itself and shows the next state when it comes
      const reply = await post("/api/daemon/step");
      if (!reply.ok) this.handlers.status(reply.data.error, "bad");
      return;
    }
    clearTimeout(this.timer);
    this.running = running;
    const reply = await post("/api/try/step");
    if (!reply.ok) {
      this.handlers.status(reply.data.error, "bad");
      return;
    }
    this.show(reply.data);
  }

  async answer() {
    const input = document.getElementById("answer-input");
    const text = input.value.trim();
    if (!text || !this.active) return;
    const reply = await post(this.onDaemon() ? "/api/daemon/answer" : "/api/try/answer", { text });
    input.value = "";
    if (!reply.ok) {
      this.handlers.status(reply.data.error, "bad");
      return;
    }
    this.log(`answer "${text}" ${reply.data.taken ? "taken" : "not taken"}`);
    if (!this.onDaemon() || this.paused) this.step(this.running);
  }

  async stop() {
    clearTimeout(this.timer);
    this.polls += 1;
    this.running = false;
    this.active = false;
    await post(this.onDaemon() ? "/api/daemon/stop" : "/api/try/stop");
    this.handlers.lit(new Set());
    document.getElementById("trial-state").textContent = "stopped";
  }

  show(step) {
    const path = step.path && this.prefix ? `${this.prefix}/${step.path}` : step.path;
    this.handlers.lit(step.finished ? new Set() : litPaths(path));
    const where = document.getElementById("trial-state");
    where.dataset.path = path || "";
    where.textContent = step.finished
      ? `ended: ${step.outcome || step.status}${step.error ? ` (${step.error})` : ""}`
      : `${step.t.toFixed(1)} s  ${path || "-"}${step.awaiting_answer ? "  (waiting for an answer)" : ""}`;
    this.showUserdata(step.userdata, step.changed);
    this.showRobot(step.robot);
    for (const command of step.commands) {
      this.log(`${command.channel}.${command.action} ${JSON.stringify(command.args)}`);
    }
    if (step.finished) {
      this.active = false;
      this.running = false;
      return;
    }
    if (this.running && !step.awaiting_answer) {
      this.timer = setTimeout(() => this.step(true), STEP_MS);
    } else if (step.awaiting_answer) {
      document.getElementById("answer-input").focus();
    }
  }

  showUserdata(userdata, changed) {
    const table = document.getElementById("userdata");
    table.replaceChildren();
    for (const [key, value] of Object.entries(userdata || {})) {
      const row = h("tr", undefined, key in (changed || {}) ? "changed" : "");
      row.appendChild(h("td", key));
      const text = JSON.stringify(value);
      row.appendChild(h("td", text.length > VALUE_CHARS ? `${text.slice(0, VALUE_CHARS)}… (${text.length} characters)` : text));
      table.appendChild(row);
    }
  }

  showRobot(robot) {
    const box = document.getElementById("robot");
    box.replaceChildren();
    const said = robot.said.length ? robot.said[robot.said.length - 1] : "";
    box.appendChild(h("div", said ? `says: “${said}”` : "says nothing yet", "said"));
    const screen = robot.screen || {};
    const shown = [screen.text, ...(screen.choices || [])].filter(Boolean).join(" | ");
    box.appendChild(h("div", `screen: ${shown || "-"}`));
    const joints = Object.entries(robot.joints).map(([k, v]) => `${k} ${v.toFixed(2)}`).join("  ");
    box.appendChild(h("div", joints, "joints"));
    box.dataset.joints = JSON.stringify(robot.joints);
    if (this.handlers.moved) this.handlers.moved(robot.joints);
  }

  log(text) {
    const list = document.getElementById("log");
    list.appendChild(h("li", text));
    while (list.children.length > 200) list.firstChild.remove();
    list.lastChild.scrollIntoView({ block: "nearest" });
  }

  async record() {
    const reply = await get(`/api/robot?on=${this.onDaemon() ? "daemon" : "sim"}`);
    if (!reply.ok) {
      this.handlers.status(reply.data.error, "bad");
      return;
    }
    this.handlers.record(reply.data.joints);
  }
}
