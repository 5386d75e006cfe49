"""
Where the suite's DDS traffic may go: the environment that keeps every node on loopback.

:func:`dds_environment` returns the variables every suite process gets (the launcher's nodes,
its own monitor, the tests' nodes): by default the Fast DDS profile shipped in this package's
``config/fastdds_loopback.xml`` (:data:`LOOPBACK_PROFILE`: UDPv4 bound to 127.0.0.1 by an
interface allowlist, shared memory, unicast discovery to 127.0.0.1) with
``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT``, so that rmw_fastrtps applies the profile as
it is. With ``LOCALHOST``, rmw_fastrtps (kilted) adds a UDPv4 transport of its own to the
profile's, without an allowlist: its sockets bind to 0.0.0.0 and to the other interfaces'
addresses (checked with ``ss -lupn``), although discovery stays on this machine.

The profile is only used once it is checked (:func:`loopback_profile_ok`): a profile Fast DDS
could not load would leave the default transports with ``SYSTEM_DEFAULT``, multicast discovery
on every interface. Any other profile (``--dds-profile FILE`` or the user's own
``FASTDDS_DEFAULT_PROFILES_FILE``), or none, runs with ``LOCALHOST``: discovery on this machine,
rmw's transports. No ROS import.
"""
import os
from pathlib import Path
import xml.etree.ElementTree as ElementTree

#: The Fast DDS variable naming the XML profile file every participant loads.
PROFILE_VAR = 'FASTDDS_DEFAULT_PROFILES_FILE'
#: The ROS 2 variable of the discovery range.
RANGE_VAR = 'ROS_AUTOMATIC_DISCOVERY_RANGE'


def _config_dir():
    here = Path(__file__).resolve().parents[1] / 'config'
    if (here / 'fastdds_loopback.xml').is_file():
        return here
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory('mr_damper_bringup')) / 'config'


#: The shipped loopback profile (source tree, else the installed share folder).
LOOPBACK_PROFILE = _config_dir() / 'fastdds_loopback.xml'
_NS = '{http://www.eprosima.com}'


def loopback_profile_ok(path=LOOPBACK_PROFILE):
    """
    Tell whether ``path`` is a readable profile that binds every transport to loopback.

    Checked: it parses; the default participant turns the built-in transports off and uses
    only transports of type SHM or UDPv4 whose allowlist is exactly ``127.0.0.1``; its unicast
    locators and initial peers are ``127.0.0.1``; it has no multicast locator.
    """
    try:
        root = ElementTree.parse(path).getroot()
    except (OSError, ElementTree.ParseError):
        return False
    transports = {}
    for td in root.iter(f'{_NS}transport_descriptor'):
        allow = [i.get('name') for i in td.iter(f'{_NS}interface')
                 if i.get('name') is not None]
        transports[td.findtext(f'{_NS}transport_id')] = (td.findtext(f'{_NS}type'), allow)
    parts = [p for p in root.iter(f'{_NS}participant') if p.get('is_default_profile') == 'true']
    if len(parts) != 1:
        return False
    rtps = parts[0].find(f'{_NS}rtps')
    if rtps is None or (rtps.findtext(f'{_NS}useBuiltinTransports') or '').strip() != 'false':
        return False
    used = [t.text for t in rtps.iter(f'{_NS}transport_id')]
    if not used or any(t not in transports for t in used):
        return False
    for t in used:
        kind, allow = transports[t]
        if kind == 'UDPv4' and allow != ['127.0.0.1']:
            return False
        if kind not in ('UDPv4', 'SHM'):
            return False
    if any(True for _ in rtps.iter(f'{_NS}metatrafficMulticastLocatorList')) or any(
            True for _ in rtps.iter(f'{_NS}defaultMulticastLocatorList')):
        return False
    addresses = [a.text for a in rtps.iter(f'{_NS}address')]
    return bool(addresses) and all(a == '127.0.0.1' for a in addresses)


def dds_environment(profile=None, environ=None):
    """
    Return the DDS variables of the suite's processes: ``{name: value}``, None to remove.

    Parameters
    ----------
    profile : str or path, optional
        None: the user's ``FASTDDS_DEFAULT_PROFILES_FILE`` if ``environ`` has one, else
        :data:`LOOPBACK_PROFILE`. ``'none'``: no profile (rmw's LOCALHOST configuration).
        A path: that profile file.
    environ : mapping, optional
        The environment to start from (default ``os.environ``).

    Returns
    -------
    dict
        ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (``SYSTEM_DEFAULT`` with the checked loopback
        profile, else ``LOCALHOST``) and ``FASTDDS_DEFAULT_PROFILES_FILE`` (None: unset it).

    Raises
    ------
    ValueError
        For a profile file that does not exist.

    """
    environ = os.environ if environ is None else environ
    if profile is None:
        profile = environ.get(PROFILE_VAR) or LOOPBACK_PROFILE
    if str(profile).lower() == 'none':
        return {RANGE_VAR: 'LOCALHOST', PROFILE_VAR: None}
    path = Path(profile).expanduser().resolve()
    if not path.is_file():
        raise ValueError(f'DDS profile {path}: no such file')
    loopback = path == Path(LOOPBACK_PROFILE).resolve() and loopback_profile_ok(path)
    return {RANGE_VAR: 'SYSTEM_DEFAULT' if loopback else 'LOCALHOST', PROFILE_VAR: str(path)}


def apply(variables, environ=None):
    """Set (or remove, for None) ``variables`` in ``environ`` (default ``os.environ``)."""
    environ = os.environ if environ is None else environ
    for name, value in variables.items():
        if value is None:
            environ.pop(name, None)
        else:
            environ[name] = value
    return environ


def on_loopback(environ=None):
    """Tell whether ``environ`` keeps DDS on this machine (LOCALHOST, or the loopback profile)."""
    environ = os.environ if environ is None else environ
    rng = environ.get(RANGE_VAR)
    if rng == 'LOCALHOST':
        return True
    prof = environ.get(PROFILE_VAR)
    return (rng == 'SYSTEM_DEFAULT' and prof is not None
            and Path(prof).resolve() == Path(LOOPBACK_PROFILE).resolve()
            and loopback_profile_ok(prof))
