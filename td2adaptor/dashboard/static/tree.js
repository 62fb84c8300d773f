// A property's value as a readable tree; every number in it also gets a small time plot of its recent values.
// Updated in place while the value keeps its shape (a sensor at 10 Hz must not rebuild the DOM each time).

import { Series, draw, spark } from "./plot.js";

function shape(value) {
  if (Array.isArray(value)) return `[${value.map(shape).join(",")}]`;
  if (value && typeof value === "object") return `{${Object.entries(value).map(([k, v]) => `${k}:${shape(v)}`).join(",")}}`;
  return typeof value;
}

export class ValueView {
  constructor(container) {
    this.container = container;
    this.shape = null;
    this.leaves = new Map(); // pointer -> {text, canvas?}
    this.series = new Map(); // pointer -> Series (kept across shape changes)
  }

  update(value, t) {
    const s = shape(value);
    if (s !== this.shape) {
      this.shape = s;
      this.leaves.clear();
      this.container.replaceChildren(this.render(value, ""));
    }
    this.fill(value, "", t);
  }

  render(value, pointer, key) {
    const item = document.createElement(key === undefined ? "div" : "li");
    if (key !== undefined) {
      const k = document.createElement("span");
      k.className = "key";
      k.textContent = `${key}: `;
      item.append(k);
    }
    if (value && typeof value === "object") {
      const list = document.createElement("ul");
      list.className = key === undefined ? "tree" : "";
      const entries = Array.isArray(value) ? value.map((v, i) => [String(i), v]) : Object.entries(value);
      if (entries.length === 0) item.append(Array.isArray(value) ? "[]" : "{}");
      for (const [k, v] of entries) list.append(this.render(v, `${pointer}/${k}`, k));
      item.append(list);
      return item;
    }
    const text = document.createElement("span");
    text.dataset.pointer = pointer;
    const leaf = { text };
    item.append(text);
    if (typeof value === "number") {
      text.className = "num";
      leaf.canvas = spark();
      item.append(leaf.canvas);
    }
    this.leaves.set(pointer, leaf);
    return item;
  }

  fill(value, pointer, t) {
    if (value && typeof value === "object") {
      const entries = Array.isArray(value) ? value.map((v, i) => [String(i), v]) : Object.entries(value);
      for (const [k, v] of entries) this.fill(v, `${pointer}/${k}`, t);
      return;
    }
    const leaf = this.leaves.get(pointer);
    if (!leaf) return;
    leaf.text.textContent = typeof value === "number" ? String(Math.round(value * 1e6) / 1e6) : JSON.stringify(value);
    if (leaf.canvas && typeof value === "number") {
      let series = this.series.get(pointer);
      if (!series) this.series.set(pointer, (series = new Series()));
      series.add(t, value);
      draw(leaf.canvas, series);
    }
  }
}
