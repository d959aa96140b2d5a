// The simulated Mini drawn from the front, to pose by hand as ROS Commander's users pose
// their robot with markers: drag the head sideways to pan it (neck) and up or down to
// tilt it (head), the body sideways to turn it (hip), a hand to raise or lower its arm.
// The robot faces the designer, so its left arm is on the right of the drawing. Every
// angle stays within the joint's limits; the figure follows the robot in a trial too.

import { el } from "./svg.js";

const PIXELS_PER_RADIAN = 60; // a drag of 60 px turns the head or the body 1 rad
const SHOULDER_Y = 78;
const ARM_LENGTH = 44;
const SHOULDERS = { right_arm: 52, left_arm: 108 }; // x: the robot's right is on our left
const HEAD = { x: 80, y: 38, r: 22 };

export class Figure {
  // limits: name -> {low, high, neutral}; moved(joints): called with the joints a drag set.
  constructor(parent, limits, moved) {
    this.limits = limits;
    this.moved = moved;
    this.dragging = null; // {part, from, start} while a part is dragged
    this.joints = Object.fromEntries(Object.entries(limits).map(([name, j]) => [name, j.neutral]));
    this.svg = el("svg", { id: "figure", viewBox: "0 0 160 150", width: 160, height: 150,
      role: "img", "aria-label": "The simulated Mini: drag its head, body or hands" }, parent);
    el("rect", { class: "base", x: 45, y: 132, width: 70, height: 12, rx: 4 }, this.svg);
    this.body = el("g", { class: "part", "data-part": "hip" }, this.svg);
    el("rect", { class: "torso", x: 56, y: 64, width: 48, height: 68, rx: 14 }, this.body);
    this.front = el("line", { class: "front", y1: 74, y2: 124 }, this.body);
    this.arms = {};
    for (const [name, x] of Object.entries(SHOULDERS)) {
      const arm = el("g", { class: "part arm", "data-part": name }, this.svg);
      this.arms[name] = { line: el("line", { x1: x, y1: SHOULDER_Y }, arm),
        hand: el("circle", { class: "hand", r: 7 }, arm) };
    }
    this.head = el("g", { class: "part", "data-part": "head" }, this.svg);
    el("circle", { class: "skull", cx: HEAD.x, cy: HEAD.y, r: HEAD.r }, this.head);
    this.eyes = [-8, 8].map(() => el("circle", { class: "eye", r: 3 }, this.head));
    this.listen();
    this.draw();
  }

  clamp(name, angle) {
    const { low, high } = this.limits[name];
    return Math.round(Math.min(high, Math.max(low, angle)) * 100) / 100;
  }

  // The joints as the robot has them now (not while the designer drags).
  show(joints) {
    if (this.dragging) return;
    Object.assign(this.joints, joints || {});
    this.draw();
  }

  draw() {
    const j = this.joints;
    const turn = Math.sin(j.hip || 0) * 20; // the body's front line, turned with the hip
    this.front.setAttribute("x1", 80 + turn);
    this.front.setAttribute("x2", 80 + turn);
    const pan = Math.sin((j.neck || 0) + (j.hip || 0)) * 10;
    const tilt = Math.sin(j.head || 0) * 14;
    this.eyes.forEach((eye, i) => {
      eye.setAttribute("cx", HEAD.x + (i ? 8 : -8) + pan);
      eye.setAttribute("cy", HEAD.y - 2 + tilt);
    });
    for (const [name, x] of Object.entries(SHOULDERS)) {
      const outward = name === "left_arm" ? 1 : -1;
      const angle = j[name] || 0; // 0 hangs down; raised outward in the drawing
      const hx = x + outward * Math.sin(angle) * ARM_LENGTH;
      const hy = SHOULDER_Y + Math.cos(angle) * ARM_LENGTH;
      const { line, hand } = this.arms[name];
      line.setAttribute("x2", hx);
      line.setAttribute("y2", hy);
      hand.setAttribute("cx", hx);
      hand.setAttribute("cy", hy);
    }
  }

  point(event) {
    const box = this.svg.getBoundingClientRect();
    return { x: (event.clientX - box.left) * (160 / box.width),
      y: (event.clientY - box.top) * (150 / box.height) };
  }

  listen() {
    this.svg.addEventListener("pointerdown", (event) => {
      const part = event.target.closest(".part");
      if (!part) return;
      event.preventDefault();
      this.svg.setPointerCapture(event.pointerId);
      this.dragging = { part: part.dataset.part, from: this.point(event), start: { ...this.joints } };
    });
    this.svg.addEventListener("pointermove", (event) => {
      if (!this.dragging) return;
      const changed = this.follow(this.dragging, this.point(event));
      Object.assign(this.joints, changed);
      this.draw();
      this.moved(changed);
    });
    const end = () => { this.dragging = null; };
    this.svg.addEventListener("pointerup", end);
    this.svg.addEventListener("pointercancel", end);
  }

  // The joints a drag of `part` to `at` sets.
  follow({ part, from, start }, at) {
    const dx = (at.x - from.x) / PIXELS_PER_RADIAN;
    const dy = (at.y - from.y) / PIXELS_PER_RADIAN;
    if (part === "head") {
      return { neck: this.clamp("neck", start.neck + dx), head: this.clamp("head", start.head + dy) };
    }
    if (part === "hip") return { hip: this.clamp("hip", start.hip + dx) };
    const outward = part === "left_arm" ? 1 : -1;
    // 0 straight down, pi/2 outward, pi up; above the shoulder on the inner side is up
    const angle = Math.atan2(outward * (at.x - SHOULDERS[part]), at.y - SHOULDER_Y);
    return { [part]: this.clamp(part, angle < -Math.PI / 2 ? Math.PI : angle) };
  }
}
