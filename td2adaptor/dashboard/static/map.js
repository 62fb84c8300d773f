// The fleet on a 2D map (SVG): each robot with a pose at its x, y, its heading as a line; the view fits them all.

const NS = "http://www.w3.org/2000/svg";

function svg(tag, attrs = {}) {
  const node = document.createElementNS(NS, tag);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, String(v));
  return node;
}

export class FleetMap {
  constructor(root, onPick) {
    this.root = root;
    this.onPick = onPick;
    this.marks = new Map();
    this.poses = new Map();
    this.selected = null;
  }

  set(robot, pose) {
    if (pose) this.poses.set(robot, pose); else this.poses.delete(robot);
  }

  remove(robot) {
    this.poses.delete(robot);
    this.marks.get(robot)?.remove();
    this.marks.delete(robot);
  }

  draw() {
    const size = 300, pad = 48;
    const all = [...this.poses.values()];
    if (all.length === 0) return false;
    let [x0, x1, y0, y1] = [Infinity, -Infinity, Infinity, -Infinity];
    for (const [x, y] of all) { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); }
    const span = Math.max(x1 - x0, y1 - y0, 2);
    const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
    const scale = (size - 2 * pad) / span;
    const at = (x, y) => [size / 2 + (x - cx) * scale, size / 2 - (y - cy) * scale];
    for (const [robot, [x, y, theta]] of this.poses) {
      let mark = this.marks.get(robot);
      if (!mark) {
        mark = svg("g", { class: "robot", "data-robot": robot });
        mark.append(svg("circle", { r: 6 }), svg("line", {}), svg("text", { x: 8, y: -8 }));
        mark.querySelector("text").textContent = robot;
        mark.addEventListener("click", () => this.onPick(robot));
        this.root.append(mark);
        this.marks.set(robot, mark);
      }
      const [px, py] = at(x, y);
      mark.setAttribute("transform", `translate(${px.toFixed(1)},${py.toFixed(1)})`);
      const label = mark.querySelector("text"); // on the side with room for it
      label.setAttribute("x", px > size * 0.6 ? -8 : 8);
      label.setAttribute("text-anchor", px > size * 0.6 ? "end" : "start");
      mark.dataset.x = x; mark.dataset.y = y;
      mark.dataset.selected = String(robot === this.selected);
      const line = mark.querySelector("line");
      const h = theta ?? 0;
      line.setAttribute("x2", (10 * Math.cos(h)).toFixed(1));
      line.setAttribute("y2", (-10 * Math.sin(h)).toFixed(1));
      line.setAttribute("visibility", theta === null || theta === undefined ? "hidden" : "visible");
    }
    return true;
  }
}
