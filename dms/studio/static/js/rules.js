// The rules pane: a DMSL file of the folder (or --rules) in a text area, checked by the
// server as `dms rules check` checks it after each change; each finding is marked at its
// line in the gutter and listed below (click one to go to its line and column).

import { get, post } from "./api.js";

const CHECK_MS = 300;

function h(tag, text, cls) {
  const node = document.createElement(tag);
  if (text !== undefined) node.textContent = text;
  if (cls) node.className = cls;
  return node;
}

export class RulesPane {
  constructor() {
    this.text = document.getElementById("rules-text");
    this.gutter = document.getElementById("rules-gutter");
    this.findings = document.getElementById("rules-findings");
    this.select = document.getElementById("rules-select");
    this.file = null; // {name, hash}
    this.timer = null;
    this.seq = 0;
    this.loaded = false;
    document.getElementById("rules-button").addEventListener("click", () => this.toggle());
    document.getElementById("rules-save").addEventListener("click", () => this.save());
    this.select.addEventListener("change", () => this.open(this.select.value));
    this.text.addEventListener("input", () => {
      this.drawGutter([]);
      clearTimeout(this.timer);
      this.timer = setTimeout(() => this.check(), CHECK_MS);
    });
    this.text.addEventListener("scroll", () => { this.gutter.scrollTop = this.text.scrollTop; });
  }

  status(text, kind = "") {
    const box = document.getElementById("rules-status");
    box.textContent = text;
    box.className = kind;
  }

  async toggle() {
    const open = document.body.classList.toggle("rules-open");
    if (open && !this.loaded) await this.load();
  }

  async load() {
    this.loaded = true;
    const reply = await get("/api/rules");
    if (!reply.ok) return this.status(reply.data.error, "bad");
    this.select.replaceChildren(...reply.data.names.map((name) => new Option(name, name)));
    if (!reply.data.names.length) {
      this.status("no rules file: start the studio with --rules FILE, or put a .dmsl file in the folder", "bad");
      return;
    }
    await this.open(reply.data.names[0]);
  }

  async open(name) {
    const reply = await get(`/api/rules/${encodeURIComponent(name)}`);
    if (!reply.ok) return this.status(reply.data.error, "bad");
    this.file = { name, hash: reply.data.hash };
    this.text.value = reply.data.text;
    this.text.title = reply.data.file;
    await this.check();
  }

  async check() {
    if (!this.file) return;
    const seq = (this.seq += 1);
    const reply = await post("/api/rules/check", { name: this.file.name, text: this.text.value });
    if (seq !== this.seq) return;
    if (!reply.ok) return this.status(reply.data.error, "bad");
    this.show(reply.data);
  }

  show(report) {
    this.drawGutter(report.findings);
    this.findings.replaceChildren();
    for (const finding of report.findings) {
      const item = h("li", `line ${finding.line}, column ${finding.column}: ${finding.message}`, finding.severity);
      item.dataset.line = String(finding.line);
      item.dataset.text = finding.text;
      item.addEventListener("click", () => this.goTo(finding.line, finding.column));
      this.findings.appendChild(item);
    }
    for (const other of report.elsewhere) this.findings.appendChild(h("li", `another file: ${other}`, "error"));
    const errors = report.findings.filter((f) => f.severity === "error").length + report.elsewhere.length;
    if (!report.findings.length && !report.elsewhere.length) this.findings.appendChild(h("li", "none: it verifies", "ok"));
    document.body.dataset.rulesChecked = String(this.seq);
    this.status(errors ? `${errors} problem(s)` : "verifies", errors ? "bad" : "good");
  }

  drawGutter(findings) {
    const lines = this.text.value.split("\n").length;
    const marks = {};
    for (const finding of findings) {
      if (marks[finding.line] !== "error") marks[finding.line] = finding.severity;
    }
    this.gutter.replaceChildren();
    for (let line = 1; line <= lines; line += 1) {
      const row = h("div", String(line), marks[line] || "");
      row.dataset.line = String(line);
      if (marks[line]) row.title = findings.filter((f) => f.line === line).map((f) => f.message).join("\n");
      this.gutter.appendChild(row);
    }
    this.gutter.scrollTop = this.text.scrollTop;
  }

  goTo(line, column) {
    const before = this.text.value.split("\n").slice(0, line - 1).join("\n");
    const at = (line > 1 ? before.length + 1 : 0) + Math.max(column - 1, 0);
    this.text.focus();
    this.text.setSelectionRange(at, at);
  }

  async save() {
    if (!this.file) return;
    const reply = await post("/api/rules/save", { name: this.file.name, text: this.text.value, hash: this.file.hash });
    if (!reply.ok) return this.status(reply.data.error, "bad");
    this.file.hash = reply.data.hash;
    this.status(`saved ${this.file.name}`, "good");
  }
}
