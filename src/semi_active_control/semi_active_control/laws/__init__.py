"""
The control laws: quarter-car laws (one corner) and full-car laws (the whole car), by name.

A quarter-car law (a controller) has ``name``, ``kind`` and ``demand(state) -> float``:

- ``kind == 'current'`` (:class:`Passive`): ``demand`` returns a coil current [A];
- ``kind == 'semi-active'`` (skyhook, on-off skyhook, groundhook, hybrid, ADD, SH-ADD,
  clipped-optimal, frequency-shaped clipped-optimal): ``demand``
  returns the desired damper force **on the body** [N], positive up, always dissipative
  (``demand * v_rel <= 0``); it goes through an inverse damper model
  (:class:`mr_damper_model.models.inverse.KwokCurrentInverse` with ``sign_convention='body'``) to a
  current saturated to the coil's range;
- ``kind == 'active'`` (``skyhook-ideal``, ``lqr-active``): ``demand`` is a force on the body
  applied directly (``QuarterCar.step_force``), no damper and no current limits.

Controllers only read the measured :class:`~mr_damper_common.contract.CornerState` (and, for the
inverse, identified parameters); never the plant's true parameters.

Skyhook-family laws use absolute body / wheel velocities (``v_s``, ``v_u``) and the suspension
velocity ``v_rel = v_s - v_u``:

- skyhook (continuous, clipped, Karnopp 1974): ``F = -(c_sky v_s + c_p v_rel)`` when that is
  dissipative, else 0 (the damper's minimum);
- on-off skyhook: ``F = -c_on v_rel`` when ``v_s v_rel > 0`` else ``-c_off v_rel``;
- groundhook (Valasek 1997): ``F = +c_gnd v_u`` when ``v_u v_rel < 0``, else 0;
- hybrid (Ahmadian): ``F = -c (alpha s_sky + (1 - alpha) s_gnd)`` with ``s_sky = v_s`` when
  ``v_s v_rel > 0`` (else 0) and ``s_gnd = -v_u`` when ``v_u v_rel < 0`` (else 0);
- ADD (Savaresi 2005, acceleration-driven damper): ``F = -c_max v_rel`` when
  ``a_s v_rel > 0``, else ``-c_min v_rel``;
- SH-ADD (Savaresi and Spelta 2007, mixed skyhook / ADD): per sample, the skyhook choice
  (``c_max`` when ``v_s v_rel > 0``) if ``v_s^2 - alpha^2 a_s^2 >= 0`` (slow body motion), else
  the ADD choice (``c_max`` when ``a_s v_rel > 0``); ``F = -c v_rel`` with ``c`` the choice;
- clipped-optimal (Dyke et al. 1996): the fully active LQR force ``-K x`` clipped to what the
  damper can give: dissipative, and within ``[F(i_min), F(i_max)]`` of the identified model at
  the present travel and velocity;
- frequency-shaped clipped-optimal (``clipped-optimal-wk``): the same with an LQR whose cost
  weights the ISO 2631-1 Wk-weighted body acceleration (the comfort metric); the law runs the
  Wk filter on the measured body acceleration and feeds its states back.

A full-car law chooses the four corner forces from the whole car's state
(:mod:`~semi_active_control.laws.full_car`): per-corner laws, modal skyhook and the full-car
clipped-optimal laws (plain and ISO 2631-1 weighted); each corner's force then goes through
that corner's inverse under its own supervisor
(:class:`semi_active_control.runtime.full_car_controller_core.FullCarController`).

Laws by name: :data:`LAWS` (:mod:`~semi_active_control.laws.registry`), one dict whose keys
are the names; :func:`make_controller` and :func:`make_full_car_law` build them
(docs/extending.md adds a law).

Modules: ``base`` (interface, passive, the damper clip), ``skyhook`` (skyhook family),
``add`` (ADD, SH-ADD), ``optimal`` (LQR-designed laws), ``full_car`` (full-car laws, modal
skyhook), ``full_car_lqr`` and ``full_car_lqr_wk`` (full-car clipped-optimal), ``registry``.

See docs/control-laws.md for the laws, their gains and the offline semi-active bound
(:mod:`quarter_car_sim.bound.quarter_car`).
"""
from semi_active_control.laws.add import ADD, DEFAULT_SHADD_F_SWITCH_HZ, ShAdd  # noqa: F401
from semi_active_control.laws.base import (car_state_feedback, clip_to_damper,  # noqa: F401
                                           Controller, Passive)
from semi_active_control.laws.full_car import ForceLaw, ModalSkyhook, PerCornerLaws  # noqa: F401
from semi_active_control.laws.full_car_lqr import FullCarClippedOptimal  # noqa: F401
from semi_active_control.laws.full_car_lqr_wk import FullCarClippedOptimalWk  # noqa: F401
from semi_active_control.laws.optimal import (clipped_optimal_gain,  # noqa: F401
                                              ClippedOptimal, ClippedOptimalWk,
                                              DEFAULT_CO_WEIGHTS, DEFAULT_COWK_WEIGHTS,
                                              LqrActive, wk_lqr_design)
from semi_active_control.laws.registry import (CONTROLLER_NAMES,  # noqa: F401
                                               DAMPER_LAW_NAMES, Law, law_names, LawOptions,
                                               LAWS, make_controller, make_full_car_law)
from semi_active_control.laws.skyhook import (DEFAULT_C_P, DEFAULT_C_SKY,  # noqa: F401
                                              Groundhook, Hybrid, Skyhook, SkyhookIdeal,
                                              SkyhookOnOff)
