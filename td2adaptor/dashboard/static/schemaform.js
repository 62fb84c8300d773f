// A form generated from a TD data schema (a subset of JSON Schema: object, array, string, number, integer,
// boolean, enum, const, ranges, lengths, required), the page's own check of what it collects, and a JSON text
// view of the same value. A field left empty is left out (the node gives it the ROS default), unless required.
// Fields are named by their JSON pointer, e.g. "/procedure/goals/0/pose/x".

const HIDDEN = new Set(["correlationId"]); // the page sets it: it follows the mission by it

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (value === undefined || value === null || value === false) continue;
    if (key === "text") node.textContent = value;
    else node.setAttribute(key, value === true ? "" : String(value));
  }
  for (const child of children) if (child) node.append(child);
  return node;
}

function kindOf(schema) {
  if (!schema || typeof schema !== "object") return "json";
  if ("const" in schema) return "const";
  if (Array.isArray(schema.enum)) return "enum";
  if (schema.type === "object" || (schema.properties && !schema.type)) return "object";
  return ["array", "string", "number", "integer", "boolean"].includes(schema.type) ? schema.type : "json";
}

// builders: each returns {node, read(): {value, empty}} so parents can leave empty optional members out
function build(schema, pointer, name, required) {
  const kind = kindOf(schema);
  const title = schema?.title || name;
  const help = [schema?.description, range(schema)].filter(Boolean).join(" ");
  if (kind === "object") {
    const fields = [];
    const box = el("fieldset", { "data-pointer": pointer }, name ? el("legend", { text: title + (required ? " *" : "") }) : null);
    const needed = new Set(schema.required || []);
    for (const [key, sub] of Object.entries(schema.properties || {})) {
      if (HIDDEN.has(key)) continue;
      const field = build(sub, `${pointer}/${key}`, key, needed.has(key));
      fields.push([key, field]);
      box.append(field.node);
    }
    return {
      node: name ? box : el("div", {}, ...box.childNodes),
      read() {
        const value = {};
        for (const [key, field] of fields) {
          const got = field.read();
          if (!got.empty) value[key] = got.value;
        }
        return { value, empty: Object.keys(value).length === 0 };
      },
    };
  }
  if (kind === "array") {
    const items = [];
    const list = el("div", { class: "items" });
    const box = el("fieldset", { "data-pointer": pointer }, el("legend", { text: `${title} (list)` }), list);
    const add = el("button", { type: "button", "data-add": pointer, text: "+ item" });
    const fixed = schema.minItems !== undefined && schema.minItems === schema.maxItems;
    const addItem = () => {
      const field = build(schema.items || {}, `${pointer}/${items.length}`, `${items.length}`, true);
      const remove = el("button", { type: "button", text: "remove" });
      const row = el("div", { class: "item" }, field.node, fixed ? null : remove);
      const entry = { field, row };
      remove.addEventListener("click", () => { items.splice(items.indexOf(entry), 1); row.remove(); });
      items.push(entry);
      list.append(row);
    };
    add.addEventListener("click", addItem);
    if (!fixed) box.append(add);
    for (let i = 0; i < (schema.minItems || 0); i++) addItem();
    if (!schema.minItems && kindOf(schema.items) === "object") addItem(); // a list of goals wants one to start
    return {
      node: box,
      read() {
        const value = items.map((entry) => entry.field.read().value);
        return { value, empty: value.length === 0 && !required };
      },
    };
  }
  const label = el("label", { title: help || null }, el("span", { text: title + (required ? " *" : "") }));
  let input;
  if (kind === "boolean") {
    input = el("select", { name: pointer }, el("option", { value: "", text: "—" }), el("option", { value: "true", text: "true" }), el("option", { value: "false", text: "false" }));
  } else if (kind === "enum") {
    input = el("select", { name: pointer }, el("option", { value: "", text: "—" }));
    schema.enum.forEach((v, i) => input.append(el("option", { value: String(i), text: JSON.stringify(v) })));
  } else if (kind === "const") {
    input = el("input", { name: pointer, type: "text", value: JSON.stringify(schema.const), readonly: true });
  } else if (kind === "number" || kind === "integer") {
    input = el("input", { name: pointer, type: "text", inputmode: "decimal", placeholder: help || kind });
  } else if (kind === "string") {
    input = el("input", { name: pointer, type: "text", placeholder: schema.format || "" });
  } else {
    input = el("textarea", { name: pointer, rows: 2, placeholder: "JSON" });
  }
  if (schema?.default !== undefined && kind !== "const") input.value = kind === "enum" ? String(schema.enum.indexOf(schema.default)) : String(schema.default);
  label.append(input);
  return {
    node: label,
    read() {
      const text = input.value;
      if (kind === "const") return { value: schema.const, empty: !required };
      if (text === "") return { value: undefined, empty: true };
      if (kind === "enum") return { value: schema.enum[Number(text)], empty: false };
      if (kind === "boolean") return { value: text === "true", empty: false };
      if (kind === "number" || kind === "integer") {
        const trimmed = text.trim();
        const value = /^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(trimmed) ? Number(trimmed) : NaN;
        return { value: Number.isNaN(value) ? text : value, empty: false };
      }
      if (kind === "string") return { value: text, empty: false };
      try { return { value: JSON.parse(text), empty: false }; } catch { return { value: text, empty: false, bad: true }; }
    },
  };
}

function range(schema) {
  if (!schema) return "";
  const parts = [];
  if (schema.minimum !== undefined) parts.push(`≥ ${schema.minimum}`);
  if (schema.exclusiveMinimum !== undefined) parts.push(`> ${schema.exclusiveMinimum}`);
  if (schema.maximum !== undefined) parts.push(`≤ ${schema.maximum}`);
  if (schema.exclusiveMaximum !== undefined) parts.push(`< ${schema.exclusiveMaximum}`);
  return parts.join(", ");
}

// The page's check: what the TD's schema says (the node checks again, and more: closed objects, ROS ranges).
export function validate(schema, value, pointer = "") {
  const problems = [];
  const say = (message) => problems.push({ path: pointer || "/", message });
  if (!schema || typeof schema !== "object") return problems;
  if ("const" in schema && JSON.stringify(value) !== JSON.stringify(schema.const)) say(`must be ${JSON.stringify(schema.const)}`);
  if (Array.isArray(schema.enum) && !schema.enum.some((v) => JSON.stringify(v) === JSON.stringify(value))) say(`must be one of ${schema.enum.map((v) => JSON.stringify(v)).join(", ")}`);
  switch (schema.type) {
    case "object":
      if (typeof value !== "object" || value === null || Array.isArray(value)) { say("must be an object"); break; }
      for (const key of schema.required || []) if (!(key in value)) problems.push({ path: `${pointer}/${key}`, message: "is required" });
      for (const [key, sub] of Object.entries(schema.properties || {})) if (key in value) problems.push(...validate(sub, value[key], `${pointer}/${key}`));
      break;
    case "array":
      if (!Array.isArray(value)) { say("must be a list"); break; }
      if (schema.minItems !== undefined && value.length < schema.minItems) say(`needs at least ${schema.minItems} items`);
      if (schema.maxItems !== undefined && value.length > schema.maxItems) say(`takes at most ${schema.maxItems} items`);
      value.forEach((item, i) => problems.push(...validate(schema.items, item, `${pointer}/${i}`)));
      break;
    case "integer":
    case "number":
      if (typeof value !== "number" || !Number.isFinite(value)) { say("must be a finite number"); break; }
      if (schema.type === "integer" && !Number.isInteger(value)) { say("must be a whole number"); break; }
      if (schema.minimum !== undefined && value < schema.minimum) say(`must be ≥ ${schema.minimum}`);
      if (schema.maximum !== undefined && value > schema.maximum) say(`must be ≤ ${schema.maximum}`);
      if (schema.exclusiveMinimum !== undefined && value <= schema.exclusiveMinimum) say(`must be > ${schema.exclusiveMinimum}`);
      if (schema.exclusiveMaximum !== undefined && value >= schema.exclusiveMaximum) say(`must be < ${schema.exclusiveMaximum}`);
      break;
    case "string":
      if (typeof value !== "string") { say("must be text"); break; }
      if (schema.minLength !== undefined && [...value].length < schema.minLength) say(`needs at least ${schema.minLength} characters`);
      if (schema.maxLength !== undefined && [...value].length > schema.maxLength) say(`takes at most ${schema.maxLength} characters`);
      if (schema.pattern !== undefined && !new RegExp(schema.pattern, "u").test(value)) say(`must match ${schema.pattern}`);
      break;
    case "boolean":
      if (typeof value !== "boolean") say("must be true or false");
      break;
    default:
  }
  return problems;
}

// A form for `schema`: the generated fields, a JSON view to edit the value as text, a submit button.
// `submit(value)` is called with a value the page found valid; it returns a promise of an error text or null.
export function schemaForm(schema, { label, submit, name }) {
  const form = el("form", { class: "schema", "data-form": name, novalidate: true });
  const fields = build(schema || {}, "", "", true);
  const raw = el("textarea", { name: "json", rows: 4, hidden: true, "aria-label": "input as JSON" });
  const toggle = el("button", { type: "button", "data-json-toggle": "", text: "JSON" });
  const problems = el("div", { class: "problems", role: "alert" });
  const send = el("button", { type: "submit", text: label });
  form.append(fields.node, raw, el("div", {}, send, " ", toggle), problems);
  const hasInput = schema && (kindOf(schema) !== "object" || Object.keys(schema.properties || {}).some((k) => !HIDDEN.has(k)));
  if (!hasInput) { fields.node.hidden = true; toggle.hidden = true; }
  toggle.addEventListener("click", () => {
    if (raw.hidden) raw.value = JSON.stringify(fields.read().value ?? {}, null, 1);
    raw.hidden = !raw.hidden;
    fields.node.hidden = !raw.hidden || !hasInput;
  });
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    problems.textContent = "";
    form.querySelectorAll(".invalid").forEach((n) => n.classList.remove("invalid"));
    let value;
    if (!raw.hidden) {
      try { value = JSON.parse(raw.value || "{}"); } catch { problems.textContent = "the JSON text is not valid JSON"; return; }
    } else {
      const got = fields.read();
      value = got.value === undefined ? {} : got.value;
    }
    const found = validate(schema, value);
    if (found.length) {
      for (const p of found) form.querySelector(`[name="${CSS.escape(p.path)}"]`)?.classList.add("invalid");
      problems.textContent = found.map((p) => `${p.path}: ${p.message}`).join("; ");
      form.dataset.result = "refused-by-page";
      return;
    }
    send.disabled = true;
    const error = await submit(value);
    send.disabled = false;
    form.dataset.result = error ? "refused-by-server" : "sent";
    if (error) problems.textContent = error;
  });
  return form;
}

export { el };
