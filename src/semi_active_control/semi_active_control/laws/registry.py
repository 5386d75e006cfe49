"""
Laws by name: :data:`LAWS`, one dict whose keys are the names the tools and nodes accept.

Each entry is a :class:`Law`: the car it drives (``'quarter'``, a law reading one corner's
state; ``'full'``, a law choosing the four corner forces from the whole car), its kind
(``'current'``, ``'semi-active'``, ``'active'``, see :mod:`semi_active_control.laws`) and its
factory ``make(options)`` (options: :class:`LawOptions`). The name lists (:data:`CONTROLLER_NAMES`,
:data:`DAMPER_LAW_NAMES`, :func:`law_names`) are read off the dict, so they cannot drift from
it; a law added to the dict is built by :func:`make_controller` / :func:`make_full_car_law` and
listed by :func:`law_names` like the others (docs/extending.md).

Names beyond the keys: ``passive@<I>A`` (key ``passive``, a constant current ``I``), and for the
full car ``per-corner-<law>`` (four quarter-car damper laws, each designed on its corner's
quarter car) and ``passive@<I>A`` at every corner.
"""
from dataclasses import dataclass
from typing import Callable

from semi_active_control.car.quarter_car import QuarterCarParams
from semi_active_control.car.quarter_car_linear import lqr_design
from semi_active_control.laws.add import ADD, ShAdd
from semi_active_control.laws.base import Passive
from semi_active_control.laws.full_car import DEFAULT_MODAL_C_P, ModalSkyhook, PerCornerLaws
from semi_active_control.laws.full_car_lqr import FullCarClippedOptimal
from semi_active_control.laws.full_car_lqr_wk import FullCarClippedOptimalWk
from semi_active_control.laws.optimal import (clipped_optimal_gain, ClippedOptimal,
                                              ClippedOptimalWk, LqrActive, wk_lqr_design)
from semi_active_control.laws.skyhook import (DEFAULT_C_P, DEFAULT_C_SKY, Groundhook, Hybrid,
                                              Skyhook, SkyhookIdeal, SkyhookOnOff)


@dataclass(frozen=True)
class LawOptions:
    """
    What a law's factory may read (the keyword options of the two ``make_*`` functions).

    Attributes
    ----------
    params : QuarterCarParams or FullCarParams or None
        The car a law is designed on (LQR designs, modal gains; None: the default car).
    dt : float
        Control period [s] (the sample time of a filter inside a law).
    c_sky, c_p : float
        Skyhook gain and passive part [N s/m] (skyhook, hybrid, skyhook-ideal; modal skyhook's
        passive part per corner).
    alpha : float
        Hybrid weight [-].
    lqr_gain : array_like or None
        LQR gain (lqr-active, clipped-optimal; None: designed on ``params``).
    inverse : KwokCurrentInverse or None
        Inverse model whose force range clips the clipped-optimal demands.
    current_a : float
        Current of a passive law [A] (from its name, ``passive@<I>A``).
    zeta : dict or None
        Modal skyhook damping ratios.

    """

    params: object = None
    dt: float = 1e-3
    c_sky: float = DEFAULT_C_SKY
    c_p: float = DEFAULT_C_P
    alpha: float = 0.7
    lqr_gain: object = None
    inverse: object = None
    current_a: float = 0.0
    zeta: dict = None


@dataclass(frozen=True)
class Law:
    """
    One entry of :data:`LAWS`.

    Attributes
    ----------
    car : str
        ``'quarter'`` (a law of one corner: ``demand(state)``) or ``'full'`` (the four corner
        forces of the whole car: ``prepare(state)`` and ``corner_laws``).
    kind : str
        ``'current'``, ``'semi-active'`` or ``'active'`` (the kind of the laws it makes).
    make : callable
        ``make(options: LawOptions)`` -> the law.

    """

    car: str
    kind: str
    make: Callable


def _clipped_optimal(o):
    gain = clipped_optimal_gain(o.params) if o.lqr_gain is None else o.lqr_gain
    return ClippedOptimal(gain, None if o.inverse is None else o.inverse.body_force_range)


def _clipped_optimal_wk(o):
    if o.lqr_gain is not None:
        raise ValueError('clipped-optimal-wk designs its own gain from its weights '
                         '(wk_lqr_design); `lqr_gain` is for clipped-optimal and lqr-active')
    return ClippedOptimalWk(wk_lqr_design(o.params),
                            None if o.inverse is None else o.inverse.body_force_range, dt=o.dt)


def _lqr_active(o):
    gain = o.lqr_gain
    if gain is None:
        gain = lqr_design(o.params or QuarterCarParams()).gain
    return LqrActive(gain)


#: The laws by name (see the module docstring); add one with ``LAWS[name] = Law(...)``.
LAWS = {
    'passive': Law('quarter', 'current', lambda o: Passive(o.current_a)),
    'skyhook': Law('quarter', 'semi-active', lambda o: Skyhook(o.c_sky, o.c_p)),
    'skyhook-onoff': Law('quarter', 'semi-active', lambda o: SkyhookOnOff()),
    'groundhook': Law('quarter', 'semi-active', lambda o: Groundhook()),
    'hybrid': Law('quarter', 'semi-active', lambda o: Hybrid(o.c_sky, o.alpha)),
    'add': Law('quarter', 'semi-active', lambda o: ADD()),
    'sh-add': Law('quarter', 'semi-active', lambda o: ShAdd()),
    'clipped-optimal': Law('quarter', 'semi-active', _clipped_optimal),
    'clipped-optimal-wk': Law('quarter', 'semi-active', _clipped_optimal_wk),
    'skyhook-ideal': Law('quarter', 'active', lambda o: SkyhookIdeal(o.c_sky, o.c_p)),
    'lqr-active': Law('quarter', 'active', _lqr_active),
    'modal-skyhook': Law('full', 'semi-active', lambda o: ModalSkyhook.from_car(
        o.params, zeta=o.zeta, c_p=o.c_p)),
    'full-car-clipped-optimal': Law('full', 'semi-active',
                                    lambda o: FullCarClippedOptimal.from_car(o.params)),
    'full-car-clipped-optimal-wk': Law('full', 'semi-active',
                                       lambda o: FullCarClippedOptimalWk.from_car(o.params,
                                                                                  dt=o.dt)),
}


def law_names(car='quarter', *, damper_only=False):
    """
    Return the names of the laws of ``car`` in :data:`LAWS` (``passive`` as ``passive@<I>A``).

    Parameters
    ----------
    car : {'quarter', 'full'}
        Laws of one corner or of the whole car (the full car also takes ``per-corner-<law>``
        and ``passive@<I>A``, not listed here).
    damper_only : bool
        Only the laws that drive an MR damper by its coil current (no ``'active'`` kind).

    Returns
    -------
    tuple of str

    """
    return tuple('passive@<I>A' if name == 'passive' else name for name, law in LAWS.items()
                 if law.car == car and not (damper_only and law.kind == 'active'))


#: The quarter-car laws' names, as the command-line tools list them (built-in laws).
CONTROLLER_NAMES = law_names('quarter')

#: The laws that drive an MR damper by its coil current (``damper_only=True``; the nodes).
DAMPER_LAW_NAMES = law_names('quarter', damper_only=True)


def _key(name):
    """Return ``(key of LAWS, current [A] of a passive name)`` of a law name."""
    n = str(name).strip().lower()
    if n == 'passive':
        return 'passive', 0.0
    if n.startswith('passive@'):
        try:
            return 'passive', float(n[len('passive@'):].rstrip('a'))
        except ValueError:
            raise ValueError(f'bad passive current in {name!r} (use e.g. passive@0.5A)') from None
    return n, 0.0


def make_controller(name, *, c_sky=DEFAULT_C_SKY, c_p=DEFAULT_C_P, lqr_gain=None, alpha=0.7,
                    params=None, inverse=None, damper_only=False, dt=1e-3):
    """
    Build a quarter-car law from its name: the one factory (command line and nodes).

    Parameters
    ----------
    name : str
        A quarter-car name of :data:`LAWS` (:data:`CONTROLLER_NAMES`: ``passive@<I>A`` (or
        ``passive`` = 0 A), ``skyhook``, ``skyhook-onoff``, ``groundhook``, ``hybrid``,
        ``add``, ``sh-add``, ``clipped-optimal``, ``clipped-optimal-wk``, ``skyhook-ideal``,
        ``lqr-active``).
    c_sky, c_p : float
        Skyhook gain and passive part [N s/m] (skyhook, hybrid, skyhook-ideal).
    lqr_gain : array_like, optional
        LQR gain (lqr-active, clipped-optimal; refused by clipped-optimal-wk, which designs
        its own); default designed on ``params`` by
        :func:`semi_active_control.car.quarter_car_linear.lqr_design` (lqr-active) or
        :func:`~semi_active_control.laws.optimal.clipped_optimal_gain` (clipped-optimal).
    alpha : float
        Hybrid weight.
    params : QuarterCarParams, optional
        Car parameters for the LQR design.
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse, optional
        Inverse model whose force range clips the clipped-optimal demands (else the inverse of
        the loop saturates them, see :class:`~semi_active_control.laws.optimal.ClippedOptimal`).
    damper_only : bool
        Only controllers that drive an MR damper by its coil current (kinds ``'current'`` and
        ``'semi-active'``), as the car and controller nodes need.
    dt : float
        Control period [s]: the sample time of the Wk filter inside ``clipped-optimal-wk``
        (called once per period).

    Returns
    -------
    Controller

    Raises
    ------
    ValueError
        Unknown name (or a full-car law's); with ``damper_only``, a fully active controller
        (``skyhook-ideal``, ``lqr-active``): it applies forces directly and cannot drive an MR
        damper.

    """
    key, current_a = _key(name)
    law = LAWS.get(key)
    if law is None or law.car != 'quarter':
        hint = (f'; {key!r} is a full-car law (vehicle_controller_node, full_car_node, '
                'full-car-sim)'
                if law is not None else '')
        raise ValueError(f'unknown controller {name!r} (use {", ".join(law_names())}){hint}')
    if damper_only and law.kind not in ('current', 'semi-active'):
        raise ValueError(f'controller {name!r} is {law.kind}: it needs a force actuator, not an '
                         f'MR damper (use {", ".join(law_names(damper_only=True))})')
    return law.make(LawOptions(params=params, dt=dt, c_sky=c_sky, c_p=c_p, alpha=alpha,
                               lqr_gain=lqr_gain, inverse=inverse, current_a=current_a))


def make_full_car_law(name, params, *, dt=1e-3, zeta=None, c_p=DEFAULT_MODAL_C_P):
    """
    Build a full-car law by name.

    Parameters
    ----------
    name : str
        A full-car name of :data:`LAWS` (``'modal-skyhook'``, ``'full-car-clipped-optimal'``,
        ``'full-car-clipped-optimal-wk'``), ``'passive@<I>A'`` (the current at every corner)
        or ``'per-corner-<law>'`` with a quarter-car damper law (:data:`DAMPER_LAW_NAMES`,
        e.g. ``per-corner-skyhook``), each corner's law designed on its quarter car
        (:meth:`FullCarParams.corner`).
    params : FullCarParams
        Car.
    dt : float
        Control period [s].
    zeta, c_p
        Modal skyhook options (:meth:`~semi_active_control.laws.full_car.ModalSkyhook.from_car`).

    Returns
    -------
    PerCornerLaws, ModalSkyhook, FullCarClippedOptimal or FullCarClippedOptimalWk

    Raises
    ------
    ValueError
        Unknown name, or a quarter-car law given without ``per-corner-``.

    """
    n = str(name).strip().lower()
    key, _ = _key(n)
    if key == 'passive':
        laws = [make_controller(n, damper_only=True) for _ in range(4)]
        return PerCornerLaws(laws, name=laws[0].name)
    if n.startswith('per-corner-'):
        law = n[len('per-corner-'):]
        return PerCornerLaws([make_controller(law, params=params.corner(i), damper_only=True,
                                              dt=dt) for i in range(4)])
    law = LAWS.get(key)
    if law is None or law.car != 'full':
        hint = (f'; for the quarter-car law at each corner use per-corner-{key}'
                if law is not None else '')
        raise ValueError(f'unknown full-car law {name!r} (use '
                         f'{", ".join(law_names("full"))}, passive@<I>A or '
                         f'per-corner-<law>){hint}')
    return law.make(LawOptions(params=params, dt=dt, c_p=c_p, zeta=zeta))
