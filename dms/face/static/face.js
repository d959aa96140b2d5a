// The face page: the robot's face, voice and tablet, for a person in front of it.
// Everything the daemon says arrives on /events; everything the person does is one POST.
"use strict";

const TOKEN = new URLSearchParams(location.search).get("token") || "";
const ICONS = {
  multimedia: "music", news: "newspaper", weather: "cloud-sun", quiz: "circle-help",
  dance: "footprints", bingo: "grid-3x3", jokes: "laugh", sayings: "quote",
  talk: "message-circle", presentation: "hand", cognitive_stimulation: "brain",
  instructions: "info",
};
const NAMES = {
  multimedia: "Music", news: "News", weather: "Weather", quiz: "Quiz", dance: "Dance",
  bingo: "Bingo", jokes: "Jokes", sayings: "Sayings", talk: "Talk", presentation: "Meet Mini",
  cognitive_stimulation: "Brain games", instructions: "How to use me", sleep: "Sleeping",
  wait: "Waiting", notification: "Reminder", menu: "Choosing",
};
const LED_COLORS = {
  white: "#f4f4f4", orange: "#ff9a3c", blue: "#6aa8ff", green: "#6fdc8c", red: "#ff6b6b",
  yellow: "#ffe066", purple: "#c39bff", pink: "#f4a3a8", off: "#e9e2d6",
};
const RATING_WORDS = ["Not at all", "A little", "So-so", "A lot", "Very much"];
const KEY_ROWS = "QWERTYUIOPASDFGHJKLZXCVBNM";
const DEFAULT_WPM = 150;

// What the page knows; `log` keeps when each event arrived (the latency benchmark reads it).
const face = {
  alive: false, presence: { present: false, user_id: null }, people: { people: [], note: "" },
  language: "en", screen: null, screenAt: 0, activity: null, bingo: null, asking: null,
  picking: null, names: {}, log: [],
};
window.face = face;

const $ = (id) => document.getElementById(id);
function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs)) {
    if (name === "class") node.className = value;
    else if (name === "on") node.addEventListener("click", value);
    else if (name.startsWith("data-") || name === "type" || name === "style") node.setAttribute(name, value);
    else node[name] = value;
  }
  for (const child of children) if (child != null) node.append(child);
  return node;
}
function icon(name) {
  return el("span", { class: "icon", style: `--icon: url(/static/vendor/lucide/${name}.svg)` });
}

async function post(path, body) {
  const response = await fetch(`${path}?token=${encodeURIComponent(TOKEN)}`, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body || {}),
  });
  const data = await response.json().catch(() => ({}));
  if (!response.ok) throw new Error(data.error || `${response.status}`);
  return data;
}

// ---------------------------------------------------------------- the face

const faceBox = $("face");
function blink() {
  faceBox.classList.add("blink");
  setTimeout(() => faceBox.classList.remove("blink"), 140);
  setTimeout(blink, 2500 + Math.random() * 4000);
}
function look(gaze) {
  // a positive neck or hip turn looks to the robot's left (the viewer's right); a positive
  // head tilt looks down
  const pan = (gaze.neck || 0) + 0.5 * (gaze.hip || 0);
  const x = Math.max(-1, Math.min(1, pan / 1.0)) * 45;
  const y = Math.max(-1, Math.min(1, (gaze.head || 0) / 0.45)) * 30;
  for (const eye of document.querySelectorAll(".eye")) {
    eye.style.transform = `translate(${x}%, ${y}%)`;
  }
}
function cheeks(led) {
  const color = LED_COLORS[(led && led.color) || ""] || (led && /^#[0-9a-f]{6}$/i.test(led.color) ? led.color : null);
  const box = document.querySelector(".cheeks");
  box.className = "cheeks " + ((led && led.pattern) || "");
  for (const cheek of document.querySelectorAll(".cheek")) {
    cheek.style.background = color || "";
    cheek.style.boxShadow = color ? `0 0 26px 6px ${color}` : "";
  }
}
function expression(name) {
  faceBox.classList.toggle("sleeping", name === "closed_eyes" || face.activity === "sleep");
  faceBox.classList.toggle("happy", name === "happy");
}
function gesture() {
  faceBox.classList.remove("nod");
  void faceBox.offsetWidth;
  faceBox.classList.add("nod");
}

// ---------------------------------------------------------------- the voice
// One utterance at a time. The robot's speech channel sends the next utterance only once
// the last one is over (said, or cut short by an answer), so a new one ends the one the
// page may still be saying. The browser's voice in the person's language says it; where
// there is none, the mouth moves for as long as the robot takes to say it, and the caption
// carries it.

const voice = { queue: [], speaking: null, timer: null };
function voiceFor(lang) {
  if (!("speechSynthesis" in window)) return null;
  const voices = speechSynthesis.getVoices();
  const base = lang.split("-")[0].toLowerCase();
  return voices.find((v) => v.lang.toLowerCase() === lang.toLowerCase())
    || voices.find((v) => v.lang.toLowerCase().split("-")[0] === base) || null;
}
function personLanguage() {
  const here = face.people.people.find((p) => p.id === face.presence.user_id);
  return (here && here.language) || face.language;
}
function say(utterance) {
  voice.queue = [utterance];
  if (voice.speaking && "speechSynthesis" in window) {
    voice.speaking = null; // its end, coming from cancel(), must not start another
    speechSynthesis.cancel();
  }
  nextUtterance();
}
function nextUtterance() {
  const utterance = voice.queue.shift();
  voice.speaking = utterance || null;
  $("mouth").classList.remove("open");
  clearInterval(voice.timer);
  if (!utterance) return;
  $("caption-old").textContent = $("caption").textContent;
  $("caption").textContent = utterance.text;
  voice.timer = setInterval(() => $("mouth").classList.toggle("open"), 160);
  const lang = personLanguage();
  const chosen = voiceFor(lang);
  $("voice-note").hidden = Boolean(chosen);
  $("voice-note").textContent = `Captions only: this browser has no voice for "${lang}".`;
  const wpm = utterance.rate_wpm || DEFAULT_WPM;
  if (chosen) {
    const spoken = new SpeechSynthesisUtterance(utterance.text);
    spoken.voice = chosen;
    spoken.lang = chosen.lang;
    spoken.rate = Math.max(0.5, Math.min(2, wpm / 170));
    if (utterance.volume != null) spoken.volume = Math.max(0, Math.min(1, utterance.volume / 100));
    spoken.onend = spoken.onerror = () => { if (voice.speaking === utterance) nextUtterance(); };
    speechSynthesis.speak(spoken);
  } else {
    const seconds = 0.3 + (60 * utterance.text.split(/\s+/).length) / wpm;
    setTimeout(() => { if (voice.speaking === utterance) nextUtterance(); }, seconds * 1000);
  }
}
function interrupt(target) {
  voice.queue = voice.queue.filter((u) => u.id !== target);
  if (voice.speaking && voice.speaking.id === target) {
    if ("speechSynthesis" in window) speechSynthesis.cancel();
    nextUtterance();
  }
}

// ---------------------------------------------------------------- the tablet

const screenBox = $("screen");
function setScreen(...children) {
  screenBox.replaceChildren(...children);
}
function tap(choice, button) {
  face.log.push({ t: performance.now(), kind: "tap", text: choice });
  for (const b of screenBox.querySelectorAll("button.big")) b.disabled = true;
  if (button) button.classList.add("chosen");
  const shown = face.screen;
  post("/api/screen", { choice }).catch((error) => heard(`Not sent: ${error.message}`));
  setTimeout(() => { // not taken (a stale screen): the buttons come back
    if (face.screen === shown) for (const b of screenBox.querySelectorAll("button.big")) b.disabled = false;
  }, 2500);
}
function choiceButton(label, choice, cls = "") {
  const button = el("button", { class: `big ${cls}`, "data-choice": choice }, label);
  button.addEventListener("click", () => tap(choice, button));
  return button;
}
function kindOf(choices) {
  const lower = choices.map((c) => c.toLowerCase());
  if (lower.length && lower.every((c) => c in ICONS)) return "menu";
  if (lower.join() === "1,2,3,4,5") return "rating";
  if (lower.includes("stop") && lower.includes("continue")) return "confirm";
  if (lower.length === 2 && lower.includes("yes") && lower.includes("no")) return "yesno";
  return choices.length ? "options" : "text";
}
function showScreen(screen) {
  face.screen = screen;
  face.screenAt = performance.now();
  expression(screen.face);
  const choices = screen.choices || [];
  const kind = kindOf(choices);
  const title = screen.text ? el("h2", {}, screen.text) : null;
  if (kind === "menu") {
    setScreen(title, el("div", { class: "choices menu" }, ...choices.map((c) => {
      const button = choiceButton("", c, "activity");
      button.append(icon(ICONS[c.toLowerCase()]), NAMES[c.toLowerCase()] || c);
      return button;
    })), el("div", { class: "row" }, choiceButton("You choose for me", "you choose", "secondary")));
  } else if (kind === "rating") {
    setScreen(title, el("div", { class: "choices five rating" }, ...choices.map((c, i) => {
      const button = choiceButton(c, c);
      button.append(el("small", {}, RATING_WORDS[i]));
      return button;
    })));
  } else if (kind === "confirm") {
    setScreen(title, el("div", { class: "choices two" },
      choiceButton("Yes, stop", "stop", "stop"), choiceButton("No, go on", "continue", "go")));
  } else if (kind === "yesno") {
    setScreen(title, el("div", { class: "choices two" },
      choiceButton("Yes", "yes", "go"), choiceButton("No", "no", "stop")));
  } else if (kind === "options") {
    const long = choices.some((c) => c.length > 18);
    setScreen(title, el("div", { class: `choices ${long ? "list" : "two"}` },
      ...choices.map((c) => choiceButton(c, c))));
  } else if (!showBingo(screen.text || "")) {
    setScreen(screen.text ? el("p", { class: "shown" }, screen.text) : idle());
  }
  if (choices.length) closeKeyboard();
}
function idle() {
  const name = face.activity;
  if (!name) return el("p", { class: "shown" }, "");
  return el("p", { class: "shown" }, ICONS[name] ? icon(ICONS[name]) : "", NAMES[name] || name);
}

// Bingo: "Your card: 3, 17, 22 and 45" deals a card; a number shown alone is a call.
function showBingo(text) {
  const dealt = /^your card:\s*(.+)$/i.exec(text);
  if (dealt) face.bingo = { card: dealt[1].match(/\d+/g) || [], called: new Set(), last: null };
  else if (face.bingo && /^\d{1,3}$/.test(text.trim())) {
    face.bingo.called.add(text.trim());
    face.bingo.last = text.trim();
  } else return false;
  const { card, called, last } = face.bingo;
  setScreen(
    el("h2", {}, "Your bingo card"),
    last ? el("p", { class: "ball" }, "Number ", el("b", {}, last)) : null,
    el("div", { class: "card" }, ...card.map((n) => el("div", { class: called.has(n) ? "called" : "" }, n))),
    el("div", { class: "row" }, choiceButton("BINGO!", "bingo", "go")),
  );
  return true;
}

// ---------------------------------------------------------------- typing an answer

function openKeyboard(prompt, onSend) {
  const form = $("keyboard-template").content.firstElementChild.cloneNode(true);
  const input = form.querySelector(".typed");
  form.querySelector(".prompt").textContent = prompt;
  const keys = form.querySelector(".keys");
  for (const letter of KEY_ROWS) {
    keys.append(el("button", { type: "button", on: () => { input.value += input.value ? letter.toLowerCase() : letter; } }, letter));
  }
  keys.append(el("button", { type: "button", class: "wide", on: () => { input.value += " "; } }, "space"));
  keys.append(el("button", { type: "button", class: "wide", on: () => { input.value = input.value.slice(0, -1); } }, "⌫"));
  form.querySelector(".cancel").addEventListener("click", () => { closeKeyboard(); restore(); });
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    const text = input.value.trim();
    if (text) onSend(text);
  });
  face.typing = true;
  setScreen(form);
  input.focus();
}
function closeKeyboard() { face.typing = false; }
function restore() {
  if (!face.presence.present) return showArrival();
  if (face.screen) showScreen(face.screen); else setScreen(idle());
}
function typeAnswer(prompt) {
  openKeyboard(prompt || "Type your answer", (text) => {
    face.log.push({ t: performance.now(), kind: "typed", text });
    post("/api/say", { text }).then(() => { closeKeyboard(); heard(`You wrote: ${text}`); restore(); })
      .catch((error) => heard(`Not sent: ${error.message}`));
  });
}

// ---------------------------------------------------------------- who is here

function showArrival() {
  face.picking = "who";
  const people = face.people.people;
  setScreen(
    el("h2", {}, "Hello! Who is here?"),
    people.length ? el("div", { class: "choices" }, ...people.map((p) => {
      const button = el("button", { class: "big person", "data-person": p.id, on: () => arrive(p.id, false) }, p.name);
      return button;
    })) : el("p", { class: "note" }, face.people.note
      ? `Mini cannot list the people it knows (${face.people.note}).` : "Nobody is known yet."),
    el("div", { class: "row" }, el("button", { class: "big primary", id: "new-person", on: newPerson },
      icon("user-plus"), people.length ? "Someone new" : "I am here")),
  );
}
function idFromName(name) {
  return name.trim().toLowerCase().normalize("NFKD").replace(/[\u0300-\u036f]/g, "")
    .replace(/[^a-z0-9]+/g, "_").replace(/^_+|_+$/g, "").slice(0, 64);
}
function newPerson() {
  openKeyboard("What is your name?", (name) => {
    const id = idFromName(name);
    if (!id) return;
    face.names[id] = name.trim();
    const known = face.people.people.find((p) => p.id === id);
    if (known) arrive(id, false); else consent(id, name);
  });
}
function consent(id, name) {
  face.picking = "consent";
  setScreen(
    el("h2", {}, `Welcome, ${name}! May Mini remember you?`),
    el("div", { class: "consent" }, el("ul", {},
      el("li", {}, "Mini keeps your name, your answers to its questions, the activities you do and how much you liked them, and when each visit starts and ends."),
      el("li", {}, "It learns from them what you like. It keeps them on this robot's computer, not on the internet; what you say into the microphone is turned into text here and not kept."),
      el("li", {}, "You can ask at any time to erase everything: the staff run ", el("code", {}, `dms users erase ${id}`), "."))),
    el("div", { class: "row" },
      el("button", { class: "big secondary", id: "consent-no", on: () => showArrival() }, icon("x"), "No, thank you"),
      el("button", { class: "big primary", id: "consent-yes", on: () => arrive(id, true) }, icon("check"), "Yes, remember me")),
  );
}
function arrive(id, agreed) {
  face.picking = null;
  post("/api/here", { user_id: id, consent: agreed }).catch((error) => {
    if (/consent/.test(error.message)) consent(id, id); else heard(`Not sent: ${error.message}`);
  });
}
function presence(data) {
  face.presence = data;
  const person = face.people.people.find((p) => p.id === data.user_id);
  const name = person ? person.name : face.names[data.user_id] || data.user_id;
  $("who").textContent = data.present ? `${name} is here` : "Nobody is here";
  $("leave-button").hidden = !data.present;
  if (!data.present) { face.screen = null; face.bingo = null; showArrival(); }
  else if (face.picking !== null || !face.screen) { face.picking = null; setScreen(idle()); }
}

// ---------------------------------------------------------------- push-to-talk
// The microphone is recorded while the button is held (or from one tap to the next) and
// sent as one WAV; the server transcribes it on this machine.

const talk = { stream: null, context: null, node: null, chunks: [], started: 0, pressed: 0, stopping: false };
async function startTalking() {
  if (talk.node || talk.starting) return;
  talk.starting = true;
  try {
    talk.stream = await navigator.mediaDevices.getUserMedia({
      // the recogniser wants the voice as it is: no echo cancelling, denoising or gain riding
      audio: { echoCancellation: false, noiseSuppression: false, autoGainControl: false },
    });
  } catch (error) {
    heard(`The microphone is not available (${error.message}).`);
    return;
  } finally {
    talk.starting = false;
  }
  talk.context = new AudioContext(); // the device's own rate: the server resamples it well
  await talk.context.audioWorklet.addModule("/static/recorder.js");
  const source = talk.context.createMediaStreamSource(talk.stream);
  talk.node = new AudioWorkletNode(talk.context, "recorder");
  talk.chunks = [];
  let count = 0;
  talk.node.port.onmessage = (event) => {
    talk.chunks.push(event.data);
    count += event.data.length;
    face.recorded = count / talk.context.sampleRate;
    if (face.recorded > 15) stopTalking();
  };
  source.connect(talk.node);
  talk.started = performance.now();
  face.recorded = 0;
  $("talk-button").classList.add("recording");
  $("talk-label").textContent = "Listening… tap when done";
}
function wav(chunks, rate) {
  const count = chunks.reduce((n, c) => n + c.length, 0);
  const view = new DataView(new ArrayBuffer(44 + 2 * count));
  const text = (at, s) => [...s].forEach((ch, i) => view.setUint8(at + i, ch.charCodeAt(0)));
  text(0, "RIFF"); view.setUint32(4, 36 + 2 * count, true); text(8, "WAVEfmt ");
  view.setUint32(16, 16, true); view.setUint16(20, 1, true); view.setUint16(22, 1, true);
  view.setUint32(24, rate, true); view.setUint32(28, rate * 2, true);
  view.setUint16(32, 2, true); view.setUint16(34, 16, true); text(36, "data");
  view.setUint32(40, 2 * count, true);
  let at = 44;
  for (const chunk of chunks) for (const s of chunk) {
    view.setInt16(at, Math.max(-1, Math.min(1, s)) * 32767, true);
    at += 2;
  }
  return view.buffer;
}
async function stopTalking() {
  if (!talk.node) return;
  const rate = talk.context.sampleRate;
  talk.node.port.onmessage = null;
  talk.node.disconnect();
  talk.node = null;
  for (const track of talk.stream.getTracks()) track.stop(); // the microphone is off between turns
  talk.stream = null;
  await talk.context.close();
  $("talk-button").classList.remove("recording");
  $("talk-label").textContent = "Talk";
  face.log.push({ t: performance.now(), kind: "speech-end", text: "" });
  heard("Listening to what you said…");
  const response = await fetch(`/api/voice?token=${encodeURIComponent(TOKEN)}`, {
    method: "POST", headers: { "Content-Type": "audio/wav" }, body: wav(talk.chunks, rate),
  });
  const data = await response.json().catch(() => ({}));
  if (!response.ok) heard(`Not understood: ${data.error || response.status}`);
  else heard(data.text ? `I heard: “${data.text}”` : "I did not hear any words. Please try again.");
}
function heard(text) { $("heard").textContent = text; }

// ---------------------------------------------------------------- events from the daemon

function apply(name, data) {
  const text = name === "decision" ? `${data.action} ${data.activity}` : data.text || "";
  face.log.push({ t: performance.now(), kind: name, text });
  switch (name) {
    case "say": say(data); break;
    case "interrupt": interrupt(data.target); break;
    case "screen":
      if (face.presence.present && (!face.typing || data.choices.length)) showScreen(data);
      else face.screen = data;
      break;
    case "led": cheeks(data); break;
    case "gaze": look(data); break;
    case "motion": gesture(); break;
    case "decision": onDecision(data); break;
    case "state": onState(data); break;
    case "alive": face.alive = data.alive; $("link-dot").classList.toggle("alive", data.alive); $("offline").hidden = data.alive; break;
    case "presence": presence(data); break;
    case "people":
      face.people = data;
      if (!face.presence.present && face.picking === "who") showArrival();
      break;
    case "heard": break;
  }
}
function onDecision(decision) {
  face.decision = decision;
  if (["start", "cancel", "complete", "fail"].includes(decision.action) && face.presence.present) {
    // what was shown or asked before belonged to what has ended (unless it came just now)
    if (performance.now() - face.screenAt > 500) face.screen = null;
    closeKeyboard();
    restore();
  }
  if (decision.action === "ask") {
    setTimeout(() => { // a question without choices on the screen: the keyboard
      const shown = face.screen && face.screen.text === decision.detail && face.screen.choices.length;
      if (!shown && face.presence.present && face.decision === decision) typeAnswer(decision.detail);
    }, 600);
  }
}
function onState(state) {
  const changed = state.activity !== face.activity;
  face.activity = state.activity;
  if (state.activity !== "bingo") face.bingo = null;
  expression(face.screen && face.screen.face);
  if (changed && face.presence.present && !face.screen && !face.typing) setScreen(idle());
}
function snapshot(data) {
  face.language = data.language;
  face.people = data.people;
  face.activity = data.state.activity;
  $("talk-button").hidden = Boolean(data.voice_missing);
  if (data.voice_missing) $("talk-button").title = data.voice_missing;
  apply("alive", { alive: data.alive });
  cheeks(data.led);
  look(data.gaze || {});
  const last = data.said[data.said.length - 1];
  if (last) $("caption").textContent = last.text;
  face.screen = data.screen;
  presence(data.presence);
  if (data.presence.present && data.screen) showScreen(data.screen);
  document.body.dataset.ready = "1";
}

function connect() {
  const events = new EventSource(`/events?token=${encodeURIComponent(TOKEN)}`);
  events.addEventListener("snapshot", (e) => snapshot(JSON.parse(e.data)));
  for (const name of ["say", "interrupt", "screen", "led", "gaze", "motion", "decision", "state", "alive", "presence", "people", "heard"]) {
    events.addEventListener(name, (e) => apply(name, JSON.parse(e.data)));
  }
  events.addEventListener("full", () => { events.close(); heard("Too many pages are open on this robot."); });
}

// ---------------------------------------------------------------- wiring

for (const button of document.querySelectorAll(".touch")) {
  button.addEventListener("click", () => {
    face.log.push({ t: performance.now(), kind: "touch", text: button.dataset.part });
    button.classList.add("pressed");
    setTimeout(() => button.classList.remove("pressed"), 400);
    post("/api/touch", { part: button.dataset.part, kind: button.dataset.kind })
      .catch((error) => heard(`Not sent: ${error.message}`));
  });
}
$("leave-button").addEventListener("click", () => post("/api/leave").catch((error) => heard(`Not sent: ${error.message}`)));
$("type-button").addEventListener("click", () => typeAnswer(face.decision && face.decision.action === "ask" ? face.decision.detail : ""));
const talkButton = $("talk-button");
talkButton.addEventListener("pointerdown", () => {
  if (talk.node) { talk.stopping = true; return; }
  talk.pressed = performance.now();
  startTalking();
});
talkButton.addEventListener("pointerup", () => { // held: letting go ends it; a short tap listens on
  if (talk.stopping) { talk.stopping = false; stopTalking(); }
  else if (talk.node && performance.now() - talk.pressed > 700) stopTalking();
});
talkButton.addEventListener("keydown", (event) => {
  if (event.key === " " || event.key === "Enter") {
    event.preventDefault();
    if (talk.node) stopTalking(); else startTalking();
  }
});
if ("speechSynthesis" in window) speechSynthesis.getVoices(); // loads the voice list early
setTimeout(blink, 2000);
connect();
