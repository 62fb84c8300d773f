"""Connecting `GeneratedPort`s to a ROS graph: the rclpy node and its spinner, or rospy's node, or the bridge.

`connect(...)` returns a `RosLink`: one port per robot configuration and the way to close everything again.

* ROS 2: one rclpy context and node per ROS domain id among the robots (usually one), spun in the
  background by the generated package's own `spin_in_background`; every robot's components live on it.
* ROS 1 in this interpreter (rospy importable): `rospy.init_node` once (rospy allows one node per process),
  so every robot must use the same master.
* ROS 1 from another interpreter (`ros1_python`, or rospy not importable here): the ports run in a bridge
  process under that interpreter (`td2adaptor.runtime.ros.bridge`), one per ROS master.

The generated package must be importable: from an installed/sourced workspace, or by `package_paths`
(directories put on `sys.path`, e.g. the generated source) and `prefixes` (ROS 2 install prefixes whose
Python packages and libraries are loaded into this process, e.g. built interfaces or a colcon install space).
"""

from __future__ import annotations

import ctypes
import functools
import importlib
import importlib.util
import itertools
import os
import re
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from td2adaptor.model import Model
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.ros.fastdds import apply_edge_profile
from td2adaptor.runtime.ros.genport import GeneratedPort, Layout
from td2adaptor.runtime.ros.port import PortError, RobotPort, RosSetupError
from td2adaptor.runtime.ros.words import import_failure

PY_DIR = f"python{sys.version_info.major}.{sys.version_info.minor}"
_loaded_prefixes: set[Path] = set()


@dataclass
class RosLink:
    """Ports onto the ROS graph, by robot id, and what closes them: the ports first, then `closers` in reverse
    order of opening. `grow` connects more robots while this link is open (a robot that joins the fleet at run
    time): a link of their own, closed before this one, on the same ROS graph (ROS 2: a new rclpy node in this
    link's context, since a spinning executor cannot take new clients; rospy: the same node; the ROS 1 bridge:
    a bridge process of their own). `graph(domain)`: an rclpy node of that domain that is not spun, for reading
    the ROS 2 graph (discovery); None on ROS 1."""

    ports: dict[str, RobotPort] = field(default_factory=dict)
    closers: list[Callable[[], None]] = field(default_factory=list)
    description: str = ""
    grow: Callable[[Sequence[RuntimeConfig]], RosLink] | None = None
    graph: Callable[[int | None], Any] | None = None

    def release(self, robot: str) -> None:
        """Close one robot's port (the robot left the fleet); the link goes on for the others."""
        port = self.ports.pop(robot, None)
        close = getattr(port, "close", None)
        if callable(close):
            try:
                close()
            except Exception:  # noqa: BLE001 - the robot is leaving either way
                pass

    def close(self) -> None:
        """Close every port, stop spinning, leave the ROS graph; errors are swallowed (we are leaving)."""
        for robot in list(self.ports):
            self.release(robot)
        closers, self.closers = self.closers, []
        for closer in reversed(closers):
            try:
                closer()
            except Exception:  # noqa: BLE001 - shutting down: keep closing the rest
                pass


def load_prefix(prefix: Path) -> None:
    """Make a ROS 2 install prefix usable in this process: its Python packages and shared libraries.

    rosidl loads typesupport libraries by bare name, which only LD_LIBRARY_PATH at start-up or an already
    loaded library satisfies; every library is preloaded with RTLD_GLOBAL, in dependency order found by
    retrying what failed.
    """
    prefix = prefix.resolve()
    if prefix in _loaded_prefixes:
        return
    if not prefix.is_dir():
        raise RosSetupError(f"install prefix {prefix} does not exist")
    pending = sorted((prefix / "lib").glob("lib*.so"))
    while pending:
        failed: list[Path] = []
        for lib in pending:
            try:
                ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            except OSError:
                failed.append(lib)
        if len(failed) == len(pending):
            raise RosSetupError(f"cannot load the libraries of {prefix}: {', '.join(p.name for p in failed)}")
        pending = failed
    site = prefix / "lib" / PY_DIR / "site-packages"
    if site.is_dir() and str(site) not in sys.path:
        sys.path.insert(0, str(site))
    _loaded_prefixes.add(prefix)


def add_paths(paths: Sequence[Path]) -> None:
    """Put directories at the front of `sys.path` (in the given order)."""
    for path in reversed([str(Path(p).resolve()) for p in paths]):
        if path not in sys.path:
            sys.path.insert(0, path)


def import_package(name: str) -> ModuleType:
    """The generated adaptor package, or a `RosSetupError` that says how to make it importable."""
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        raise RosSetupError(import_failure(name, exc)) from None


def make_port(
    model: Model | Layout, module: ModuleType, config: RuntimeConfig, distro: str, node: Any = None
) -> GeneratedPort:
    """The `GeneratedPort` of one robot; a namespace the package refuses is a `RosSetupError`."""
    try:
        return GeneratedPort(
            model,
            module,
            config.ros_namespace,
            distro=distro,
            node=node,
            timeout=config.call_timeout,
            wait_timeout=config.call_timeout,
            feedback_grace=config.goal_feedback_grace,
            server_timeout=config.action_server_timeout,
        )
    except ValueError as exc:  # InvalidRobotName of the generated package
        raise RosSetupError(f"robot {config.robot}: {exc}") from None
    except PortError as exc:
        raise RosSetupError(f"robot {config.robot}: {exc}") from None


def node_name(configs: Sequence[RuntimeConfig]) -> str:
    """A ROS node name for the edge node of these robots (letters, digits, '_')."""
    base = f"td2adaptor_edge_{configs[0].robot}" if len(configs) == 1 else "td2adaptor_edge"
    return re.sub(r"[^A-Za-z0-9_]", "_", base)


def _groups(configs: Sequence[RuntimeConfig], key: Callable[[RuntimeConfig], Any]) -> dict[Any, list[RuntimeConfig]]:
    out: dict[Any, list[RuntimeConfig]] = {}
    for config in configs:
        out.setdefault(key(config), []).append(config)
    return out


def connect_ros2(model: Model, package: str, configs: Sequence[RuntimeConfig], *, name: str | None = None) -> RosLink:
    """Ports for `configs` on ROS 2: one rclpy context and node per domain id, spun in the background."""
    if importlib.util.find_spec("rclpy") is None:
        raise RosSetupError(
            "ROS 2 (rclpy) is not importable: source your ROS 2 setup, or install the ros2 extra "
            "(pip install 'td2adaptor[ros2]')"
        )
    module = import_package(package)
    spin = getattr(module, "spin_in_background", None)
    if not callable(spin):
        raise RosSetupError(f"{package} is not an rclpy adaptor generated by td2adaptor (no spin_in_background)")
    apply_edge_profile()  # before rclpy makes this process's first participant: Fast DDS reads it then
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    link = RosLink(description=f"ROS 2, package {package}")
    # the model's layout once for every port, not once per robot: its hashes took 40 ms of CPU per robot at idle,
    # two thirds of a robot's ROS side (issue 32: the robots that join must be served within 2 s)
    layout = Layout.of(model)
    contexts: dict[int | None, Any] = {}  # one rclpy context per domain id, the link's to shut down
    graph_nodes: dict[int | None, Any] = {}
    making = threading.Lock()  # a shared fleet grows the link from several threads at once (share.py `_begin`)

    def context_of(domain: int | None) -> Any:
        with making:
            if domain not in contexts:
                context = Context()
                rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
                link.closers.append(functools.partial(rclpy.shutdown, context=context))
                contexts[domain] = context
            return contexts[domain]

    def attach(into: RosLink, members: Sequence[RuntimeConfig], node_name: str) -> None:
        """One rclpy node for `members` in their domain's context, their ports on it, then spun."""
        context = context_of(members[0].ros_domain_id)
        # a joiner's node (into a grown link) serves no parameters: one node per joining batch, less graph noise
        node: Any = rclpy.create_node(node_name, context=context, start_parameter_services=into is link)
        into.closers.append(node.destroy_node)
        # every client and subscription is created before the node spins: an EventsExecutor cannot take new
        # ones while it spins (rclpy 7.1 blocks), and a SingleThreadedExecutor rebuilds its wait set
        for config in members:
            into.ports[config.robot] = make_port(layout, module, config, "ros2", node)
        into.closers.append(spin(node).stop)  # stopped after the ports closed (RosLink.close)

    grown = itertools.count(1)

    def grow(more: Sequence[RuntimeConfig]) -> RosLink:
        extra = RosLink(description=link.description)
        try:
            for members in _groups(more, lambda c: c.ros_domain_id).values():
                attach(extra, members, f"{name or node_name(members)}_{next(grown)}")
        except BaseException:
            extra.close()
            raise
        return extra

    def graph(domain: int | None) -> Any:
        if domain not in graph_nodes:
            node = rclpy.create_node(
                f"{name or 'td2adaptor_edge'}_graph", context=context_of(domain), start_parameter_services=False
            )
            link.closers.append(node.destroy_node)
            graph_nodes[domain] = node
        return graph_nodes[domain]

    link.grow, link.graph = grow, graph
    try:
        for domain, members in _groups(configs, lambda c: c.ros_domain_id).items():
            suffix = f"_d{domain}" if domain is not None and len(configs) > len(members) else ""
            attach(link, members, (name or node_name(members)) + suffix)
    except BaseException:
        link.close()
        raise
    return link


def connect_ros1(
    model: Model,
    package: str,
    configs: Sequence[RuntimeConfig],
    *,
    name: str | None = None,
    python: str | None = None,
    pythonpath: Sequence[Path] = (),
    environ: Mapping[str, str] | None = None,
) -> RosLink:
    """Ports for `configs` on ROS 1: rospy in this process, or a bridge under `python` per master."""
    environ = os.environ if environ is None else environ
    if python is None and importlib.util.find_spec("rospy") is not None:
        return _connect_rospy(model, package, configs, name=name)
    from td2adaptor.runtime.ros.bridge import Ros1Bridge, default_python

    interpreter = python or default_python()
    if interpreter is None:
        raise RosSetupError(
            "ROS 1 (rospy) is not importable here and no ROS 1 interpreter was found: give --ros1-python PATH "
            "(the Python that has rospy, e.g. /usr/bin/python3) or set TD2ADAPTOR_ROS1_PYTHON"
        )
    link = RosLink(description=f"ROS 1 (a bridge under {interpreter}), package {package}")
    layout = Layout.of(model)

    def attach(into: RosLink, members: Sequence[RuntimeConfig], suffix: str) -> None:
        """A bridge process for `members` (one ROS master), their ports on it."""
        bridge = Ros1Bridge(
            layout,
            package,
            [(c.robot, c.ros_namespace) for c in members],
            python=interpreter,
            pythonpath=pythonpath,
            master_uri=members[0].ros_master_uri or environ.get("ROS_MASTER_URI"),
            node_name=(name or node_name(members)) + suffix,
            timeout=max(c.call_timeout for c in members),
            feedback_grace={c.robot: c.goal_feedback_grace for c in members},
            environ=environ,
        )
        bridge.start()
        into.closers.append(bridge.close)
        for config in members:
            into.ports[config.robot] = bridge.port(config.robot)

    grown = itertools.count(1)

    def grow(more: Sequence[RuntimeConfig]) -> RosLink:
        """A bridge of their own: a bridge's robots are fixed when it starts (and a ROS 1 node name is unique
        on its master, so it gets a numbered one)."""
        extra = RosLink(description=link.description)
        try:
            for members in _groups(more, lambda c: c.ros_master_uri).values():
                attach(extra, members, f"_{next(grown)}")
        except BaseException:
            extra.close()
            raise
        return extra

    link.grow = grow
    try:
        for members in _groups(configs, lambda c: c.ros_master_uri).values():
            attach(link, members, "")
    except BaseException:
        link.close()
        raise
    return link


def _connect_rospy(model: Model, package: str, configs: Sequence[RuntimeConfig], *, name: str | None) -> RosLink:
    masters = {c.ros_master_uri for c in configs if c.ros_master_uri}
    if len(masters) > 1:
        raise RosSetupError(
            f"rospy allows one master per process, the robots name {len(masters)}: run one process per master "
            "or use the bridge (--ros1-python)"
        )
    if masters:
        os.environ["ROS_MASTER_URI"] = next(iter(masters))
    module = import_package(package)
    rospy: Any = importlib.import_module("rospy")
    link = RosLink(description=f"ROS 1 (rospy), package {package}")
    layout = Layout.of(model)  # once for every port (connect_ros2)
    rospy.init_node(name or node_name(configs), disable_signals=True)
    link.closers.append(lambda: rospy.signal_shutdown("td2adaptor edge node stopped"))

    def grow(more: Sequence[RuntimeConfig]) -> RosLink:
        """Their ports on the process's one rospy node (rospy takes new clients at any time)."""
        if len({c.ros_master_uri for c in more if c.ros_master_uri} | masters) > 1:
            raise RosSetupError("rospy allows one master per process: a robot of another master needs its own")
        extra = RosLink(description=link.description)
        try:
            for config in more:
                extra.ports[config.robot] = make_port(layout, module, config, "ros1")
        except BaseException:
            extra.close()
            raise
        return extra

    link.grow = grow
    try:
        for config in configs:
            link.ports[config.robot] = make_port(layout, module, config, "ros1")
    except BaseException:
        link.close()
        raise
    return link


def connect(
    model: Model,
    package: str,
    configs: Sequence[RuntimeConfig],
    *,
    ros: int = 2,
    package_paths: Sequence[Path] = (),
    prefixes: Sequence[Path] = (),
    ros1_python: str | None = None,
    name: str | None = None,
) -> RosLink:
    """Ports for every robot of `configs` through the generated package `package` (see the module docstring)."""
    if ros not in (1, 2):
        raise RosSetupError(f"ROS version must be 1 or 2, not {ros}")
    if ros == 2:
        for prefix in prefixes:
            load_prefix(Path(prefix))
        add_paths(package_paths)
        return connect_ros2(model, package, configs, name=name)
    if ros1_python is None:
        add_paths(package_paths)
    return connect_ros1(model, package, configs, name=name, python=ros1_python, pythonpath=package_paths)
