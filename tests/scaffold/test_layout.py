"""The source-independent steps on hand-made graphs: what is left out, names, components, procedures,
namespaces and fleets (the real graphs are in test_ros2 / test_ros1 / test_offline)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.model import MessageDef
from td2adaptor.model.msgschema import message_schema
from td2adaptor.rostypes.registry import TypeRegistry
from td2adaptor.scaffold import Options, scaffold
from td2adaptor.scaffold.graph import Endpoint, Filters, Graph, select
from td2adaptor.scaffold.writer import Schemas
from tests.scaffold.common import compiled_errors, w3c_errors

F64, TRIGGER = "std_msgs/msg/Float64", "std_srvs/srv/Trigger"


def topic(name: str, role: str = "publisher", node: str = "/robot/driver", type_: str = F64) -> Endpoint:
    return Endpoint("topic", name, type_, role, (node,))  # type: ignore[arg-type]


def service(name: str, type_: str = TRIGGER, node: str = "/robot/driver") -> Endpoint:
    return Endpoint("service", name, type_, "server", (node,))


def run(endpoints: list[Endpoint], **options: Any) -> tuple[dict[str, Any] | None, Diagnostics]:
    diags = Diagnostics()
    return scaffold(Graph("a test graph", endpoints), Options(**options), diags), diags


def names(doc: dict[str, Any] | None) -> dict[str, list[str]]:
    assert doc is not None
    return {s: list(doc.get(s, {})) for s in ("properties", "actions")}


def test_infrastructure_and_hidden_names_are_left_out_unless_kept() -> None:
    graph = Graph(
        "g",
        [
            topic("/rosout"),
            topic("/parameter_events"),
            topic("/tf_static"),
            topic("/robot/odom"),
            topic("/robot/fibonacci/_action/feedback"),
            service("/robot/driver/get_parameters"),
            service("/robot/driver/get_type_description"),
            service("/robot/driver/set_logger_level"),
            service("/robot/reset"),
        ],
    )
    kept = select(graph, Filters(), Diagnostics())
    assert [e.name for e in kept] == ["/robot/odom", "/robot/reset"]
    kept = select(graph, Filters(keep=("/tf_static",)), Diagnostics())
    assert [e.name for e in kept] == ["/robot/odom", "/robot/reset", "/tf_static"]


def test_filters_by_namespace_node_and_regex() -> None:
    graph = Graph("g", [topic("/a/x", node="/a/n1"), topic("/a/y", node="/a/n2"), topic("/b/x", node="/b/n1")])
    assert [e.name for e in select(graph, Filters(namespaces=("/a",)), Diagnostics())] == ["/a/x", "/a/y"]
    assert [e.name for e in select(graph, Filters(nodes=("/a/n2",)), Diagnostics())] == ["/a/y"]
    assert [e.name for e in select(graph, Filters(include=("x$",), exclude=("^/b",)), Diagnostics())] == ["/a/x"]


def test_a_name_with_two_types_keeps_the_first_and_says_so() -> None:
    diags = Diagnostics()
    graph = Graph("g", [topic("/r/x"), topic("/r/x", role="subscriber", type_="std_msgs/msg/Int32")])
    assert [e.type for e in select(graph, Filters(), diags)] == [F64]
    assert diags.codes() == ["SCF106"]


def test_names_grow_while_they_collide_and_keywords_get_a_suffix() -> None:
    doc, _ = run([topic("/robot/left/camera/image"), topic("/robot/right/camera/image"), topic("/robot/import")])
    assert names(doc)["properties"] == ["importValue", "leftCameraImage", "rightCameraImage"]


def test_run_query_cancel_services_are_a_procedure() -> None:
    trio = [service(f"/robot/dock/{leaf}") for leaf in ("run", "query", "cancel")]
    doc, _ = run([*trio, service("/robot/reset")])
    assert doc is not None
    assert names(doc)["actions"] == ["reset", "dockRun", "dockCancel", "dockQuery"]
    run_action = doc["actions"]["dockRun"]
    assert run_action["rosv:component"] == "DockComponent" == doc["actions"]["dockQuery"]["rosv:component"]
    # std_srvs/Trigger answers no mission id: no missionId is proposed
    assert run_action["rosv:procedure"] == {"query": "dockQuery", "cancel": "dockCancel"}
    assert (doc["actions"]["dockQuery"]["safe"], doc["actions"]["dockRun"]["safe"]) == (True, False)


def test_components_by_prefix_or_by_node() -> None:
    endpoints = [
        topic("/robot/camera/image", node="/robot/cam"),
        topic("/robot/camera/info", node="/robot/cam"),
        topic("/robot/odom", node="/robot/base"),
    ]
    doc, _ = run(endpoints)
    assert doc is not None
    components = {n: a["rosv:component"] for n, a in doc["properties"].items()}
    assert components == {"image": "CameraComponent", "info": "CameraComponent", "odom": "OdomComponent"}
    doc, _ = run(endpoints, group="node")
    assert doc is not None
    components = {n: a["rosv:component"] for n, a in doc["properties"].items()}
    assert components == {"image": "CamComponent", "info": "CamComponent", "odom": "BaseComponent"}


def test_a_topic_the_robot_publishes_and_reads_is_read_and_one_it_only_reads_is_written() -> None:
    doc, _ = run([topic("/robot/a"), topic("/robot/a", role="subscriber"), topic("/robot/cmd", role="subscriber")])
    assert doc is not None
    assert doc["properties"]["a"]["readOnly"] is True and doc["properties"]["cmd"]["writeOnly"] is True
    assert doc["properties"]["cmd"]["forms"][0]["rosv:role"] == "publisher"


def test_td2adaptor_s_own_nodes_are_left_out_and_said_unless_named() -> None:
    bridge = "/td2adaptor_edge_rb1_12345_1700000000000"  # the ROS 1 bridge's anonymous rospy node
    graph = Graph(
        "g",
        [
            topic("/robot/cmd", role="subscriber"),
            topic("/robot/cmd", node="/td2adaptor_edge_rb1"),  # an edge node publishes what the robot reads
            topic("/robot/odom", role="subscriber", node=bridge),  # and reads what the robot publishes
            topic("/robot/odom"),
            topic("/robot/cmd", node="/td2adaptor_edge_d3"),  # a fleet's node on a second domain
            topic("/robot/cmd", node="/td2adaptor_edgeless"),  # somebody else's node
        ],
    )
    diags = Diagnostics()
    kept = {(e.name, e.role): e.nodes for e in select(graph, Filters(), diags)}
    assert kept == {
        ("/robot/cmd", "subscriber"): ("/robot/driver",),
        ("/robot/cmd", "publisher"): ("/td2adaptor_edgeless",),
        ("/robot/odom", "publisher"): ("/robot/driver",),
    }
    assert diags.codes() == ["SCF115"]
    said = next(iter(diags)).message
    assert f"/td2adaptor_edge_d3, /td2adaptor_edge_rb1, {bridge}:" in said, said
    named = select(graph, Filters(nodes=("/td2adaptor_edge_rb1",)), diags)
    assert [(e.name, e.role) for e in named] == [("/robot/cmd", "publisher")]
    doc, _ = run(graph.endpoints[:4])
    assert doc is not None and doc["properties"]["cmd"]["writeOnly"] is True


def test_a_robot_namespace_becomes_the_placeholder_and_a_root_graph_stays_verbatim() -> None:
    doc, diags = run([topic("/rb/odom"), topic("/rb/scan"), topic("/door/cmd", role="subscriber")])
    assert doc is not None and doc["@type"] == "Thing"
    forms = {n: a["forms"][0] for n, a in doc["properties"].items()}
    assert forms["odom"]["rosv:name"] == "/{{robotName}}/odom" and forms["odom"]["href"] == "ros:odom"
    assert forms["cmd"]["rosv:name"] == "/door/cmd" and forms["cmd"]["href"] == "ros:/door/cmd"
    assert "SCF105" in diags.codes()
    doc, diags = run([topic("/odom"), topic("/scan")])
    assert doc is not None and doc["properties"]["odom"]["forms"][0]["rosv:name"] == "/odom"
    assert "SCF105" not in diags.codes()


def test_namespaces_with_the_same_interfaces_are_a_fleet_and_given_ones_that_differ_share_what_they_can() -> None:
    fleet = [topic(f"/{r}/{t}") for r in ("r1", "r2", "r3") for t in ("odom", "scan")]
    doc, _ = run(fleet)
    assert doc is not None and doc["@type"] == "tm:ThingModel" and "id" not in doc
    assert names(doc)["properties"] == ["odom", "scan"]
    doc, diags = run([*fleet, topic("/r1/extra")], robot_namespaces=("r1", "r2", "r3"))
    assert doc is not None and names(doc)["properties"] == ["odom", "scan"]
    assert "SCF104" in diags.codes()


def test_a_robot_namespace_of_several_segments_is_refused_not_silently_ignored() -> None:
    fleet = [topic(f"/fleet/{r}/{t}") for r in ("r1", "r2") for t in ("odom", "scan")]
    for given in (("fleet/r1", "fleet/r2"), ("/fleet/r1",), ("r1", "/fleet/r2/")):
        doc, diags = run(fleet, robot_namespaces=given)
        assert doc is None and diags.codes() == ["SCF112"], given
        assert "{{robotName}}" in diags.errors()[0].message
    # found, not given: the first segment is the robot namespace (one Thing, robotName = fleet)
    doc, diags = run(fleet)
    assert doc is not None and doc["@type"] == "Thing" and "SCF105" in diags.codes()
    assert doc["properties"]["r1Odom"]["forms"][0]["rosv:name"] == "/{{robotName}}/r1/odom"
    # one segment given: replaced
    doc, _ = run([topic(f"/{r}/{t}") for r in ("r1", "r2") for t in ("odom", "scan")], robot_namespaces=("/r1/",))
    assert doc is not None and doc["properties"]["odom"]["forms"][0]["rosv:name"] == "/{{robotName}}/odom"


def test_nothing_left_is_an_error() -> None:
    doc, diags = run([topic("/rosout")])
    assert doc is None and diags.codes() == ["SCF102"]


def test_two_procedures_with_the_same_last_segment_get_their_own_names_and_components() -> None:
    trios = [
        service(f"/robot/{arm}/Grip/{leaf}") for arm in ("left", "right") for leaf in ("add", "query_state", "cancel")
    ]
    doc, _ = run(trios)
    assert doc is not None
    actions = doc["actions"]
    assert sorted(actions) == sorted(["gripRun", "gripQuery", "gripCancel", "grip2Run", "grip2Query", "grip2Cancel"])
    assert {actions["gripRun"]["rosv:component"], actions["grip2Run"]["rosv:component"]} == {
        "GripComponent",
        "Grip2Component",
    }
    assert actions["grip2Run"]["rosv:procedure"] == {"query": "grip2Query", "cancel": "grip2Cancel"}


def test_td_style_leaves_the_contract_only_members_to_the_event_contract() -> None:
    from td2adaptor.scaffold.writer import td_style

    strict = {
        "type": "object",
        "properties": {
            "required": {"type": "boolean"},  # a field called so stays
            "pose": {"type": "object", "properties": {"x": {"type": "number"}}, "additionalProperties": False},
            "list": {"type": "array", "items": {"type": "object", "properties": {}, "required": []}},
        },
        "additionalProperties": False,
        "required": ["required", "pose"],
    }
    assert td_style(strict) == {
        "type": "object",
        "properties": {
            "required": {"type": "boolean"},
            "pose": {"type": "object", "properties": {"x": {"type": "number"}}},
            "list": {"type": "array", "items": {"type": "object", "properties": {}}},
        },
    }


def test_the_five_topics_of_an_actionlib_server_are_one_action_and_four_of_them_are_not() -> None:
    five = [
        topic("/r/move/goal", "subscriber", type_="nav_msgs/msg/MoveActionGoal"),
        topic("/r/move/cancel", "subscriber", type_="actionlib_msgs/msg/GoalID"),
        topic("/r/move/status", type_="actionlib_msgs/msg/GoalStatusArray"),
        topic("/r/move/feedback", type_="nav_msgs/msg/MoveActionFeedback"),
        topic("/r/move/result", type_="nav_msgs/msg/MoveActionResult"),
    ]
    folded = select(Graph("g", five), Filters(), Diagnostics())
    assert [(e.kind, e.name, e.type) for e in folded] == [("action", "/r/move", "nav_msgs/action/Move")]
    partial = select(Graph("g", five[:4]), Filters(), Diagnostics())
    assert [e.kind for e in partial] == ["topic"] * 4


def test_a_group_of_constants_named_after_a_field_becomes_its_enum(tmp_path: Path) -> None:
    doc, diags = run([topic("/robot/battery", type_="sensor_msgs/msg/BatteryState")])
    assert doc is not None and not diags.has_errors
    battery = doc["properties"]["battery"]["properties"]
    status = battery["power_supply_status"]
    assert status["enum"] == [0, 1, 2, 3, 4] and status["type"] == "integer"
    assert "POWER_SUPPLY_STATUS_CHARGING = 1" in status["description"]
    assert battery["power_supply_technology"]["enum"] == list(range(9))
    assert "enum" not in battery["voltage"] and "enum" not in battery["present"]
    assert compiled_errors(doc, tmp_path) == [] and w3c_errors(doc) == []
    # nested, in an array: action_msgs/GoalStatus.status and its STATUS_* constants
    schemas = Schemas([], Diagnostics())
    status_list = schemas.parts("action_msgs/msg/GoalStatusArray")[0]["properties"]["status_list"]  # type: ignore[index]
    assert status_list["items"]["properties"]["status"]["enum"] == [0, 1, 2, 3, 4, 5, 6]
    # constants not named after a field (Marker's ARROW, ADD, ... for `type` and `action`): no enum
    marker = schemas.parts("visualization_msgs/msg/Marker")[0]["properties"]  # type: ignore[index]
    assert not [name for name, sub in marker.items() if "enum" in sub]
    # the event contract's message schema is not narrowed
    table = TypeRegistry("ros2", [], Diagnostics()).table(["sensor_msgs/msg/BatteryState"])
    contract = message_schema(table.get("sensor_msgs/msg/BatteryState"), table)  # type: ignore[arg-type]
    assert "enum" not in contract["properties"]["power_supply_status"]


def test_the_enum_rule_wants_the_same_type_two_constants_and_takes_the_longest_prefix(tmp_path: Path) -> None:
    folder = tmp_path / "enum_test_msgs" / "msg"
    folder.mkdir(parents=True)
    (folder / "Modes.msg").write_text(
        "uint8 MODE_IDLE=0\nuint8 MODE_RUN=1\nuint8 MODE_LIMIT_LOW=2\nuint8 MODE_LIMIT_HIGH=9\n"
        "int32 LEVEL_A=1\nint32 LEVEL_B=2\nuint8 SOLO_ONE=1\nstring COLOUR_RED=red\nstring COLOUR_BLUE=blue\n"
        "uint8 mode\nuint8 mode_limit\nuint8 level\nuint8 solo\nstring colour\nuint8[] mode_list\n",
        encoding="utf-8",
    )
    parts = Schemas([tmp_path], Diagnostics()).parts("enum_test_msgs/msg/Modes")
    assert parts is not None
    props = parts[0]["properties"]
    assert props["mode"]["enum"] == [0, 1] and props["mode_limit"]["enum"] == [2, 9]
    assert props["colour"]["enum"] == ["red", "blue"] and "COLOUR_RED = 'red'" in props["colour"]["description"]
    assert "enum" not in props["level"]  # LEVEL_* are int32, the field uint8
    assert "enum" not in props["solo"]  # one constant is not a group (more likely a limit)
    assert "enum" not in props["mode_list"] and "enum" not in props["mode_list"]["items"]


def test_field_comments_of_interface_files_become_descriptions_and_units(tmp_path: Path) -> None:
    folder = tmp_path / "comment_test_msgs" / "msg"
    folder.mkdir(parents=True)
    text = (
        "# The message's own comment: no field's.\n"
        "float32 voltage  # Voltage in Volts\n"
        "\n"
        "# How fast it goes,\n"
        "# measured at the wheels.\n"
        "float64 speed  # [m/s]\n"
        "float32 charge  # %\n"
        "uint8 MODE_IDLE=0  # idle\n"
        "uint8 MODE_RUN=1\n"
        "# the mode\n"
        "uint8 mode\n"
        "float32 temperature  # in degrees Celsius\n"
        "float64[2] velocity  # linear [m/s], angular [rad/s]\n"
        "float32 current  # in amperes, at most 3 [A]\n"
        "uint8 LIGHT_OFF=0\n"
        "uint8 LIGHT_ON=1\n"
        "uint8 light  # the lamp:\n"
        "string name\n"
        "Inner inner  # the nested part\n"
    )
    (folder / "Commented.msg").write_text(text, encoding="utf-8")
    (folder / "Inner.msg").write_text("int32 count  # how many; not a unit\n", encoding="utf-8")
    schemas = Schemas([tmp_path], Diagnostics())
    parts = schemas.parts("comment_test_msgs/msg/Commented")
    assert parts is not None
    props = parts[0]["properties"]
    assert props["voltage"]["description"] == "Voltage in Volts" and props["voltage"]["unit"] == "V"
    speed = props["speed"]
    assert speed["description"] == "How fast it goes, measured at the wheels. [m/s]" and speed["unit"] == "m/s"
    assert props["charge"] == {"type": "number", "unit": "%"}  # a comment that only names the unit
    # a comment that ends no sentence is one before the constants
    assert props["mode"]["description"].startswith("the mode. One of the message's constants: MODE_IDLE = 0")
    assert props["light"]["description"] == "the lamp. One of the message's constants: LIGHT_OFF = 0, LIGHT_ON = 1."
    assert props["temperature"]["unit"] == "°C"
    # two units in one comment: no one unit is the field's (not the first one for the whole field)
    assert props["velocity"]["description"] == "linear [m/s], angular [rad/s]" and "unit" not in props["velocity"]
    assert props["current"]["unit"] == "A"  # the same unit named twice is the one unit
    assert "description" not in props["name"] and "unit" not in props["name"]
    inner = props["inner"]
    assert inner["description"] == "the nested part"
    assert inner["properties"]["count"] == {
        "type": "integer", "minimum": -(2**31), "maximum": 2**31 - 1, "description": "how many; not a unit",
    }  # fmt: skip
    # a comment is text only: the definition (equality, hash, ROS 1 md5) is the one without comments
    registry = TypeRegistry("ros1", [tmp_path], Diagnostics())
    plain = tmp_path / "plain"
    (plain / "comment_test_msgs" / "msg").mkdir(parents=True)
    for name, body in (("Commented", text), ("Inner", "int32 count\n")):
        lines = [line.split("#")[0].rstrip() for line in body.splitlines() if line.split("#")[0].strip()]
        (plain / "comment_test_msgs" / "msg" / f"{name}.msg").write_text("\n".join(lines) + "\n", encoding="utf-8")
    bare = TypeRegistry("ros1", [plain], Diagnostics())
    name = "comment_test_msgs/msg/Commented"
    commented = registry.table([name]).get(name)
    assert isinstance(commented, MessageDef) and commented == bare.table([name]).get(name)
    assert [f.comment for f in commented.fields][:2] == [
        "Voltage in Volts",
        "How fast it goes, measured at the wheels. [m/s]",
    ]
    assert registry.ros1_definition(name)[1] == bare.ros1_definition(name)[1]
    # the built-in type sets (rosbags' stores) carry no comments
    battery = schemas.parts("sensor_msgs/msg/BatteryState")
    assert battery is not None and "description" not in battery[0]["properties"]["voltage"]


def test_a_recording_s_definitions_fill_only_the_gaps_and_never_fail() -> None:
    from td2adaptor.scaffold.bag import definitions

    text = (
        "# the probe's reading\nHeader header\nReading[<=4] readings  # at most four\n"
        + "=" * 80
        + "\nMSG: probe_msgs/Reading\nfloat64 volts  # Voltage in Volts\n"
        + "=" * 80
        + "\nMSG: std_msgs/Float64\nstring data\n"  # a different Float64: the store's wins
        + "=" * 80
        + "\nMSG: probe_msgs/Broken\nNowhere missing\n"
    )
    recorded = {name: (f"bag:{name}", body) for name, body in definitions("probe_msgs/msg/Probe", text).items()}
    assert sorted(recorded) == ["probe_msgs/msg/Broken", "probe_msgs/msg/Probe", "probe_msgs/msg/Reading", F64]
    diags = Diagnostics()
    schemas = Schemas([], diags, recorded)
    (probe,) = schemas.parts("probe_msgs/msg/Probe") or []
    readings = probe["properties"]["readings"]
    assert readings["maxItems"] == 4 and readings["items"]["properties"]["volts"]["type"] == "number"
    assert "Volts" in readings["items"]["properties"]["volts"].get("description", "")
    assert schemas.parts(F64) == [{"type": "object", "properties": {"data": {"type": "number"}}}]
    assert schemas.parts("probe_msgs/msg/Broken") is None  # uses a type nobody defines: left out quietly
    assert list(diags) == [], [str(d) for d in diags]
    # the ROS 1 registry cannot take a bounded sequence: Probe is left out there, without a diagnostic
    ros1 = TypeRegistry("ros1", [], diags, recorded)
    assert ros1.resolve("probe_msgs/msg/Reading") is not None and ros1.resolve("probe_msgs/msg/Probe") is None
    assert list(diags) == []


def test_without_the_w3c_schema_only_that_check_is_skipped(monkeypatch: Any) -> None:
    import pytest

    from tests import wot_corpus
    from tests.scaffold.common import W3CSchemaMissing

    def missing(name: str) -> Any:
        pytest.skip(f"needs ../shared/wot/official/{name} (test)")

    monkeypatch.setattr(wot_corpus, "official_json", missing)
    with pytest.warns(W3CSchemaMissing, match="td-schema-v1.1.json"):
        assert w3c_errors({"@type": "Thing"}) == []  # the test goes on: its other assertions still run
