"""
The four-corner controller core with the LQ road-preview law fed from the topic (issue 36).

:class:`PreviewControllerCore` (``full_car_controller_node``) runs the LQ preview law
(:class:`~semi_active_control.laws.full_car_preview.FullCarPreviewLaw`, look-ahead) in the
four-corner controller core, with a
:class:`~semi_active_control.estimation.preview_input.PreviewInput` between the
``full_car/road_preview`` topic and the law's road map. Without a usable preview the law is
``full-car-clipped-optimal-wk`` for that step (counted); the law itself also falls back when
the map does not reach under a wheel. Every force still goes through each corner's inverse and
supervisor (the core's controller).
"""
import math

from semi_active_control.estimation.preview_input import PreviewInput
from semi_active_control.laws.full_car_preview import make_full_car_preview_law
from semi_active_control.runtime.full_car_controller_core import FullCarControllerCore

#: Live law names of ``full_car_controller_node`` that take the road-preview topic.
LIVE_PREVIEW_LAWS = ('preview-look-ahead',)


class PreviewControllerCore(FullCarControllerCore):
    """
    The four-corner controller core with the LQ road-preview law fed from the topic.

    Parameters
    ----------
    params : FullCarParams
        Car (the law's design).
    law : str
        One of :data:`LIVE_PREVIEW_LAWS`.
    dt : float
        Period of the states [s].
    horizon_s, step_s : float
        Preview horizon and tap spacing [s] (:func:`~semi_active_control.laws.full_car_preview.
        make_full_car_preview_law`).
    preview_timeout_s, preview_max_age_s : float
        The input's ``timeout_s`` and ``max_age_s`` [s]
        (:class:`~semi_active_control.estimation.preview_input.PreviewInput`).
    **supervisor_settings
        As :class:`~semi_active_control.runtime.full_car_controller_core.
        FullCarControllerCore`.

    Attributes
    ----------
    preview : PreviewInput
        The topic's side.
    first_previewed_t, last_previewed_t, last_fallback_t : float
        Stamps [s] of the first and last step run with preview and of the last without (NaN:
        none): the order of preview, fallback and recovery.

    """

    def __init__(self, params, law='preview-look-ahead', *, dt=1e-3, horizon_s=0.3,
                 step_s=1e-3, preview_timeout_s=0.25, preview_max_age_s=0.1,
                 **supervisor_settings):
        name = str(law).strip().lower()
        if name not in LIVE_PREVIEW_LAWS:
            raise ValueError(f'unknown live preview law {law!r} (use '
                             f'{", ".join(LIVE_PREVIEW_LAWS)})')
        self.law = make_full_car_preview_law(params, source='look-ahead', horizon_s=horizon_s,
                                             step_s=step_s, dt=dt, name=name)
        self.preview = PreviewInput(self.law.road, timeout_s=preview_timeout_s,
                                    max_age_s=preview_max_age_s)
        self.first_previewed_t = self.last_previewed_t = self.last_fallback_t = math.nan
        super().__init__(params, self.law, dt=dt, **supervisor_settings)

    def offer_preview(self, fields):
        """Take one decoded road-preview message (``PreviewInput.offer``)."""
        return self.preview.offer(fields)

    def before_command(self, state):
        """Feed the map up to the state's stamp; switch the law's preview on or off."""
        self.law.preview_enabled = self.preview.before_step(state.t)

    def after_command(self, state):
        """Record whether the step ran with preview (the law's own count of the step)."""
        if self.law.last_previewed:
            if math.isnan(self.first_previewed_t):
                self.first_previewed_t = state.t
            self.last_previewed_t = state.t
        else:
            self.last_fallback_t = state.t

    def status(self, t_clock=None):
        """Return the core's status plus ``preview`` (the law's, map's and input's counters)."""
        st = super().status(t_clock)
        st['preview'] = {**self.law.status(), 'input': self.preview.status(),
                         'first_previewed_t': self.first_previewed_t,
                         'last_previewed_t': self.last_previewed_t,
                         'last_fallback_t': self.last_fallback_t,
                         'horizon_s': float(self.law.preview.times_s[-1])
                         if len(self.law.preview.times_s) else 0.0}
        return st
