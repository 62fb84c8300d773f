// A standard WoT consumer (Eclipse Thingweb node-wot with its MQTT binding) using a robot as a Thing, through
// the WoT Scripting API only: it fetches the robot's Thing Description where the edge node keeps it (retained
// on td2adaptor/<robot>/td) and consumes it exactly as published; reads, observes and writes properties with
// their own data, and the robot's presence (its retained status); invokes gotoRun with the goal's fields (plus
// the optional correlationId the TD declares) and follows it to its terminal outcome; invokes a second run,
// queries it and cancels it while it runs; sends a goal the robot's message cannot hold and receives the
// error event; then ends its observation and its subscription to the error event (the TD's one form for both
// operations) and receives nothing more there.
// One JSON line per observation on stdout; exits 0 when all is seen, 1 on an error or after 25 s.
//   NODE_PATH=<node_modules> node nodewot_client.js BROKER_URL ROBOT
// With WOT_USERNAME and WOT_PASSWORD set, it logs in to the broker with them: to fetch the TD, and as the
// credentials it gives node-wot for the Thing (which uses them only where the TD's security asks for them).
"use strict";
const mqtt = require("mqtt"); // the MQTT client node-wot's binding uses, only to fetch the retained TD
const { Servient } = require("@node-wot/core");
const { MqttClientFactory } = require("@node-wot/binding-mqtt");

const t0 = process.hrtime.bigint();
function emit(kind, value) {
  const ms = Number(process.hrtime.bigint() - t0) / 1e6;
  process.stdout.write(JSON.stringify({ kind, value, ms }) + "\n");
}

const login = process.env.WOT_USERNAME
  ? { username: process.env.WOT_USERNAME, password: process.env.WOT_PASSWORD }
  : undefined;

async function fetchTD(broker, robot) {
  const client = await mqtt.connectAsync(broker, login || {});
  const text = await new Promise((resolve) => {
    client.on("message", (_topic, payload) => {
      if (payload.length > 0) resolve(payload.toString("utf8"));
    });
    client.subscribe(`td2adaptor/${robot}/td`);
  });
  await client.endAsync();
  return text;
}

// resolves with the first event of `list` that satisfies `predicate` (now or later)
function waiter(list) {
  const pending = [];
  return {
    push(value) {
      list.push(value);
      for (const p of pending.slice()) {
        if (p.predicate(value)) {
          pending.splice(pending.indexOf(p), 1);
          p.resolve(value);
        }
      }
    },
    until(predicate) {
      const found = list.find(predicate);
      if (found) return Promise.resolve(found);
      return new Promise((resolve) => pending.push({ predicate, resolve }));
    },
  };
}

async function main() {
  const [broker, robot] = process.argv.slice(2);
  const text = await fetchTD(broker, robot);
  emit("td", text);
  const servient = new Servient();
  servient.addClientFactory(new MqttClientFactory());
  const td = JSON.parse(text);
  if (login) servient.addCredentials({ [td.id]: login });
  const WoT = await servient.start();
  const thing = await WoT.consume(td);

  // properties: the value itself, read (retained), observed, written
  const read = await thing.readProperty("poseMarker");
  emit("read", await read.value());
  const observed = waiter([]);
  const observation = await thing.observeProperty("poseMarker", async (output) => {
    const value = await output.value();
    emit("observed", value);
    observed.push(value);
  });
  await thing.writeProperty("door", { data: 0.75 });
  emit("written", { data: 0.75 });
  // is the robot there? its retained status, read as a property
  emit("presence", await (await thing.readProperty("presence")).value());

  // events: progress and outcome of procedures, answers to queries and cancels, errors
  const feedback = waiter([]);
  const states = waiter([]);
  const errors = waiter([]);
  const subscriptions = {};
  for (const [name, sink] of [["gotoRunFeedback", feedback], ["gotoRunState", states], ["error", errors]]) {
    subscriptions[name] = await thing.subscribeEvent(name, async (output) => {
      const value = await output.value();
      emit(name, value);
      sink.push(value);
    });
  }
  emit("subscribed", null);
  await new Promise((resolve) => setTimeout(resolve, 300)); // let the broker confirm the subscriptions

  // 1. a goal, followed to its terminal outcome
  const goal = { procedure: { goals: [{ pose: { x: 1.5, y: 3.0, theta: 0.0 } }] } };
  emit("invoke", "wot-1");
  await thing.invokeAction("gotoRun", { ...goal, correlationId: "wot-1" });
  await feedback.until((e) => e.correlationId === "wot-1" && e.terminal);
  emit("outcome", "wot-1");

  // 2. another one, queried and cancelled while it runs
  await thing.invokeAction("gotoRun", { ...goal, correlationId: "wot-2" });
  const started = await feedback.until((e) => e.correlationId === "wot-2" && !e.terminal);
  await thing.invokeAction("gotoQuery", { mission: started.mission, correlationId: "q-1" });
  await states.until((e) => e.correlationId === "q-1");
  await thing.invokeAction("gotoCancel", { mission: started.mission, correlationId: "c-1" });
  await states.until((e) => e.correlationId === "c-1");
  await feedback.until((e) => e.correlationId === "wot-2" && e.terminal);
  emit("cancelled", "wot-2");

  // 3. goals the robot's message cannot hold: refused at once, with the error event
  await thing.invokeAction("pickRun", { nope: 1, correlationId: "bad-1" });
  await errors.until((e) => e.correlationId === "bad-1");
  await observed.until(() => true);

  // 4. unobserve and unsubscribe (node-wot takes the topic from the form it finds for that operation): the
  // next error reaches a plain MQTT client but not node-wot; the state event node-wot still receives after
  // it was published on the same connection, so the error would have come first
  const watcher = await mqtt.connectAsync(broker, login || {});
  const seen = waiter([]);
  watcher.on("message", (_topic, payload) => seen.push(JSON.parse(payload.toString("utf8"))));
  await watcher.subscribeAsync(`td2adaptor/${robot}/wot-thing/error`);
  await observation.stop();
  await subscriptions.error.stop();
  emit("unsubscribed", null);
  await thing.invokeAction("pickRun", { nope: 2, correlationId: "bad-2" });
  await seen.until((e) => e.correlationId === "bad-2");
  await thing.invokeAction("gotoQuery", { correlationId: "q-2" });
  await states.until((e) => e.correlationId === "q-2");
  await watcher.endAsync();
  emit("done", null);
  await servient.shutdown();
  process.exit(0);
}

main().catch((error) => {
  emit("error", String(error && error.stack ? error.stack : error));
  process.exit(1);
});
setTimeout(() => {
  emit("error", "timed out");
  process.exit(1);
}, 25000);
