// The page: the fleet from the server's event stream, one robot's view built from its Thing Description.

import { FleetMap } from "./map.js";
import { el, schemaForm } from "./schemaform.js";
import { Timeline } from "./timeline.js";
import { ValueView } from "./tree.js";

const $ = (id) => document.getElementById(id);
const state = { robots: new Map(), selected: null, td: null, readOnly: false, source: null, views: new Map(), values: new Map(), pending: new Map(), frame: 0 };
// what the page measured: when each value of the watched robot reached the screen (bench/dashboard.py reads it)
const probe = (window.dashboardProbe = { paints: [], keep: 5000 });
const map = new FleetMap($("map"), (robot) => select(robot));
const timeline = new Timeline($("timeline"), { operate, canOperate });

function selectedFromHash() {
  const m = location.hash.match(/^#\/robot\/(.+)$/);
  return m ? decodeURIComponent(m[1]) : null;
}

function connect() {
  state.source?.close();
  const watch = state.selected ? `?watch=${encodeURIComponent(state.selected)}` : "";
  const source = new EventSource(`/api/events${watch}`);
  state.source = source;
  source.onopen = () => setConnection("live");
  source.onerror = () => setConnection(source.readyState === EventSource.CLOSED ? "lost" : "connecting");
  source.onmessage = (message) => {
    const received = Date.now();
    const item = JSON.parse(message.data);
    if (item.k === "snapshot") snapshot(item);
    else if (item.k === "batch") item.items.forEach((i) => apply(i, received));
  };
}

function setConnection(word) {
  $("connection").dataset.state = word;
  $("connection").textContent = word;
}

function snapshot(item) {
  const changed = state.readOnly !== item.readOnly;
  state.readOnly = item.readOnly;
  if (changed && state.td) renderRobot();
  $("mode").hidden = !item.readOnly;
  document.body.dataset.readOnly = String(item.readOnly);
  state.robots.clear();
  for (const robot of item.robots) state.robots.set(robot.id, robot);
  for (const robot of state.robots.values()) map.set(robot.id, robot.pose);
  renderFleet();
  if (state.selected && item.values) {
    for (const [name, value] of Object.entries(item.values)) showValue(name, value, Date.now(), Date.now());
    timeline.clear();
    for (const e of item.events || []) timeline.event(e.name, e.data, e.t);
  }
}

function apply(item, received) {
  if (item.k === "robot") {
    const known = state.robots.has(item.robot.id);
    state.robots.set(item.robot.id, item.robot);
    map.set(item.robot.id, item.robot.pose);
    renderFleet();
    if (item.robot.id === state.selected) {
      renderStatus();
      if (!state.td || !known) loadRobot();
    }
  } else if (item.k === "gone") {
    state.robots.delete(item.robot);
    map.remove(item.robot);
    renderFleet();
    if (item.robot === state.selected) renderStatus();
  } else if (item.k === "pose") {
    const robot = state.robots.get(item.robot);
    if (robot) robot.pose = item.pose;
    map.set(item.robot, item.pose);
    schedule();
  } else if (item.k === "value" && item.robot === state.selected) {
    state.pending.set(item.name, [item.value, item.t, received]);
    schedule();
  } else if (item.k === "event" && item.robot === state.selected) {
    timeline.event(item.name, item.data, item.t);
  }
}

function schedule() {
  if (!state.frame) state.frame = requestAnimationFrame(frame);
}

function frame() {
  state.frame = 0;
  const painted = [];
  for (const [name, [value, t, received]] of state.pending) {
    showValue(name, value, t, received);
    painted.push([name, value, received]);
  }
  state.pending.clear();
  $("map-section").hidden = !map.draw();
  const now = Date.now();
  for (const [name, value, received] of painted) {
    const stamp = value && typeof value === "object" && typeof value.stamp === "number" ? value.stamp : null;
    probe.paints.push({ robot: state.selected, name, stamp, received, paint: now });
  }
  if (probe.paints.length > probe.keep) probe.paints.splice(0, probe.paints.length - probe.keep);
}

function showValue(name, value, t) {
  state.values.set(name, [value, t]);
  const view = state.views.get(name);
  if (view) {
    view.update(value, t);
    view.container.closest(".prop").dataset.updated = String(t);
  }
}

// The status in one word: offline; online with the robot's ROS side absent or partial (the edge node is up, the
// robot is not all there); online; unknown (no status yet).
function statusWord(robot) {
  const status = robot?.status;
  if (!status?.state) return "unknown";
  if (status.state === "online" && typeof status.robot === "string" && status.robot !== "present") return status.robot;
  return status.state;
}

function fields(obj, skip = []) {
  return Object.entries(obj || {}).filter(([k, v]) => !skip.includes(k) && v !== null && v !== undefined);
}

// a status member as text, whatever it holds (an owner process, a list of missing actions, ...)
function describe(value) {
  if (Array.isArray(value)) return value.map(describe).join(", ");
  if (value && typeof value === "object") return Object.entries(value).map(([k, v]) => `${k} ${describe(v)}`).join(" ");
  return String(value);
}

function lastError(robot) {
  return robot?.lastError || robot?.status?.lastError || null;
}

function renderFleet() {
  const list = $("robots");
  const robots = [...state.robots.values()].sort((a, b) => a.id.localeCompare(b.id));
  $("count").textContent = `(${robots.length})`;
  $("no-robots").hidden = robots.length > 0;
  const items = robots.map((robot) => {
    const word = statusWord(robot);
    const li = el("li", { "data-robot": robot.id, "data-state": word, "aria-selected": String(robot.id === state.selected) });
    li.append(el("strong", { text: robot.id }), " ", el("span", { class: "badge status-word", "data-state": word, text: word }));
    const shown = fields(robot.status, ["state", "time", "lastError"]).map(([k, v]) => `${k}: ${describe(v)}`);
    li.append(el("span", { class: "fields", text: [robot.title, ...shown].join(" · ") }));
    const error = lastError(robot);
    if (error) li.append(el("span", { class: "error", text: `${error.code}: ${error.message}` }));
    li.addEventListener("click", () => select(robot.id));
    return li;
  });
  list.replaceChildren(...items);
  map.selected = state.selected;
  $("map-section").hidden = !map.draw();
}

function renderStatus() {
  const robot = state.robots.get(state.selected);
  const dl = $("robot-status");
  dl.replaceChildren();
  const word = robot ? statusWord(robot) : "gone";
  dl.dataset.state = word;
  dl.append(el("dt", { text: "status" }), el("dd", {}, el("span", { class: "badge", "data-state": word, text: word })));
  for (const [k, v] of fields(robot?.status, ["state", "lastError"])) dl.append(el("dt", { text: k }), el("dd", { text: describe(v) }));
  const error = lastError(robot);
  if (error) dl.append(el("dt", { text: "last error" }), el("dd", { class: "error", text: `${error.code}: ${error.message}` }));
}

function select(robot) {
  if (robot === state.selected) return;
  location.hash = `#/robot/${encodeURIComponent(robot)}`;
}

async function loadRobot() {
  const id = state.selected;
  state.td = null;
  $("robot").hidden = !id;
  if (!id) return;
  const answer = await fetch(`/api/robots/${encodeURIComponent(id)}/td`);
  if (!answer.ok || id !== state.selected) return;
  state.td = await answer.json();
  renderRobot();
}

function renderRobot() {
  const td = state.td;
  $("robot").dataset.robot = state.selected;
  $("robot-title").textContent = `${td.title} — ${state.selected}`;
  $("robot-description").textContent = td.description || "";
  renderStatus();
  state.views.clear();
  const props = $("properties");
  props.replaceChildren();
  for (const [name, prop] of Object.entries(td.properties || {})) {
    const box = el("div", { class: "prop", "data-prop": name }, el("h4", { text: prop.title || name }));
    const ops = (prop.forms || []).flatMap((f) => [].concat(f.op || []));
    if (ops.includes("observeproperty") || ops.includes("readproperty")) {
      const view = new ValueView(el("div", { class: "value" }, el("span", { class: "muted", text: "no value yet" })));
      box.append(view.container);
      state.views.set(name, view);
    }
    if (ops.includes("writeproperty") && !state.readOnly) {
      box.append(schemaForm(dataSchema(prop), { label: "write", name: `write:${name}`, submit: (value) => writeProperty(name, value) }));
    }
    props.append(box);
  }
  for (const [name, [value, t]] of state.values) showValue(name, value, t);
  const actions = $("actions");
  actions.replaceChildren();
  const entries = Object.entries(td.actions || {}).sort(([, a], [, b]) => Number(hasOp(b, "queryaction")) - Number(hasOp(a, "queryaction")));
  for (const [name, action] of entries) {
    const details = el("details", { class: "action", "data-action": name }, el("summary", { text: action.title || name }));
    if (action.description) details.append(el("p", { class: "muted", text: action.description }));
    if (state.readOnly) details.append(el("p", { class: "muted", text: "read-only: not invokable here" }));
    else details.append(schemaForm(action.input || { type: "object", properties: {} }, { label: "invoke", name: `invoke:${name}`, submit: (value) => invoke(name, value) }));
    actions.append(details);
  }
}

function hasOp(affordance, op) {
  return (affordance.forms || []).some((f) => [].concat(f.op || []).includes(op));
}

function canOperate(action, op) {
  const affordance = state.td?.actions?.[action];
  return !state.readOnly && !!affordance && hasOp(affordance, `${op}action`);
}

function dataSchema(prop) {
  const { forms, title, description, observable, readOnly, writeOnly, ...schema } = prop;
  return schema;
}

async function post(url, body) {
  try {
    const answer = await fetch(url, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
    const data = await answer.json().catch(() => ({}));
    return answer.ok ? data : { error: data.error || `refused (${answer.status})` };
  } catch (exc) {
    return { error: `the dashboard did not answer (${exc.message})` };
  }
}

function operate(action, op, input) {
  return post(`/api/robots/${encodeURIComponent(state.selected)}/actions/${encodeURIComponent(action)}`, { op, input });
}

async function invoke(name, value) {
  const correlationId = `dash-${Math.random().toString(36).slice(2, 12)}`;
  const input = value && typeof value === "object" && !Array.isArray(value) ? { ...value, correlationId } : value;
  timeline.sent(correlationId, name, Date.now());
  const answer = await operate(name, "invoke", input);
  if (answer.error) timeline.notSent(correlationId, answer.error);
  return answer.error || null;
}

async function writeProperty(name, value) {
  const answer = await post(`/api/robots/${encodeURIComponent(state.selected)}/properties/${encodeURIComponent(name)}`, { value });
  return answer.error || null;
}

function route() {
  state.selected = selectedFromHash();
  state.pending.clear();
  state.values.clear();
  timeline.clear();
  connect();
  loadRobot();
  renderFleet();
}

window.addEventListener("hashchange", route);
route();
