// A question to the designer in a modal dialog, answered by a button: the studio asks
// before it discards anything (an Open, a New, a file changed on disk). Escape is the
// last button (Cancel, by convention).

let shown = null; // the dialog element, made once

function dialog() {
  if (!shown) {
    shown = document.createElement("dialog");
    shown.id = "ask";
    document.body.appendChild(shown);
  }
  return shown;
}

// Ask: title, text, buttons [[choice, label], ...] (the first is the main one), and an
// element shown between the text and the buttons (a comparison). Resolves to a choice.
export function ask(title, text, buttons, extra = null) {
  const box = dialog();
  if (box.open) box.close("superseded");
  box.replaceChildren();
  const heading = document.createElement("h2");
  heading.textContent = title;
  const body = document.createElement("p");
  body.textContent = text;
  box.append(heading, body);
  if (extra) box.appendChild(extra);
  const row = document.createElement("div");
  row.className = "buttons";
  box.appendChild(row);
  return new Promise((resolve) => {
    const cancel = buttons[buttons.length - 1][0];
    buttons.forEach(([choice, label], index) => {
      const button = document.createElement("button");
      button.dataset.choice = choice;
      button.textContent = label;
      if (index === 0) button.className = "primary";
      button.addEventListener("click", () => box.close(choice));
      row.appendChild(button);
    });
    box.addEventListener("close", () => {
      document.body.dataset.asking = "";
      resolve(box.returnValue && box.returnValue !== "superseded" ? box.returnValue : cancel);
    }, { once: true });
    box.returnValue = "";
    box.showModal();
    document.body.dataset.asking = box.dataset.kind = title;
    row.firstChild.focus();
  });
}

// The lines of `before` and `after` compared (a longest common subsequence; beyond
// MAX_LINES the two are shown whole): an element listing removed, added and kept lines,
// long runs of kept lines folded.
const MAX_LINES = 3000;
const CONTEXT = 3;

export function diffView(before, after) {
  const a = before.split("\n");
  const b = after.split("\n");
  const box = document.createElement("div");
  box.className = "diff";
  const line = (kind, text) => {
    const row = document.createElement("div");
    row.className = kind;
    row.textContent = `${kind === "del" ? "-" : kind === "add" ? "+" : " "} ${text}`;
    box.appendChild(row);
  };
  if (a.length * b.length > MAX_LINES * MAX_LINES / 4) {
    for (const text of a) line("del", text);
    for (const text of b) line("add", text);
    return box;
  }
  const n = a.length;
  const m = b.length;
  const common = Array.from({ length: n + 1 }, () => new Uint32Array(m + 1));
  for (let i = n - 1; i >= 0; i -= 1) {
    for (let j = m - 1; j >= 0; j -= 1) {
      common[i][j] = a[i] === b[j] ? common[i + 1][j + 1] + 1 : Math.max(common[i + 1][j], common[i][j + 1]);
    }
  }
  const rows = [];
  let i = 0;
  let j = 0;
  while (i < n || j < m) {
    if (i < n && j < m && a[i] === b[j]) rows.push(["same", a[i++], j++]);
    else if (i < n && (j === m || common[i + 1][j] >= common[i][j + 1])) rows.push(["del", a[i++]]);
    else rows.push(["add", b[j++]]);
  }
  const near = rows.map((_row, index) => rows.slice(Math.max(0, index - CONTEXT), index + CONTEXT + 1)
    .some((other) => other[0] !== "same"));
  let folded = 0;
  rows.forEach(([kind, text], index) => {
    if (kind === "same" && !near[index]) {
      folded += 1;
      return;
    }
    if (folded) line("gap", `… ${folded} lines the same`);
    folded = 0;
    line(kind, text);
  });
  if (folded) line("gap", `… ${folded} lines the same`);
  if (!rows.some(([kind]) => kind !== "same")) line("gap", "(no difference)");
  return box;
}
