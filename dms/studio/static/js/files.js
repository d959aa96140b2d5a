// Files without lost work: Open and New ask before they discard edits (and stay
// undoable), the tab warns before it closes on edits, every edit is kept as a draft in
// the browser's storage (offered back when the file is opened again, or the page is
// reopened), and a file changed on disk offers Reload, Compare or Overwrite.

import { get, post } from "./api.js";
import { ask, diffView } from "./dialog.js";
import { canonical } from "./doc.js";

const DRAFT_MS = 600; // a draft is written this long after the last edit
const DRAFTS_KEPT = 20;
const PREFIX = "dms-studio-draft:";
const EMPTY = () => ({ name: "new_behavior", outcomes: ["done"], states: {} });

export class Files {
  constructor(app, hooks) {
    this.app = app; // {doc, folder}
    this.hooks = hooks; // {status(text, kind), refreshList(name)}
    this.timer = null;
    this.warned = null; // the hash on disk already offered for reload
    window.addEventListener("beforeunload", (event) => {
      this.keepDraft();
      if (this.app.doc.modified) {
        event.preventDefault();
        event.returnValue = "";
      }
    });
    window.addEventListener("focus", () => this.lookAtDisk());
  }

  get doc() {
    return this.app.doc;
  }

  // ------------------------------------------------------------ asking first

  // Whether what is in the page may be replaced: not modified, saved now, or discarded.
  async mayDiscard(what) {
    if (!this.doc.modified) return true;
    const name = this.doc.data.name || "this behavior";
    const choice = await ask(`${name} has changes not saved`,
      `${what} replaces them. Save them first? (Discarded changes come back with Undo.)`,
      [["save", "Save"], ["discard", "Discard changes"], ["cancel", "Cancel"]]);
    if (choice === "save") return (await this.save()) === "saved";
    if (choice === "discard") this.dropDraft(); // the designer let them go (Undo still has them)
    return choice === "discard";
  }

  async open(name) {
    const select = document.getElementById("open-select");
    if (!name || (name === this.doc.file.name && !this.doc.modified)) return false;
    if (!(await this.mayDiscard(`Opening ${name}`))) {
      select.value = this.doc.file.name || "";
      this.hooks.status("not opened: the changes are kept");
      return false;
    }
    const opened = await this.load(name);
    if (opened) await this.offerDraft(name);
    return opened;
  }

  async load(name) {
    const reply = await get(`/api/behaviors/${encodeURIComponent(name)}`);
    if (!reply.ok) {
      this.hooks.status(reply.data.error, "bad");
      return false;
    }
    const layout = (reply.data.layout && reply.data.layout.positions) || {};
    this.doc.load(reply.data.doc, { name: reply.data.name, hash: reply.data.hash }, layout);
    this.warned = null;
    this.hooks.status(reply.data.layout_note ? `opened ${name}; ${reply.data.layout_note}` : `opened ${name}`);
    return true;
  }

  async newDoc() {
    if (!(await this.mayDiscard("A new behavior"))) return false;
    this.doc.load(EMPTY(), { name: null, hash: null }, {});
    return true;
  }

  // ------------------------------------------------------------ saving

  // Save: "saved", "draft", or null (refused; a file changed on disk is offered).
  async save() {
    const doc = this.doc;
    const renamed = doc.file.name && doc.file.name !== doc.data.name;
    const reply = await post("/api/save", { doc: doc.data, hash: renamed ? null : doc.file.hash,
      layout: { positions: doc.layout } });
    if (reply.status === 409 && !renamed && doc.file.name && reply.data.error.includes("changed on disk")) {
      return this.conflict();
    }
    if (!reply.ok) {
      this.hooks.status(`not saved: ${reply.data.error}`, "bad");
      return null;
    }
    if (reply.data.kind === "saved") {
      this.dropDraft(); // under the name it had: "(new)", or the file before a rename
      doc.markSaved({ name: doc.data.name, hash: reply.data.hash });
      this.dropDraft();
      this.hooks.status(`saved ${reply.data.file}`, "good");
      await this.hooks.refreshList(doc.data.name);
    } else {
      this.hooks.status(`it does not load yet: saved as a draft, ${reply.data.file}; the file is unchanged`, "bad");
    }
    document.body.dataset.saved = reply.data.kind;
    return reply.data.kind;
  }

  // The file changed on disk since it was opened: reload it, compare, or overwrite it.
  async conflict(onDisk = null) {
    const name = this.doc.file.name;
    const buttons = [["compare", "Compare"], ["reload", "Reload from disk"], ["overwrite", "Overwrite it"],
      ["cancel", "Cancel"]];
    let choice = await ask(`${name}.yaml changed on disk`, onDisk
      ? "Another program changed the file since you opened it."
      : "Another program changed the file since you opened it: saving would lose its changes.", buttons);
    let compared = null;
    if (choice === "compare") {
      compared = await post("/api/compare", { doc: this.doc.data });
      if (!compared.ok) return this.refused(compared);
      choice = await ask(`${name}.yaml: on disk (−) and in the studio (+)`,
        "What saving would change in the file as it is now.", buttons.slice(1), diffView(compared.data.disk, compared.data.mine));
    }
    if (choice === "reload") {
      await this.load(name); // what was in the page is one Undo away
      this.hooks.status(`reloaded ${name} from disk (Undo brings back what was in the page)`);
      return null;
    }
    if (choice === "overwrite") {
      const now = compared || (await post("/api/compare", { doc: this.doc.data }));
      if (!now.ok) return this.refused(now);
      this.doc.file = { ...this.doc.file, hash: now.data.hash };
      return this.save();
    }
    this.hooks.status("not saved: the file changed on disk", "bad");
    return null;
  }

  refused(reply) {
    this.hooks.status(reply.data.error, "bad");
    return null;
  }

  // When the page comes back to the front: has the file changed on disk meanwhile?
  async lookAtDisk() {
    const { name, hash } = this.doc.file;
    if (!name || !hash) return;
    const reply = await get(`/api/behaviors/${encodeURIComponent(name)}`);
    if (!reply.ok || reply.data.hash === hash || reply.data.hash === this.warned) return;
    if (name !== this.doc.file.name) return; // another file was opened meanwhile
    this.warned = reply.data.hash;
    if (!this.doc.modified) {
      const choice = await ask(`${name}.yaml changed on disk`, "Another program changed the file. Reload it?",
        [["reload", "Reload from disk"], ["keep", "Keep the page as it is"]]);
      if (choice === "reload") await this.load(name);
    } else {
      await this.conflict(reply.data.hash);
    }
  }

  // ------------------------------------------------------------ drafts in the browser

  key(name) {
    return `${PREFIX}${this.app.folder}:${name || "(new)"}`;
  }

  // After each edit: keep the page as a draft soon (dropped once it matches the file).
  edited() {
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.keepDraft(), DRAFT_MS);
  }

  keepDraft() {
    clearTimeout(this.timer);
    const doc = this.doc;
    if (!doc.modified) {
      this.dropDraft();
      return;
    }
    const draft = { at: new Date().toISOString(), data: doc.data, layout: doc.layout, file: doc.file };
    try {
      localStorage.setItem(this.key(doc.file.name), JSON.stringify(draft));
      this.prune();
      document.body.dataset.drafted = draft.at;
    } catch (error) {
      this.hooks.status(`the draft could not be kept in the browser: ${error.message}`, "bad");
    }
  }

  dropDraft() {
    try {
      localStorage.removeItem(this.key(this.doc.file.name));
    } catch (_error) {
      // storage refused: nothing was kept there
    }
  }

  // At most DRAFTS_KEPT drafts: the oldest go first.
  prune() {
    const drafts = [];
    for (let index = 0; index < localStorage.length; index += 1) {
      const key = localStorage.key(index);
      if (!key.startsWith(PREFIX)) continue;
      try {
        drafts.push([JSON.parse(localStorage.getItem(key)).at || "", key]);
      } catch (_error) {
        drafts.push(["", key]);
      }
    }
    drafts.sort();
    for (const [, key] of drafts.slice(0, Math.max(0, drafts.length - DRAFTS_KEPT))) localStorage.removeItem(key);
  }

  // A draft of `name` kept in this browser that differs from the file: offer it back.
  async offerDraft(name) {
    let draft = null;
    try {
      draft = JSON.parse(localStorage.getItem(this.key(name)) || "null");
    } catch (_error) {
      draft = null;
    }
    if (!draft || !draft.data) return;
    if (JSON.stringify(canonical([draft.data, draft.layout || {}])) === this.doc.contentKey()) {
      this.dropDraft();
      return;
    }
    const when = new Date(draft.at).toLocaleString();
    const what = name ? `${name}.yaml` : "a new behavior";
    const choice = await ask(`Edits of ${what} not saved`,
      `This browser kept edits of ${what} from ${when} that were never saved. Restore them?`,
      [["restore", "Restore them"], ["discard", "Discard them"]]);
    if (choice !== "restore") {
      this.dropDraft();
      return;
    }
    const file = draft.file && draft.file.name === this.doc.file.name ? draft.file : this.doc.file;
    this.doc.change(() => {
      this.doc.data = draft.data;
      this.doc.layout = draft.layout || {};
      this.doc.file = file; // the file as it was then: a save finds out if it changed since
    });
    this.hooks.status(`restored the edits of ${what} from ${when}`, "good");
  }
}
