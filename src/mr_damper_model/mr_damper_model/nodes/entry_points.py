"""
Console scripts of the mr_damper_model nodes: stop handlers first, then the node module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters.
"""
from mr_damper_common.stop_flag import early_main


def identifier_node():
    """``ros2 run mr_damper_model identifier_node``."""
    return early_main('mr_damper_model.nodes.identifier_node')
