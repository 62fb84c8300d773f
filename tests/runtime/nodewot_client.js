// A standard WoT consumer (Eclipse Thingweb node-wot with its MQTT binding) using a robot as a Thing: it
// fetches the robot's Thing Description where the edge node keeps it (retained on td2adaptor/<robot>/td)
// and consumes it exactly as published; then reads and observes a property, subscribes to the feedback
// event and invokes an action. One JSON line per observation on stdout; exits 0 after the terminal feedback
// and a property value, 1 on an error.
//   NODE_PATH=<node_modules> node nodewot_client.js BROKER_URL ROBOT CORRELATION
"use strict";
const mqtt = require("mqtt"); // the MQTT client node-wot's binding uses
const { Servient } = require("@node-wot/core");
const { MqttClientFactory } = require("@node-wot/binding-mqtt");

function emit(kind, value) {
  process.stdout.write(JSON.stringify({ kind, value }) + "\n");
}

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
  const [broker, robot, correlation] = process.argv.slice(2);
  const text = await fetchTD(broker, robot);
  emit("td", text);
  const servient = new Servient();
  servient.addClientFactory(new MqttClientFactory());
  const WoT = await servient.start();
  const thing = await WoT.consume(JSON.parse(text));
  const read = await thing.readProperty("poseMarker");
  emit("read", await read.value());
  let sawProperty = false;
  let sawTerminal = false;
  const finish = () => {
    if (sawProperty && sawTerminal) {
      emit("done", null);
      servient.shutdown();
      process.exit(0);
    }
  };
  await thing.observeProperty("poseMarker", async (output) => {
    emit("property", await output.value());
    sawProperty = true;
    finish();
  });
  await thing.subscribeEvent("gotoRunFeedback", async (output) => {
    const event = await output.value();
    emit("feedback", event);
    if (event.correlation === correlation && event.payload && event.payload.terminal) {
      sawTerminal = true;
      finish();
    }
  });
  emit("subscribed", null);
  await new Promise((resolve) => setTimeout(resolve, 300)); // let the broker confirm the subscriptions
  // today's event contract: the action's input is the event (correlation, source, the goal as payload)
  const goal = { procedure: { goals: [{ pose: { x: 1.5, y: 3.0, theta: 0.0 } }] } };
  await thing.invokeAction("gotoRun", { correlation, source: "node-wot", payload: goal });
  emit("invoked", null);
}

main().catch((error) => {
  emit("error", String(error && error.stack ? error.stack : error));
  process.exit(1);
});
setTimeout(() => {
  emit("error", "timed out");
  process.exit(1);
}, 20000);
