// "Take the robot's pose": a Reachy Mini driven by `dms reachy` posed by hand. On, the
// bridge turns the head's gravity compensation on (the ask is a lease, renewed here while
// the box is ticked) and Record takes the joints the robot reports; off, the robot holds
// where the hand left it. Offered only when the daemon's robot answers as a Reachy Mini.

import { get, post } from "./api.js";

const box = document.getElementById("by-hand");
const label = box.closest("label");
let renewal = null;

function say(text, kind) {
  const line = document.getElementById("status");
  if (!line) return;
  line.textContent = text;
  line.className = kind || "";
}

function stopRenewing() {
  clearInterval(renewal);
  renewal = null;
}

// One ask at a time, in order: a renewal still on its way never lands after an off.
let asking = Promise.resolve();
function ask(on) {
  asking = asking.then(() => send(on));
  return asking;
}

async function send(on) {
  if (on && renewal === null && !box.checked) return null; // unticked while it waited
  const reply = await post("/api/robot/by-hand", { on });
  if (!reply.ok) {
    stopRenewing();
    box.checked = false;
    say(reply.data.error, "bad");
    return null;
  }
  box.checked = reply.data.by_hand;
  return reply.data;
}

box.addEventListener("change", async () => {
  if (!box.checked) {
    stopRenewing();
    if (await ask(false)) say("the robot holds its pose again", "good");
    return;
  }
  const tryOn = document.getElementById("try-on");
  tryOn.value = "daemon"; // Record reads the daemon's robot while it is posed by hand
  tryOn.dispatchEvent(new Event("change"));
  const state = await ask(true);
  if (!state) return;
  say("move the robot's head by hand, then Record", "good");
  keepRenewing(state.renew_s);
});

function keepRenewing(seconds) {
  stopRenewing();
  renewal = setInterval(() => ask(true), seconds * 1000);
}

const state = await get("/api/robot/by-hand");
box.disabled = !state.ok;
label.title = state.ok
  ? "Turn the Reachy Mini's gravity compensation on: move its head by hand, then Record"
  : state.data.error;
if (state.ok && state.data.by_hand) {
  // posed by hand from before this page (a reload): this page keeps it up, or ends it
  box.checked = true;
  keepRenewing(state.data.renew_s);
}
