"""Tests of mr_damper_bringup.network: the loopback profile and the DDS environment (no ROS)."""
import pytest

from mr_damper_bringup.network import (dds_environment, LOOPBACK_PROFILE, loopback_profile_ok,
                                       on_loopback, PROFILE_VAR, RANGE_VAR)


def test_the_shipped_profile_binds_everything_to_loopback():
    assert LOOPBACK_PROFILE.is_file() and loopback_profile_ok(LOOPBACK_PROFILE)


@pytest.mark.parametrize('old, new', [
    ('<interface name="127.0.0.1" netmask_filter="OFF"/>',
     '<interface name="0.0.0.0" netmask_filter="OFF"/>'),                # every interface
    ('<useBuiltinTransports>false</useBuiltinTransports>',
     '<useBuiltinTransports>true</useBuiltinTransports>'),               # default UDP too
    ('<initialPeersList>', '<metatrafficMulticastLocatorList><locator><udpv4><address>'
     '239.255.0.1</address></udpv4></locator></metatrafficMulticastLocatorList>'
     '<initialPeersList>'),                                              # multicast discovery
    ('<type>SHM</type>', '<type>TCPv4</type>'),
    ('is_default_profile="true"', 'is_default_profile="false"'),
    ('</dds>', ''),                                                      # cut: not XML
])
def test_a_profile_that_leaves_loopback_is_not_taken_for_the_loopback_one(tmp_path, old, new):
    text = LOOPBACK_PROFILE.read_text()
    assert old in text
    bad = tmp_path / 'bad.xml'
    bad.write_text(text.replace(old, new))
    assert not loopback_profile_ok(bad)


def test_the_dds_environment_of_the_suite(tmp_path):
    # default: the shipped profile, applied as it is (SYSTEM_DEFAULT)
    env = dds_environment(environ={})
    assert env == {RANGE_VAR: 'SYSTEM_DEFAULT', PROFILE_VAR: str(LOOPBACK_PROFILE.resolve())}
    assert on_loopback(env)
    # a user's own profile (environment or --dds-profile): LOCALHOST discovery
    own = tmp_path / 'own.xml'
    own.write_text('<dds/>')
    for got in (dds_environment(environ={PROFILE_VAR: str(own)}), dds_environment(own)):
        assert got == {RANGE_VAR: 'LOCALHOST', PROFILE_VAR: str(own.resolve())}
    none = dds_environment('none', {PROFILE_VAR: str(own)})
    assert none == {RANGE_VAR: 'LOCALHOST', PROFILE_VAR: None}
    with pytest.raises(ValueError, match='no such file'):
        dds_environment(tmp_path / 'missing.xml')
    # SYSTEM_DEFAULT without the checked profile is not loopback
    assert not on_loopback({RANGE_VAR: 'SYSTEM_DEFAULT', PROFILE_VAR: str(own)})
    assert not on_loopback({RANGE_VAR: 'SUBNET'})
    assert on_loopback({RANGE_VAR: 'LOCALHOST'})
