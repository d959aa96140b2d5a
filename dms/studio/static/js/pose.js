// Posing the simulated Mini by hand, as ROS Commander's users pose their robot before
// they record: a slider per joint, within the joint's limits (from the server). Each
// move sets the simulated Mini's joints; Record then takes them as a keyframe. During
// a trial the sliders follow the robot.

import { get, post } from "./api.js";

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
        value.textContent = Number(slider.value).toFixed(2);
        this.wanted[name] = Number(slider.value);
        if (!this.timer) this.timer = setTimeout(() => this.send(), SEND_MS);
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

  async send() {
    this.timer = null;
    const joints = this.wanted;
    this.wanted = {};
    if (Object.keys(joints).length) await this.pose(joints);
  }

  // Pose the simulated Mini: joints is name -> radians (clamped to the limits there).
  async pose(joints) {
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
    for (const [name, angle] of Object.entries(joints || {})) {
      const made = this.sliders[name];
      if (!made || document.activeElement === made.slider) continue;
      made.slider.value = angle;
      made.value.textContent = Number(angle).toFixed(2);
    }
  }
}
