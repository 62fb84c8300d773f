// Each mission as the robot tells it: sent → queued → running (every feedback) → the terminal state with the
// robot's words; answers to queries and cancels, and refusals (error events), under the mission they are about.
// Events are matched by the correlationId the page sent (the node carries it back), or the mission id.

import { el } from "./schemaform.js";

function clock(t) {
  const d = new Date(t);
  return d.toTimeString().slice(0, 8) + "." + String(d.getMilliseconds()).padStart(3, "0");
}

export class Timeline {
  constructor(root, { operate, canOperate }) {
    this.root = root;
    this.operate = operate; // (action, op, input) -> Promise<{correlationId}|{error}>
    this.canOperate = canOperate; // (action, op) -> bool
    this.cards = new Map(); // correlationId -> card
    this.aliases = new Map(); // correlationId of a query/cancel -> the card it is about
    this.byMission = new Map(); // "action:mission" -> card
  }

  clear() {
    this.cards.clear(); this.aliases.clear(); this.byMission.clear();
    this.root.replaceChildren();
  }

  card(key, action) {
    let card = this.cards.get(key);
    if (card) return card;
    const node = el("li", { "data-correlation": key, "data-action": action, "data-terminal": "false" });
    const head = el("div", { class: "tl-head" }, el("strong", { text: action }), el("span", { class: "mission muted" }));
    const buttons = el("span", { class: "tl-buttons" });
    for (const op of ["query", "cancel"]) {
      if (!this.canOperate(action, op)) continue;
      const button = el("button", { type: "button", "data-op": op, text: op });
      button.addEventListener("click", () => this.ask(card, op));
      buttons.append(" ", button);
    }
    head.append(buttons);
    node.append(head);
    this.root.prepend(node);
    card = { key, action, node, mission: null, buttons };
    this.cards.set(key, card);
    return card;
  }

  async ask(card, op) {
    const correlationId = `${op}-${Math.random().toString(36).slice(2, 10)}`;
    this.aliases.set(correlationId, card);
    const input = { correlationId };
    if (card.mission !== null) input.mission = card.mission;
    this.entry(card, "request", { text: `${op} sent` }, Date.now());
    const answer = await this.operate(card.action, op, input);
    if (answer.error) this.entry(card, "error", { text: `${op} not sent: ${answer.error}` }, Date.now());
  }

  sent(correlationId, action, t) {
    const card = this.card(correlationId, action);
    this.entry(card, "request", { text: "invoke sent" }, t);
    return card;
  }

  notSent(correlationId, error) {
    const card = this.cards.get(correlationId);
    if (card) this.entry(card, "error", { text: `not sent: ${error}` }, Date.now(), "refused");
  }

  event(name, data, t) {
    if (!data || typeof data !== "object") return;
    const correlation = typeof data.correlationId === "string" ? data.correlationId : null;
    const action = name.replace(/(Feedback|State)$/, "");
    let card = correlation ? this.aliases.get(correlation) || this.cards.get(correlation) : null;
    if (!card && data.mission !== undefined) card = this.byMission.get(`${action}:${data.mission}`);
    if (!card) {
      if (name === "error" && !correlation) return; // the fleet list shows errors about nobody's mission
      card = this.card(correlation || `${action}:${data.mission}`, name === "error" ? data.affordance || "error" : action);
    }
    if (data.mission !== undefined && card.mission === null) {
      card.mission = data.mission;
      card.node.dataset.mission = String(data.mission);
      card.node.querySelector(".mission").textContent = ` mission ${data.mission}`;
      this.byMission.set(`${card.action}:${data.mission}`, card);
    }
    if (name === "error") {
      const paths = (data.errors || []).map((e) => `${e.path}: ${e.message}`).join("; ");
      const text = `refused (${data.code}): ${data.message}${paths && !String(data.message).includes(paths) ? ` [${paths}]` : ""}`;
      this.entry(card, "error", { text, code: data.code }, t, correlation && this.aliases.has(correlation) ? null : "refused");
      return;
    }
    const words = [data.message, data.result && `result ${data.result}`, data.reason && `reason ${data.reason}`, data.last_event && `event ${data.last_event}`];
    const kind = name.endsWith("State") ? "state" : "feedback";
    const prefix = kind === "state" ? "answer: " : "";
    const seq = data.seq !== undefined ? ` #${data.seq}` : "";
    this.entry(card, kind, { state: data.state, text: `${prefix}${data.state ?? "?"}${seq} ${words.filter(Boolean).join(", ")}` }, t);
    if (data.terminal === true) {
      card.node.dataset.terminal = "true";
      card.node.dataset.outcome = data.state;
      if (kind === "feedback") card.buttons.querySelectorAll("button").forEach((b) => (b.disabled = true));
    }
  }

  entry(card, kind, { text, state, code }, t, outcome = null) {
    const line = el("div", { class: "tl-entry", "data-kind": kind, "data-state": state, "data-code": code }, el("span", { class: "muted", text: `${clock(t)} ` }));
    if (state) line.append(el("span", { class: "state", text: "" }));
    line.append(text);
    card.node.append(line);
    if (outcome) card.node.dataset.outcome = outcome;
  }
}
