"""
The one way a test initialises rclpy: a context of its own, shut down whatever happens.

Every fixture that needs rclpy in the test process uses :func:`ros_context`::

    @pytest.fixture
    def ctx():
        with ros_context() as context:
            yield context

A private context instead of rclpy's default one: a fixture that left the default context
initialised after a failure (or shut it down without rclpy replacing it) made every later
``rclpy.init()`` in the run raise ``RuntimeError: Context.init() must only be called once``,
17 errors in two other files of a loaded CI run (issue 32). The ``finally`` shuts the context
down when the test fails, when the fixture's own setup fails after ``init``, and when ``init``
itself fails; the nodes made in it are destroyed first.
"""
import contextlib


@contextlib.contextmanager
def ros_context(nodes=None, *, default=False):
    """
    Yield a new, initialised rclpy ``Context``; destroy ``nodes`` and shut it down on exit.

    Parameters
    ----------
    nodes : list, optional
        Nodes the caller appends as it makes them; each is destroyed (newest first) before the
        context goes down, also after an error.
    default : bool
        Initialise rclpy's default context instead (for code under test that asks
        ``rclpy.ok()`` of it, as the suite's spin loop does); ``rclpy.try_shutdown()`` then
        shuts it down and lets rclpy replace it, so the next ``rclpy.init()`` works.

    """
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    context = None if default else Context()
    try:
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        yield rclpy.get_default_context() if default else context
    finally:
        try:
            while nodes:
                nodes.pop().destroy_node()
        finally:
            rclpy.try_shutdown(context=context)
