"""
Console scripts of mr_damper_bringup: stop handlers first, then the module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters.
"""
from mr_damper_common.stop_flag import early_main


def suite():
    """``mr-damper-suite``: the launcher (``ros2 run mr_damper_bringup mr-damper-suite``)."""
    return early_main('mr_damper_bringup.launcher')


def record():
    """``mr-damper-record``: every suite topic into one MCAP file."""
    return early_main('mr_damper_bringup.record_node')
