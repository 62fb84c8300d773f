# Type stubs of ROS 2's launch, by td2adaptor: only what launch/edge_node.launch.py uses.
from collections.abc import Iterable

from launch import Action, SomeSubstitutionsType

class DeclareLaunchArgument(Action):
    def __init__(
        self,
        name: str,
        *,
        default_value: SomeSubstitutionsType | None = None,
        description: str | None = None,
        choices: Iterable[str] | None = None,
    ) -> None: ...
