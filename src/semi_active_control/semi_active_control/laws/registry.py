"""Controllers by name: make_controller and the names the command-line tools and nodes accept."""
from semi_active_control.laws.add import ADD, ShAdd
from semi_active_control.laws.base import Passive
from semi_active_control.laws.optimal import (clipped_optimal_gain, ClippedOptimal,
                                              ClippedOptimalWk, LqrActive, wk_lqr_design)
from semi_active_control.laws.skyhook import (DEFAULT_C_P, DEFAULT_C_SKY, Groundhook, Hybrid,
                                              Skyhook, SkyhookIdeal, SkyhookOnOff)


def make_controller(name, *, c_sky=DEFAULT_C_SKY, c_p=DEFAULT_C_P, lqr_gain=None, alpha=0.7,
                    params=None, inverse=None, damper_only=False, dt=1e-3):
    """
    Build a controller from its name: the one controller factory (command line and nodes).

    Parameters
    ----------
    name : str
        ``passive@<I>A`` (or ``passive`` = 0 A), ``skyhook``, ``skyhook-onoff``, ``groundhook``,
        ``hybrid``, ``add``, ``sh-add``, ``clipped-optimal``, ``clipped-optimal-wk``,
        ``skyhook-ideal``, ``lqr-active``.
    c_sky, c_p : float
        Skyhook gain and passive part [N s/m] (skyhook, hybrid, skyhook-ideal).
    lqr_gain : array_like, optional
        LQR gain (lqr-active, clipped-optimal; refused by clipped-optimal-wk, which designs
        its own); default designed on ``params`` by
        :func:`semi_active_control.car.quarter_car_linear.lqr_design` (lqr-active) or
        :func:`clipped_optimal_gain` (clipped-optimal).
    alpha : float
        Hybrid weight.
    params : QuarterCarParams, optional
        Car parameters for the LQR design.
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse, optional
        Inverse model whose force range clips the clipped-optimal demands (else the inverse of
        the loop saturates them, see :class:`ClippedOptimal`).
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
        Unknown name; with ``damper_only``, a fully active controller (``skyhook-ideal``,
        ``lqr-active``): it applies forces directly and cannot drive an MR damper.

    """
    ctrl = _make_controller(name, c_sky, c_p, lqr_gain, alpha, params, inverse, dt)
    if damper_only and ctrl.kind not in ('current', 'semi-active'):
        raise ValueError(f'controller {name!r} is {ctrl.kind}: it needs a force actuator, not an '
                         f'MR damper (use {", ".join(DAMPER_LAW_NAMES)})')
    return ctrl


def _make_controller(name, c_sky, c_p, lqr_gain, alpha, params, inverse, dt):
    n = str(name).strip().lower()
    if n == 'passive':
        return Passive(0.0)
    if n.startswith('passive@'):
        txt = n[len('passive@'):].rstrip('a')
        try:
            return Passive(float(txt))
        except ValueError:
            raise ValueError(f'bad passive current in {name!r} (use e.g. passive@0.5A)') from None
    if n == 'skyhook':
        return Skyhook(c_sky, c_p)
    if n == 'skyhook-onoff':
        return SkyhookOnOff()
    if n == 'groundhook':
        return Groundhook()
    if n == 'hybrid':
        return Hybrid(c_sky, alpha)
    if n == 'add':
        return ADD()
    if n == 'sh-add':
        return ShAdd()
    if n == 'clipped-optimal':
        gain = clipped_optimal_gain(params) if lqr_gain is None else lqr_gain
        return ClippedOptimal(gain, None if inverse is None else inverse.body_force_range)
    if n == 'clipped-optimal-wk':
        if lqr_gain is not None:
            raise ValueError('clipped-optimal-wk designs its own gain from its weights '
                             '(wk_lqr_design); `lqr_gain` is for clipped-optimal and lqr-active')
        return ClippedOptimalWk(wk_lqr_design(params),
                                None if inverse is None else inverse.body_force_range, dt=dt)
    if n == 'skyhook-ideal':
        return SkyhookIdeal(c_sky, c_p)
    if n == 'lqr-active':
        if lqr_gain is None:
            from semi_active_control.car.quarter_car_linear import lqr_design
            from semi_active_control.car.quarter_car import QuarterCarParams
            lqr_gain = lqr_design(params or QuarterCarParams()).gain
        return LqrActive(lqr_gain)
    raise ValueError(f'unknown controller {name!r} (use {", ".join(CONTROLLER_NAMES)})')


CONTROLLER_NAMES = ('passive@<I>A', 'skyhook', 'skyhook-onoff', 'groundhook', 'hybrid', 'add',
                    'sh-add', 'clipped-optimal', 'clipped-optimal-wk', 'skyhook-ideal',
                    'lqr-active')


#: The laws that drive an MR damper by its coil current (``damper_only=True``; the nodes).
DAMPER_LAW_NAMES = tuple(n for n in CONTROLLER_NAMES if n not in ('skyhook-ideal', 'lqr-active'))
