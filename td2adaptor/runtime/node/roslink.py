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
import os
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from td2adaptor.model import Model
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.ros.genport import GeneratedPort, Layout
from td2adaptor.runtime.ros.port import PortError, RobotPort, RosSetupError
from td2adaptor.runtime.ros.words import import_failure

PY_DIR = f"python{sys.version_info.major}.{sys.version_info.minor}"
_loaded_prefixes: set[Path] = set()


@dataclass
class RosLink:
    """Ports onto the ROS graph, by robot id, and what closes them (in reverse order of opening)."""

    ports: dict[str, RobotPort] = field(default_factory=dict)
    closers: list[Callable[[], None]] = field(default_factory=list)
    description: str = ""

    def close(self) -> None:
        """Close every port, stop spinning, leave the ROS graph; errors are swallowed (we are leaving)."""
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
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    link = RosLink(description=f"ROS 2, package {package}")
    try:
        for domain, members in _groups(configs, lambda c: c.ros_domain_id).items():
            context = Context()
            rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
            link.closers.append(functools.partial(rclpy.shutdown, context=context))
            suffix = f"_d{domain}" if domain is not None and len(configs) > len(members) else ""
            node: Any = rclpy.create_node((name or node_name(members)) + suffix, context=context)
            link.closers.append(node.destroy_node)
            # every client and subscription is created before the node spins: an EventsExecutor cannot take
            # new ones while it spins (rclpy 7.1 blocks), and a SingleThreadedExecutor rebuilds its wait set
            first = len(link.closers)
            for config in members:
                port = make_port(model, module, config, "ros2", node)
                link.closers.append(port.close)
                link.ports[config.robot] = port
            link.closers.insert(first, spin(node).stop)  # stopped after the ports closed
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
    link = RosLink(description=f"ROS 1 via {interpreter}, package {package}")
    layout = Layout.of(model)
    try:
        for master, members in _groups(configs, lambda c: c.ros_master_uri).items():
            bridge = Ros1Bridge(
                layout,
                package,
                [(c.robot, c.ros_namespace) for c in members],
                python=interpreter,
                pythonpath=pythonpath,
                master_uri=master or environ.get("ROS_MASTER_URI"),
                node_name=name or node_name(members),
                timeout=max(c.call_timeout for c in members),
                feedback_grace={c.robot: c.goal_feedback_grace for c in members},
                environ=environ,
            )
            bridge.start()
            link.closers.append(bridge.close)
            for config in members:
                link.ports[config.robot] = bridge.port(config.robot)
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
        os.environ["ROS_MASTER_URI"] = masters.pop()
    module = import_package(package)
    rospy: Any = importlib.import_module("rospy")
    link = RosLink(description=f"ROS 1 (rospy), package {package}")
    rospy.init_node(name or node_name(configs), disable_signals=True)
    link.closers.append(lambda: rospy.signal_shutdown("td2adaptor edge node stopped"))
    try:
        for config in configs:
            port = make_port(model, module, config, "ros1")
            link.closers.append(port.close)
            link.ports[config.robot] = port
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
