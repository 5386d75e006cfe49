"""
Declared ROS parameters of the suite's nodes: description, range, read-only unless dynamic.

:class:`Param` describes one parameter; :func:`declare_parameters` declares a node's and
installs the on-set callback of the dynamic ones (``docs/nodes.md`` lists them, checked by
``tests/test_docs_parameters.py``). Imports rclpy.
"""
from dataclasses import dataclass

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)


@dataclass(frozen=True)
class Param:
    """
    One declared ROS parameter of a node: default, description, range, and whether it may change.

    Attributes
    ----------
    name : str
        Parameter name.
    default : bool, int, float, str or list
        Default value (its type is the parameter's type).
    description : str
        What it does, with its unit in brackets (``'Peak force [N]'``).
    low, high : float or None
        Inclusive range of a numeric parameter (None: unbounded on that side); rclpy refuses
        values outside it, at start-up and at run time.
    dynamic : bool
        True: applied while the node runs (the node's on-set callback applies it); False:
        read at start-up only, declared read-only, so ``ros2 param set`` is refused with a
        reason instead of being accepted and ignored.

    """

    name: str
    default: object
    description: str
    low: float = None
    high: float = None
    dynamic: bool = False

    def descriptor(self):
        """Return the ``ParameterDescriptor`` (description, range, read-only, constraints)."""
        desc = ParameterDescriptor(
            description=self.description, read_only=not self.dynamic,
            additional_constraints=('can be changed while running' if self.dynamic else
                                    'read at start-up: restart the node to change it'))
        if self.low is None and self.high is None:
            return desc
        if isinstance(self.default, bool) or not isinstance(self.default, (int, float)):
            raise TypeError(f'parameter {self.name}: a range needs a numeric default')
        if isinstance(self.default, int):
            desc.integer_range = [IntegerRange(
                from_value=int(self.low if self.low is not None else -2 ** 31),
                to_value=int(self.high if self.high is not None else 2 ** 31 - 1), step=0)]
        else:
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(self.low if self.low is not None else -1e300),
                to_value=float(self.high if self.high is not None else 1e300), step=0.0)]
        return desc


def merge_parameters(*groups):
    """Return the ``Param`` specs of ``groups`` in order, each name once (its first spec)."""
    seen = set()
    return tuple(p for g in groups for p in g if not (p.name in seen or seen.add(p.name)))


def declare_parameters(node, specs, on_set=None):
    """
    Declare ``specs`` on ``node`` and install the on-set callback of the dynamic ones.

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    specs : iterable of Param
        Its parameters.
    on_set : callable or None
        ``on_set(changes)`` with ``changes`` a dict name -> new value of dynamic parameters
        (already type- and range-checked by rclpy); applies them and returns ``''``, or returns
        the reason they are refused (nothing applied). Required if a spec is dynamic.

    Returns
    -------
    dict
        Name -> value after overrides (``-p``, parameter files).

    Raises
    ------
    rclpy.exceptions.InvalidParameterValueException
        A value outside its range (the node cannot start; ``run_node`` reports it).

    """
    specs = list(specs)
    values = {}
    for spec in specs:
        values[spec.name] = node.declare_parameter(spec.name, spec.default,
                                                   spec.descriptor()).value
    dynamic = {s.name for s in specs if s.dynamic}
    if dynamic:
        if on_set is None:
            raise ValueError('`on_set` is required when a parameter is dynamic')

        def callback(params):
            changes = {p.name: p.value for p in params if p.name in dynamic}
            if not changes:
                return SetParametersResult(successful=True)
            reason = on_set(changes)
            if reason:
                node.get_logger().warning(f'parameter change refused: {reason}')
            else:
                node.get_logger().info(f'parameters changed: {changes}')
            return SetParametersResult(successful=not reason, reason=reason or '')

        node.add_on_set_parameters_callback(callback)
    return values
