# Type stubs of ROS 2's launch, by td2adaptor: only what launch/edge_node.launch.py uses.
from launch import SomeSubstitutionsType, Substitution

class LaunchConfiguration(Substitution):
    def __init__(
        self, variable_name: SomeSubstitutionsType, *, default: SomeSubstitutionsType | None = None
    ) -> None: ...
