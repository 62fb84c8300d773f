"""What a shared robot's recorder (node/admitted.py) keeps while it serves: the time and digest of each new id
wait for their invoke's entry, and the ids that never get one (queries, cancels, writes) are not kept for ever."""

from __future__ import annotations

import orjson

from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.localbus import LocalBroker, LocalBus
from td2adaptor.runtime.node.admitted import CHECKED_KEPT, Recorder, admitted_topic
from tests.runtime.edge import until


def test_the_ids_of_commands_that_open_no_entry_are_not_kept_for_ever() -> None:
    broker = LocalBroker()
    app = LocalBus(broker, "app")
    seen: list[Message] = []
    app.subscribe(admitted_topic("td2adaptor", "shared"), seen.append)
    app.connect()
    bus = LocalBus(broker, "member")
    bus.connect()
    recorder = Recorder(bus, "td2adaptor", "shared", "rb_00", "node-a", 30.0)
    query = "td2adaptor/rb_00/GoToComponent/gotoQuery"
    for n in range(20 * CHECKED_KEPT):  # a robot asked about its mission 5,120 times: every query a new id
        recorder.checked(f"q{n}", query, "2026-11-28T06:00:00Z", f"digest-{n}")
    assert len(recorder._checked) <= CHECKED_KEPT  # was one per query for as long as the robot was served
    invoke = "td2adaptor/rb_00/GoToComponent/gotoRun"
    recorder.checked("i1", invoke, "2026-11-28T06:00:01Z", "digest-i1")
    recorder.opened("key-i1", {"event_id": "i1", "topic": invoke, "kind": "procedure", "action": "gotoRun"})
    assert until(lambda: bool(seen), 5)
    entry = orjson.loads(seen[-1].payload)
    assert (entry["id"], entry["sent"], entry["digest"]) == ("i1", "2026-11-28T06:00:01Z", "digest-i1")
    bus.close()
    app.close()
