"""Helpers for the runtime tests: a real mosquitto per test, an MQTT test client, the RB-1 model."""
