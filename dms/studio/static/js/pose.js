// Posing the simulated Mini by hand, as ROS Commander's users pose their robot before
// they record: a figure to drag (figure.js) and a slider per joint, within the joint's
// limits (from the server). Each move sets the simulated Mini's joints; Record then
// takes them as a keyframe. During a trial the figure and the sliders follow the robot.

import { get, post } from "./api.js";
import { Figure } from "./figure.js";

const SEND_MS = 80; // a slider dragged sends at most this often
const JOINT_ORDER = ["hip", "neck", "head", "left_arm", "right_arm"];

export class Posing {
  constructor(handlers) {
    this.handlers = handlers; // {status(text, kind)}
    this.limits = {};
    this.sliders = {};
    this.timer = null;
    this.wanted = {};
  }

  async start() {
    const reply = await get("/api/body");
    if (!reply.ok) return;
    this.limits = reply.data.joints;
    const box = document.getElementById("posing");
    box.replaceChildren();
    this.figure = new Figure(box, this.limits, (joints) => {
      for (const [name, angle] of Object.entries(joints)) this.set(name, angle);
    });
    for (const name of JOINT_ORDER.filter((joint) => joint in this.limits)) {
      const { low, high, neutral } = this.limits[name];
      const row = document.createElement("label");
      row.className = "joint";
      const title = document.createElement("span");
      title.textContent = name;
      const slider = document.createElement("input");
      Object.assign(slider, { type: "range", min: low, max: high, step: 0.01, value: neutral, id: `joint-${name}` });
      slider.setAttribute("aria-label", `${name} (radians, ${low} to ${high})`);
      const value = document.createElement("output");
      value.textContent = neutral.toFixed(2);
      slider.addEventListener("input", () => {
        this.set(name, Number(slider.value));
        this.figure.show({ [name]: Number(slider.value) });
      });
      row.append(title, slider, value);
      box.appendChild(row);
      this.sliders[name] = { slider, value };
    }
    const reset = document.createElement("button");
    reset.textContent = "Neutral";
    reset.title = "Every joint to its neutral angle";
    reset.addEventListener("click", () => this.pose(Object.fromEntries(
      Object.entries(this.limits).map(([name, joint]) => [name, joint.neutral]))));
    box.appendChild(reset);
    const now = await get("/api/robot?on=sim");
    if (now.ok) this.show(now.data.joints);
  }

  // One joint moved by hand: shown, and sent with the others moved meanwhile.
  set(name, angle) {
    const made = this.sliders[name];
    if (made) {
      made.slider.value = angle;
      made.value.textContent = Number(angle).toFixed(2);
    }
    this.wanted[name] = angle;
    if (!this.timer) this.timer = setTimeout(() => this.send(), SEND_MS);
  }

  async send() {
    this.timer = null;
    const joints = this.wanted;
    this.wanted = {};
    if (Object.keys(joints).length) await this.pose(joints);
  }

  // Pose the simulated Mini: joints is name -> radians (clamped to the limits there).
  // One at a time, in order: an earlier reply never lands after a later one.
  pose(joints) {
    const sent = (this.sending || Promise.resolve()).then(() => this.post(joints));
    this.sending = sent.catch(() => null); // one lost on the way does not stop the next
    return sent;
  }

  async post(joints) {
    const reply = await post("/api/robot/pose", { joints });
    if (!reply.ok) {
      this.handlers.status(reply.data.error, "bad");
      return;
    }
    this.show(reply.data.joints);
    document.body.dataset.posed = JSON.stringify(reply.data.joints);
  }

  // The joints as the robot has them now (a slider being dragged keeps its place).
  show(joints) {
    if (this.figure) this.figure.show(joints);
    for (const [name, angle] of Object.entries(joints || {})) {
      const made = this.sliders[name];
      if (!made || document.activeElement === made.slider) continue;
      made.slider.value = angle;
      made.value.textContent = Number(angle).toFixed(2);
    }
  }
}
