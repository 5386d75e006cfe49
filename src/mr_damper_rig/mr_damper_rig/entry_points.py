"""
Console scripts of the mr_damper_rig nodes: stop handlers first, then the node module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters.
"""
from mr_damper_common.stop_flag import early_main


def rig_node():
    """``ros2 run mr_damper_rig rig_node``."""
    return early_main('mr_damper_rig.rig_node')
