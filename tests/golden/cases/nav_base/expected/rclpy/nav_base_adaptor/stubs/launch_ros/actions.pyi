# Type stubs of ROS 2's launch_ros, by td2adaptor: only what launch/edge_node.launch.py uses (the environment's
# keys typed as str, narrower than launch's own substitutions).
from collections.abc import Iterable, Mapping

from launch import Action, SomeSubstitutionsType

class Node(Action):
    def __init__(
        self,
        *,
        executable: SomeSubstitutionsType,
        package: SomeSubstitutionsType | None = None,
        name: SomeSubstitutionsType | None = None,
        namespace: SomeSubstitutionsType | None = None,
        arguments: Iterable[SomeSubstitutionsType] | None = None,
        output: SomeSubstitutionsType = "log",
        additional_env: Mapping[str, SomeSubstitutionsType] | None = None,
    ) -> None: ...
