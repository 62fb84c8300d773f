"""A member of a shared fleet that rejoins (its record cleared by its will, then published again: a process that
hung longer than its member connection's keepalive and resumed) gets a `timeout` of grace for its first beat
again, as at its first join (issue 32, node/share.py `Share._on_member`). It kept the beat time it had before it
left, so the others took it as gone right after "joined" ("sent no beat for 3 s: taken as gone", logged in
test_fleet_share_resume.py's runs) until its next beat, delaying the hand-back by up to `timeout` / 4.

The share's own handlers are given the messages its member connection would deliver (the records and beats of
another member); `timeout` is 0.2 s, so that a beat from before the other member left is stale by then.
"""

from __future__ import annotations

import time

import orjson
import pytest

from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from td2adaptor.runtime.node.fleet import Fleet
from td2adaptor.runtime.node.roslink import RosLink
from td2adaptor.runtime.node.share import Share
from td2adaptor.runtime.node.shareplan import beats_topic, members_topic
from tests.runtime.rb1 import rb1_model

TIMEOUT = 0.2
OTHER = "other-member"


def test_a_member_that_rejoins_gets_a_timeout_of_grace_for_its_first_beat_again(
    caplog: pytest.LogCaptureFixture,
) -> None:
    bus = MqttBus.sessionless(parse_broker_url("mqtt://127.0.0.1:1"), None, "member-test")  # never connected
    share = Share(Fleet(rb1_model(), RosLink(), distro="ros2"), bus, name="shared", root="td2adaptor", timeout=TIMEOUT)
    record = orjson.dumps({"owner": {"host": "h", "pid": 1, "started": "2026-01-01T00:00:00Z", "node": OTHER}})
    member = members_topic("td2adaptor", "shared", OTHER)

    def live() -> set[str]:
        with share._lock:
            share._beat_at = time.monotonic()  # this process beats meanwhile (its beat thread's mark)
            return share._live()

    share._on_member(Message(member, record, True))
    share._on_beat(Message(beats_topic("td2adaptor", "shared", OTHER), b"{}"))
    assert OTHER in live()
    time.sleep(TIMEOUT * 1.5)  # silent for longer than the timeout: taken as gone
    assert OTHER not in live()
    share._on_member(Message(member, b"", True))  # its will cleared its record
    share._on_member(Message(member, record, True))  # back: its record again, its first beat still to come
    caplog.clear()
    assert OTHER in live(), caplog.text
    assert "taken as gone" not in caplog.text
