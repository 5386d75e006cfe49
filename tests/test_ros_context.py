"""
A test fixture that fails leaves rclpy clean for the tests after it (issue 32, section 6).

In a loaded CI run 17 tests of two files errored with ``Context.init() must only be called
once``: a fixture had left rclpy's default context initialised (or shut down, not replaced)
after a failure. Every fixture now takes its context from :func:`ros_context.ros_context`. Here
a pytest session in a fresh interpreter runs a module whose fixture fails after ``init`` and
after making a node, a test that fails with its fixture's context open, and then tests that
need a clean rclpy: a new ``ros_context`` works, no context is left running, and the default
context can be initialised and shut down as a first user would.
"""
import textwrap

import pytest

from conftest import REPO

pytest_plugins = ['pytester']

_MODULE = textwrap.dedent('''
    import pytest
    import rclpy

    from ros_context import ros_context

    MADE = []


    @pytest.fixture
    def broken():
        nodes = []
        with ros_context(nodes) as context:
            MADE.append(context)
            nodes.append(rclpy.create_node('half_made', context=context))
            raise RuntimeError('setup failed after init')
            yield context


    @pytest.fixture
    def working():
        with ros_context() as context:
            MADE.append(context)
            yield context


    def test_setup_fails(broken):
        pass


    def test_body_fails(working):
        rclpy.create_node('in_a_failing_test', context=working)
        raise AssertionError('the test failed with its context open')


    def test_next_test_gets_a_clean_rclpy():
        assert len(MADE) == 2 and not any(c.ok() for c in MADE)
        with ros_context() as context:
            node = rclpy.create_node('after_the_failures', context=context)
            assert node.context.ok()
            node.destroy_node()
        assert not context.ok() and not rclpy.ok()


    def test_the_default_context_still_initialises_once():
        rclpy.init()
        try:
            assert rclpy.ok()
        finally:
            rclpy.try_shutdown()
        assert not rclpy.ok()
''')


@pytest.mark.slow
def test_a_failing_fixture_leaves_the_context_clean_for_the_next_test(pytester, monkeypatch):
    monkeypatch.setenv('PYTHONPATH', str(REPO / 'tests'))
    pytester.makepyfile(test_inner=_MODULE)
    result = pytester.runpytest_subprocess('-p', 'no:cacheprovider', '-q')
    result.assert_outcomes(passed=2, failed=1, errors=1)
    result.stdout.fnmatch_lines(['*RuntimeError: setup failed after init*',
                                 '*AssertionError: the test failed with its context open*'])
    result.stdout.no_fnmatch_line('*must only be called once*')
