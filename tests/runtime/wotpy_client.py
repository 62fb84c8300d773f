"""A second, independent WoT consumer: wotpy (PyPI, run under its own environment, .cache/wotpy) using a robot
through its Scripting API. Standard library and wotpy (with its amqtt) only: this file runs under wotpy's
interpreter, not td2adaptor's.

It fetches the TD retained on td2adaptor/<robot>/td, consumes the text as published, subscribes to the
poseMarker property and the gotoRunFeedback event, says "subscribed" (the test then starts a mission), reports
what arrives, and finally invokes gotoRun itself with a short timeout. One JSON line per observation.

    .cache/wotpy/bin/python wotpy_client.py BROKER_URL ROBOT
"""

from __future__ import annotations

import asyncio
import json
import sys
import time

import amqtt.client
from wotpy.wot.servient import Servient


def emit(kind: str, value: object) -> None:
    sys.stdout.write(json.dumps({"kind": kind, "value": value}) + "\n")
    sys.stdout.flush()


async def fetch_td(broker: str, robot: str) -> str:
    client = amqtt.client.MQTTClient()
    await client.connect(broker)
    await client.subscribe([(f"td2adaptor/{robot}/td", 1)])
    while True:
        message = await client.deliver_message(timeout_duration=10)
        if message.data:
            await client.disconnect()
            return bytes(message.data).decode("utf-8")


async def main(broker: str, robot: str) -> None:
    text = await fetch_td(broker, robot)
    emit("td", text)
    servient = Servient(hostname="127.0.0.1", catalogue_port=None)
    wot = await servient.start()
    thing = wot.consume(text)  # the TD exactly as published
    emit("consumed", {"title": thing.td.title, "actions": sorted(thing.td.actions), "events": sorted(thing.td.events)})
    events: list[object] = []
    values: list[object] = []
    thing.on_event("gotoRunFeedback").subscribe(lambda item: events.append(item.data))
    thing.on_property_change("poseMarker").subscribe(lambda item: values.append(item.data.value))
    await asyncio.sleep(1.0)  # its subscriptions connect in the background
    emit("subscribed", None)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and (len(events) < 2 or not values):
        await asyncio.sleep(0.1)
    emit("events", events)
    emit("values", values[:3])
    goal = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 1.0, "theta": 0.0}}]}, "correlationId": "wotpy-1"}
    try:
        result = await thing.invoke_action("gotoRun", goal, timeout=3)
        emit("invoked", result)
    except Exception as exc:  # noqa: BLE001 - reported to the test
        emit("invoke-failed", type(exc).__name__)
    await servient.shutdown()


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], sys.argv[2]))
