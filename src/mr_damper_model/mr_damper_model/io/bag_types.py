"""
The suite's own message types (``mr_damper_interfaces``) for rosbags, without ROS.

Bags written with `rosbags` carry a full ``ros2msg`` schema per topic only if the type store
knows the type. This module registers the ``.msg`` definitions of ``mr_damper_interfaces`` with
a rosbags type store, so bags of ``KwokParameters`` or ``QuarterCarState`` are typed: Foxglove,
PlotJuggler and ``AnyReader`` see named fields.

Where the definitions come from (one home): the ``share/mr_damper_interfaces/msg/`` folder that
the interfaces package installs, the same files the message classes were generated from. It is
looked up like the ament resource index does: the first prefix of ``AMENT_PREFIX_PATH`` whose
``share/ament_index/resource_index/packages/mr_damper_interfaces`` marker exists, then the
running interpreter's prefix (``launch_scripts/setup_venv.sh`` installs the package into the
venv, so a venv interpreter needs no environment variable). No copy is kept here: a copy could
drift from the generated classes and write bags whose schema does not match their payload.

The module imports rosbags only (pure Python), never rclpy or message packages.
"""
import os
from pathlib import Path
import sys

from rosbags.typesys import get_types_from_msg, get_typestore, Stores, TypesysError

INTERFACES_PACKAGE = 'mr_damper_interfaces'


class BagTypesError(LookupError):
    """The interface definitions cannot be found or read."""


def _candidate_prefixes():
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    return prefixes


def interfaces_msg_dir(prefixes=None):
    """
    Find the installed ``.msg`` folder of ``mr_damper_interfaces``.

    Parameters
    ----------
    prefixes : sequence of str or Path, optional
        Install prefixes to search in order. Default: ``AMENT_PREFIX_PATH``, then
        ``sys.prefix``.

    Returns
    -------
    pathlib.Path
        ``<prefix>/share/mr_damper_interfaces/msg``.

    Raises
    ------
    BagTypesError
        If no prefix has the package (the error lists the prefixes searched).

    """
    searched = list(_candidate_prefixes() if prefixes is None else prefixes)
    for prefix in searched:
        prefix = Path(prefix)
        marker = (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
                  / INTERFACES_PACKAGE)
        msg_dir = prefix / 'share' / INTERFACES_PACKAGE / 'msg'
        if marker.is_file() and msg_dir.is_dir():
            return msg_dir
    raise BagTypesError(
        f'{INTERFACES_PACKAGE} is not installed in any of the prefixes '
        f'{[str(p) for p in searched]}: run launch_scripts/setup_venv.sh (venv) or source the '
        'install/setup.bash of a colcon build.')


def interface_types(msg_dir=None):
    """
    Parse every ``.msg`` definition of ``mr_damper_interfaces`` into rosbags type definitions.

    Parameters
    ----------
    msg_dir : str or Path, optional
        Folder of ``*.msg`` files. Default: :func:`interfaces_msg_dir`.

    Returns
    -------
    dict
        rosbags type definitions by full type name (``'mr_damper_interfaces/msg/NAME'``), ready
        for ``Typestore.register``.

    Raises
    ------
    BagTypesError
        If the folder has no ``.msg`` file or a definition does not parse.

    """
    msg_dir = interfaces_msg_dir() if msg_dir is None else Path(msg_dir)
    paths = sorted(msg_dir.glob('*.msg'))
    if not paths:
        raise BagTypesError(f'{msg_dir}: no .msg file')
    types = {}
    for path in paths:
        name = f'{INTERFACES_PACKAGE}/msg/{path.stem}'
        try:
            types.update(get_types_from_msg(path.read_text(), name))
        except TypesysError as exc:
            raise BagTypesError(f'{path}: not a valid message definition: {exc}') from exc
    return types


def register_interface_types(typestore, msg_dir=None):
    """
    Register the ``mr_damper_interfaces`` messages with a rosbags type store (in place).

    Parameters
    ----------
    typestore : rosbags.typesys.store.Typestore
        Type store to extend, e.g. ``get_typestore(Stores.ROS2_KILTED)``.
    msg_dir : str or Path, optional
        Folder of ``*.msg`` files. Default: :func:`interfaces_msg_dir`.

    Returns
    -------
    tuple of str
        The full type names registered, sorted.

    """
    types = interface_types(msg_dir)
    typestore.register(types)
    return tuple(sorted(types))


def suite_typestore(msg_dir=None):
    """
    Return a ROS 2 kilted rosbags type store that also knows the suite's own messages.

    Parameters
    ----------
    msg_dir : str or Path, optional
        As in :func:`register_interface_types`.

    Returns
    -------
    rosbags.typesys.store.Typestore

    """
    typestore = get_typestore(Stores.ROS2_KILTED)
    register_interface_types(typestore, msg_dir)
    return typestore
