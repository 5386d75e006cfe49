"""
The LQ road-preview law fed from the road-preview topic: a part of the vehicle controller.

:class:`LivePreview` holds the LQ preview law
(:class:`~semi_active_control.laws.full_car_preview.FullCarPreviewLaw`, look-ahead) and a
:class:`~semi_active_control.estimation.preview_input.PreviewInput` between the
``full_car/road_preview`` topic and the law's road map.
:class:`~semi_active_control.runtime.vehicle_controller.VehicleControllerCore` calls
:meth:`LivePreview.before` and :meth:`LivePreview.after` around each cycle's law: without a
usable preview the law is ``full-car-clipped-optimal-wk`` for that cycle (counted); the law
itself also falls back when the map does not reach under a wheel. Every force still goes through
each corner's inverse and supervisor (the controller's).

The frames' stamps and the states' stamps are on one clock (the vehicle's: on the simulated
car, its node clock).
"""
import math

from semi_active_control.estimation.preview_input import PreviewInput
from semi_active_control.laws.full_car_preview import make_full_car_preview_law

#: Live law names of ``vehicle_controller_node`` that take the road-preview topic.
LIVE_PREVIEW_LAWS = ('preview-look-ahead',)


class LivePreview:
    """
    The LQ road-preview law and its topic input (module docstring).

    Parameters
    ----------
    params : FullCarParams
        Car (the law's design).
    law : str
        One of :data:`LIVE_PREVIEW_LAWS`.
    dt : float
        Period of the states (the control cycle) [s].
    horizon_s, step_s : float
        Preview horizon and tap spacing [s] (:func:`~semi_active_control.laws.full_car_preview.
        make_full_car_preview_law`).
    preview_timeout_s, preview_max_age_s : float
        The input's ``timeout_s`` and ``max_age_s`` [s]
        (:class:`~semi_active_control.estimation.preview_input.PreviewInput`).

    Attributes
    ----------
    law : FullCarPreviewLaw
        The law the controller runs.
    preview : PreviewInput
        The topic's side.
    first_previewed_t, last_previewed_t, last_fallback_t : float
        Stamps [s] of the first and last cycle run with preview and of the last without (NaN:
        none): the order of preview, fallback and recovery.

    """

    def __init__(self, params, law='preview-look-ahead', *, dt=2e-3, horizon_s=0.3,
                 step_s=1e-3, preview_timeout_s=0.25, preview_max_age_s=0.1):
        name = str(law).strip().lower()
        if name not in LIVE_PREVIEW_LAWS:
            raise ValueError(f'unknown live preview law {law!r} (use '
                             f'{", ".join(LIVE_PREVIEW_LAWS)})')
        self.law = make_full_car_preview_law(params, source='look-ahead', horizon_s=horizon_s,
                                             step_s=step_s, dt=dt, name=name)
        self.preview = PreviewInput(self.law.road, timeout_s=preview_timeout_s,
                                    max_age_s=preview_max_age_s)
        self.first_previewed_t = self.last_previewed_t = self.last_fallback_t = math.nan

    def offer(self, fields):
        """Take one decoded road-preview message (``PreviewInput.offer``)."""
        return self.preview.offer(fields)

    def refuse(self, reason):
        """Count a message that could not be decoded (``PreviewInput.refuse``)."""
        self.preview.refuse(reason)

    def before(self, state):
        """Feed the map up to the state's stamp; switch the law's preview on or off."""
        self.law.preview_enabled = self.preview.before_step(state.t)

    def after(self, state):
        """Record whether the cycle ran with preview (the law's own count of the cycle)."""
        if self.law.last_previewed:
            if math.isnan(self.first_previewed_t):
                self.first_previewed_t = state.t
            self.last_previewed_t = state.t
        else:
            self.last_fallback_t = state.t

    def status(self):
        """Return the law's, the map's and the input's counters and the stamps (JSON-ready)."""
        return {**self.law.status(), 'input': self.preview.status(),
                'first_previewed_t': self.first_previewed_t,
                'last_previewed_t': self.last_previewed_t,
                'last_fallback_t': self.last_fallback_t,
                'horizon_s': float(self.law.preview.times_s[-1])
                if len(self.law.preview.times_s) else 0.0}
