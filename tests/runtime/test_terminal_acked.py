"""A mission's ledger row is done only once the broker has its terminal event (engine/outbox.py): a node killed
or frozen after its MQTT client took the event but before the broker acknowledged it (the packet still in the
client's queue or socket) must leave the row `ending`, so that its next start, or the next owner of the robot,
sends the event again. Before, the row was done when the client had the packet, and the event was lost.

The moment is made without a mock: the broker process is stopped (SIGSTOP) while the event is published, so no
acknowledgement can come; continued, it acknowledges, and the row is done. Real mosquitto.
"""

from __future__ import annotations

import signal
import threading
import time
from pathlib import Path

from td2adaptor.model import Procedure
from td2adaptor.runtime import RuntimeConfig
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from td2adaptor.runtime.bus.thingbus import ThingBus
from td2adaptor.runtime.engine.ledger import Ledger
from td2adaptor.runtime.engine.missions import Mission, MissionTable
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.ros.procedures import ProcedureStatus
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import rb1_catalog

ROBOT = "acked_end"


def test_a_missions_row_is_done_only_once_the_broker_has_its_terminal_event(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    catalog = rb1_catalog()
    bus = MqttBus(parse_broker_url(broker.url), client_id="acked-end")
    ledger = Ledger(tmp_path / "ids.sqlite", keep=330)
    table = MissionTable()
    outbox = Outbox(ThingBus(bus, catalog, ROBOT), RuntimeConfig(robot=ROBOT), catalog, ledger, table)
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
    try:
        bus.connect()
        assert bus.flush(10.0)
        m = Mission("GoToComponent", "gotoRun", Procedure("gotoRun"), "c1", {}, time.monotonic())
        assert table.claim(m, threading.Event()) is None
        topic = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"
        m.key = ledger.open(
            event_id="c1", topic=topic, kind="procedure", component="GoToComponent", action="gotoRun", correlation="c1"
        )
        assert broker.proc is not None
        broker.proc.send_signal(signal.SIGSTOP)
        try:
            outbox.finish(m, ProcedureStatus("finished"))
            # no acknowledgement can come: the row is still to be sent again by whoever starts next
            left = ledger.pending()
            assert [(r.key, r.phase, r.state) for r in left] == [(m.key, "ending", "finished")], left
        finally:
            broker.proc.send_signal(signal.SIGCONT)
        assert until(lambda: not ledger.pending(), 20), ledger.pending()
        assert until(lambda: any(e.get("payload", {}).get("terminal") for _t, e in app.events), 10), app.events
    finally:
        app.close()
        bus.close()
        ledger.close()
        broker.stop()
