"""
The node table: which executables form the graph, under which names and namespaces.

The launcher (`dual_arm_bringup`) and the ROS launch file are both built from this table.
"""

from dataclasses import dataclass, field

from dual_arm_control.contract import ARMS


@dataclass(frozen=True)
class NodeSpec:
    """One process of the graph: executable, node name, namespace, parameters, param files."""

    executable: str
    name: str
    namespace: str = ''
    parameters: dict = field(default_factory=dict)
    param_files: tuple = ()

    @property
    def label(self):
        """Return a unique, file-name-safe label, used for log files."""
        return f'{self.namespace.strip("/")}_{self.name}' if self.namespace else self.name


def hold_graph():
    """Return the twin with one gravity-compensation test controller per arm."""
    nodes = [NodeSpec('sim_bridge', 'sim_bridge', param_files=('sim_bridge.yaml',))]
    for arm in ARMS:
        nodes.append(NodeSpec('gravity_comp_controller', 'controller', f'/{arm}',
                              {'arm': arm, 'mode': 'gravity'}))
    return tuple(nodes)


GRAPHS = {'hold': hold_graph}
