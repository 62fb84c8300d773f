"""rospy backend benchmarks (issue 3). Every figure is printed next to a baseline measured in the same run.

* `call_X` round trip of the generated package vs a hand-written minimal rospy client making the same call to
  the same simulated RB-1 (target ratio <= 1.05). The minimal client is `rospy.ServiceProxy(name, type)`
  called with the request (rospy's default: a new connection per call); a hand-written persistent proxy
  (`persistent=True`, no timeout handling) is shown too, as the tightest baseline.
* `construct_X_Msg` vs building the same request directly with the genpy classes (target <= 1.2x, issues 3
  and 17; from a mapping, the nested form, no target).

Needs Debian's ROS 1 (`SUDO= bash .ci/setup-ros1.sh`). Run: `.venv/bin/python bench/backend_rospy.py`.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
import td2adaptor  # noqa: E402
from td2adaptor.backends.rospy import generator as backend  # noqa: E402
from td2adaptor.diagnostics import Diagnostics  # noqa: E402
from td2adaptor.generation.backend import GenOptions  # noqa: E402
from tests.ros1 import harness  # noqa: E402

EXAMPLE = REPO / "examples" / "robotnik_rb1"
PKG = "robotnik_rb_1_adaptor"

CLIENT = r"""
import statistics, timeit
import genpy
from procedures_msgs.msg import ProcedureHeader
from procedures_msgs.srv import ProcedureQuery, ProcedureQueryRequest
from robot_local_control_msgs.msg import GoTo, Pose2DStamped
from robot_local_control_msgs.srv import GoToPetitionRequest
from geometry_msgs.msg import Pose2D
from std_msgs.msg import Header
from robotnik_rb_1_adaptor import GoToComponent

ns = "rb1_bench"
goto = GoToComponent(ns)
goto.register()
started = goto.call_gotoRun(goto.construct_gotoRun_Msg(procedure={"goals": [{"pose": {"x": 1.0}}]}))
request = ProcedureQueryRequest(header=ProcedureHeader(id=started.mission_id))
name = f"/{ns}/robot_local_control/NavigationComponent/GoToComponent/query_state"
minimal = rospy.ServiceProxy(name, ProcedureQuery)
persistent = rospy.ServiceProxy(name, ProcedureQuery, persistent=True)
variants = {
    "generated": lambda: goto.call_gotoQuery(request),
    "minimal": lambda: minimal(request),
    "persistent": lambda: persistent(request),
}
for f in variants.values():  # warm up: connections made, caches filled
    for _ in range(50):
        f()
times = {k: [] for k in variants}
for _ in range(ROUNDS):
    for key, f in variants.items():  # interleaved, so drift hits every variant alike
        for _ in range(BLOCK):
            t0 = time.perf_counter()
            f()
            times[key].append(time.perf_counter() - t0)
calls = {k: statistics.median(v) for k, v in times.items()}

header = ProcedureHeader(id=4, priority=0, stamp=genpy.Time(1, 2), name="GoToComponent")
goal = GoTo(goals=[Pose2DStamped(header=Header(frame_id="map"), pose=Pose2D(x=1.0, y=2.0, theta=0.5))])
pairs = {
    "query_msg": (lambda: goto.construct_gotoQuery_Msg(header=header), lambda: ProcedureQueryRequest(header=header)),
    "run_msg": (lambda: goto.construct_gotoRun_Msg(procedure=goal), lambda: GoToPetitionRequest(procedure=goal)),
    "run_mapping": (
        lambda: goto.construct_gotoRun_Msg(
            procedure={"goals": [{"header": {"frame_id": "map"}, "pose": {"x": 1.0, "y": 2.0, "theta": 0.5}}]}
        ),
        lambda: GoToPetitionRequest(
            procedure=GoTo(goals=[Pose2DStamped(header=Header(frame_id="map"), pose=Pose2D(x=1.0, y=2.0, theta=0.5))])
        ),
    ),
}
construct = {}
for key, (ours, direct) in pairs.items():
    a, b = [], []
    for _ in range(21):  # interleaved, so that load from other processes hits both alike; best of each
        a.append(timeit.timeit(ours, number=5000) / 5000)
        b.append(timeit.timeit(direct, number=5000) / 5000)
    construct[key] = [min(a), min(b)]
emit({"calls": calls, "construct": construct, "n": ROUNDS * BLOCK})
"""


def row(name: str, value: float, baseline_name: str, baseline: float, target: str) -> None:
    print(
        f"{name:<46} {value * 1e6:9.1f} us   {baseline_name:<34} {baseline * 1e6:9.1f} us"
        f"   ratio {value / baseline:5.2f}   target {target}"
    )


def main() -> int:
    problem = harness.ros1_problem()
    if problem:
        print(f"rospy benchmarks skipped: {problem}")
        return 0
    result = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None
    tree = backend.generate(result.model, GenOptions(), Diagnostics())
    with tempfile.TemporaryDirectory(prefix="td2adaptor-bench-rospy-") as tmp:
        root = Path(tmp)
        for rel, data in tree:
            (root / "pkg" / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / "pkg" / rel).write_bytes(data)
        interfaces = harness.interfaces_dir()
        path = [interfaces, root / "pkg" / PKG / "src"]
        with (
            harness.rosmaster(root / "home") as master,
            harness.run_sim(master, interfaces, "rb1_bench", "--duration", "60"),
        ):
            code = CLIENT.replace("ROUNDS", "20").replace("BLOCK", "100")
            out = harness.run_client(master, path, code, timeout=300)
    version = subprocess.run([harness.SYSTEM_PYTHON, "-V"], capture_output=True, text=True).stdout.split()[-1]
    print(f"rospy backend, Debian python {version}, {out['n']} calls each (medians)")
    calls = out["calls"]
    row(
        "call_gotoQuery round trip (generated)",
        calls["generated"],
        "minimal client (ServiceProxy)",
        calls["minimal"],
        "<= 1.05x",
    )
    row(
        "call_gotoQuery round trip (generated)",
        calls["generated"],
        "hand-written persistent proxy",
        calls["persistent"],
        "(tightest)",
    )
    names = {
        "query_msg": ("construct_gotoQuery_Msg(header=msg)", "ProcedureQueryRequest(header=msg)"),
        "run_msg": ("construct_gotoRun_Msg(procedure=msg)", "GoToPetitionRequest(procedure=msg)"),
        "run_mapping": ("construct_gotoRun_Msg(procedure=dict)", "GoToPetitionRequest(GoTo(...)) nested"),
    }
    for key, (ours, direct) in out["construct"].items():
        row(names[key][0], ours, names[key][1], direct, "<= 1.2x (issue 17)" if key != "run_mapping" else "(mappings)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
