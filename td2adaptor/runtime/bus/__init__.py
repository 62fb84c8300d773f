"""The event side of the edge node: the `Bus` protocol (`bus`), the in-process bus (`localbus`), MQTT
connections (`mqttbus`, and `drivenbus` without a network thread), the WoT topic adapter (`thingbus`) and how
a TD's security definitions decide the connection (`security`)."""
