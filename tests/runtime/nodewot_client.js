// A standard WoT consumer (Eclipse Thingweb node-wot with its MQTT binding) using the exposed TD of an
// adaptor: observe a property, subscribe to the feedback event, invoke an action. One JSON line per
// observation on stdout; exits 0 after the terminal feedback and a property value, 1 on an error.
//   NODE_PATH=<node_modules> node nodewot_client.js TD.json CORRELATION
"use strict";
const fs = require("fs");
const { Servient } = require("@node-wot/core");
const { MqttClientFactory } = require("@node-wot/binding-mqtt");

function emit(kind, value) {
  process.stdout.write(JSON.stringify({ kind, value }) + "\n");
}

async function main() {
  const td = JSON.parse(fs.readFileSync(process.argv[2], "utf8"));
  const correlation = process.argv[3];
  const servient = new Servient();
  servient.addClientFactory(new MqttClientFactory());
  const WoT = await servient.start();
  const thing = await WoT.consume(td);
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
