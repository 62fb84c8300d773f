// node-wot (Scripting API only) invoking gotoRun RUNS times, one after the other, each followed to its
// terminal gotoRunFeedback by its correlationId; prints one JSON line per run: {"ms": invoke -> terminal}.
//   NODE_PATH=<node_modules> node nodewot_invoke.js BROKER_URL ROBOT RUNS
"use strict";
const mqtt = require("mqtt");
const { Servient } = require("@node-wot/core");
const { MqttClientFactory } = require("@node-wot/binding-mqtt");

async function fetchTD(broker, robot) {
  const client = await mqtt.connectAsync(broker);
  const text = await new Promise((resolve) => {
    client.on("message", (_topic, payload) => {
      if (payload.length > 0) resolve(payload.toString("utf8"));
    });
    client.subscribe(`td2adaptor/${robot}/td`);
  });
  await client.endAsync();
  return text;
}

async function main() {
  const [broker, robot, runs] = process.argv.slice(2);
  const servient = new Servient();
  servient.addClientFactory(new MqttClientFactory());
  const WoT = await servient.start();
  const thing = await WoT.consume(JSON.parse(await fetchTD(broker, robot)));
  const waiting = new Map();
  await thing.subscribeEvent("gotoRunFeedback", async (output) => {
    const event = await output.value();
    const done = waiting.get(event.correlationId);
    if (done && event.terminal) done(event);
  });
  await new Promise((resolve) => setTimeout(resolve, 300));
  const goal = { procedure: { goals: [{ pose: { x: 1.0, y: 0.0, theta: 0.0 } }] } };
  for (let i = 0; i < Number(runs); i++) {
    const id = `bench-${i}`;
    const terminal = new Promise((resolve) => waiting.set(id, resolve));
    const t0 = process.hrtime.bigint();
    await thing.invokeAction("gotoRun", { ...goal, correlationId: id });
    const event = await terminal;
    const ms = Number(process.hrtime.bigint() - t0) / 1e6;
    process.stdout.write(JSON.stringify({ ms, state: event.state }) + "\n");
  }
  await servient.shutdown();
  process.exit(0);
}

main().catch((error) => {
  process.stderr.write(String(error && error.stack ? error.stack : error) + "\n");
  process.exit(1);
});
