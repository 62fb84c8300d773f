// A WoT consumer (Eclipse Thingweb node-wot with its MQTT binding) that fetches the robot's Thing Description
// (retained on td2adaptor/<robot>/td), consumes it as published and reads each property named on the command
// line with readProperty, which waits for the property's retained value. One JSON line per value read on
// stdout; exits 0 once every one is read, 1 on an error or after 10 s (a value the broker does not hold).
//   NODE_PATH=<node_modules> node nodewot_read.js BROKER_URL ROBOT PROPERTY...
"use strict";
const mqtt = require("mqtt"); // the MQTT client node-wot's binding uses, only to fetch the retained TD
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
  const [broker, robot, ...names] = process.argv.slice(2);
  const servient = new Servient();
  servient.addClientFactory(new MqttClientFactory());
  const WoT = await servient.start();
  const thing = await WoT.consume(JSON.parse(await fetchTD(broker, robot)));
  for (const name of names) {
    const output = await thing.readProperty(name);
    process.stdout.write(JSON.stringify({ name, value: await output.value() }) + "\n");
  }
  process.exit(0);
}

setTimeout(() => {
  process.stderr.write("timed out: a property value never came\n");
  process.exit(1);
}, 10000);
main().catch((err) => {
  process.stderr.write(String(err && err.stack ? err.stack : err) + "\n");
  process.exit(1);
});
