"""A process of a shared fleet that lost a robot's session puts back the other owner's admitted entry that its own
overwrote (node/admitted.py `Recorder.withdraw`), also when its member connection was down meanwhile: a hung
process's is dropped by the broker's keepalive, so it never heard the new owner's entries, and its own entry
(queued while it was down) reaches the broker on the next connection, after the new owner's. Withdrawn at that
moment, it knew nothing to put back, and its own entry (admitted, never run, no state) stayed on the broker for
the whole freshness window (the resumed-process test's `None` entry): the next owner would have taken the command
as in flight and ended it a second time. Real mosquitto (stopped and started again on its port, with
persistence, to take the member connection down), real MqttBus connections.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import orjson

from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from td2adaptor.runtime.node.admitted import Book, Recorder, admitted_topic, entry_key
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import until
from tests.runtime.test_fleet_share import retained

ROOT, FLEET, ROBOT = "td2adaptor", "shared", "rb_00"
EVENT_ID, TOPIC = "e-1", "td2adaptor/rb_00/MathComponent/fibonacci"


def test_an_entry_overwritten_while_the_member_connection_was_down_is_put_back_once_the_broker_echoes_it(
    tmp_path: Path,
) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    member = MqttBus(parse_broker_url(broker.url), client_id="member-a", clean_start=True, session_expiry=0)
    other = MqttBus(parse_broker_url(broker.url), client_id="member-b")
    book = Book()
    heard: list[dict[str, Any]] = []  # what this process's book was told, in order
    seen = threading.Condition()

    def take(message: Message) -> None:
        book.take(message)
        with seen:
            heard.append(orjson.loads(message.payload) if message.payload else {})
            seen.notify_all()

    topic = admitted_topic(ROOT, FLEET, ROBOT, entry_key(EVENT_ID, TOPIC))
    ended = {"id": EVENT_ID, "topic": TOPIC, "owner": "b", "state": "finished", "phase": "done", "at": 1.0}
    try:
        member.connect()
        # the new owner admitted and finished the command while this process hung: it heard nothing of it (here
        # it follows no entries yet; in the hung process the broker had dropped its member connection)
        other.connect()
        other.publish(topic, orjson.dumps(ended), retain=True)
        assert other.flush(10)
        other.close()  # (its connection would publish its retained entries again on the next one)
        broker.stop()  # the member connection is down (the broker keeps the retained entry: persistence)
        assert until(lambda: not member.connected, 10)
        member.subscribe(admitted_topic(ROOT, FLEET), take)  # made on the next connection, as after a drop
        recorder = Recorder(member, ROOT, FLEET, ROBOT, "a", 330.0, book)
        # on SIGCONT the hung process reads the command from the robot's socket and admits it: its entry is queued
        recorder.checked(EVENT_ID, TOPIC, None, "digest")
        recorder.opened("k1", {"event_id": EVENT_ID, "topic": TOPIC, "kind": "goal"})
        recorder.withdraw()  # then finds the robot's session taken (share.py: its engine halted)
        broker.start()
        # the member connection comes back: the broker sends the retained entry, then takes the queued one
        with seen:
            assert seen.wait_for(lambda: [e.get("owner") for e in heard][:2] == ["b", "a"], 30), heard
        assert until(lambda: (retained(broker, topic).get(topic) or {}).get("owner") == "b", 10), retained(
            broker, topic
        )
        assert member.flush(10)
        assert retained(broker, topic)[topic] == ended, retained(broker, topic)
    finally:
        member.close()
        other.close()
        broker.stop()
