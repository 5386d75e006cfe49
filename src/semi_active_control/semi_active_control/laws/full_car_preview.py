"""
Full-car road preview: the ISO-weighted LQR plus the optimal feedforward on the road ahead.

:func:`full_car_lq_preview` is :func:`semi_active_control.laws.preview.lq_preview` on the
design problem of ``full-car-clipped-optimal-wk``
(:func:`~semi_active_control.laws.full_car_lqr_wk.full_car_lqr_wk_design`: the warp-free
road-relative
car and the ISO 2631-1 filters) with the four wheels' road as the exogenous input:

- the road velocities ``zdot_r`` drive the tyre deflections (and the tyres' damping);
- the road's **warp** ``n . z_r`` (the component of the four wheel heights no body motion
  follows, ``T' n = 0``) is the state component the LQR design leaves out: with
  ``x = V x_r + u c``, ``u = [n, n, 0] / sqrt 2`` and ``c = u . x = -n . z_r / sqrt 2``, it acts
  on the rest through ``V' A u c`` and on the cost (the travels and tyre deflections carry it).
  Today's law ignores it; the preview law includes it, exactly, as a known input.

The law (:class:`FullCarPreviewLaw`) adds the feedforward ``sum_j taps[j] z_r(t + j h)`` (the
heights under ``fl, fr, rl, rr`` at the preview times, from its
:class:`~semi_active_control.estimation.road_preview.RoadPreview`) to the LQR forces of
``full-car-clipped-optimal-wk``; each corner is then clipped (dissipative) and goes through
that corner's inverse and supervisor as every full-car law does. Two sources of preview:

- ``'wheelbase'``: no sensor. The law estimates the road under each front wheel from the state
  it already reads (:class:`~semi_active_control.estimation.road_preview.FrontRoadEstimate`) and
  puts it on the map at the front axle; the rear wheels meet it ``wheelbase`` later by the odometer
  (the speed signal), the front wheels see no road ahead (held);
- ``'look-ahead'``: the map is filled by a look-ahead sensor's frames
  (:meth:`RoadPreview.offer_frame`, from a node or, offline, :class:`FedFullCarLaw`).

Without a valid window (no speed yet, a dropout longer than the map ahead, or
``preview_enabled`` False: the live input's timeout,
:mod:`~semi_active_control.runtime.live_preview`) the law is
``full-car-clipped-optimal-wk`` for that step, counted in ``stats``.
"""
import math

import numpy as np

from semi_active_control.laws.preview import (DEFAULT_PREVIEW_HORIZON_S,
                                              DEFAULT_PREVIEW_STEP_S, lq_preview,
                                              PreviewStats)
from semi_active_control.laws.full_car import ForceLaw
from semi_active_control.estimation.road_preview import FrontRoadEstimate, RoadPreview

#: Preview sources of :class:`FullCarPreviewLaw`.
PREVIEW_SOURCES = ('wheelbase', 'look-ahead')


def full_car_road_inputs(design, params):
    """
    Road inputs of a ``full_car_lqr_wk_design`` problem, for :func:`lq_preview`.

    Returns
    -------
    dict
        ``Gv``, ``Gh`` (34, 4): the four wheels' road velocities and heights into the reduced
        augmented state; ``Sxh`` (34, 4), ``Suh`` (4, 4): the cost's cross terms of the state
        and of the forces with the road heights (through the warp).

    """
    from semi_active_control.laws.full_car_lqr import relative_model
    m = design.model
    if m is None:
        raise ValueError('the design carries no model (full_car_lqr_wk_design builds one)')
    A, _, _, _, n = relative_model(params)
    V = m['V']
    nx = m['A'].shape[0]
    aw, bw, _, dw = design.filter
    # full relative state: ddot = v_u - zdot_r, m_u v_u' = ... - c_t (v_u - zdot_r)
    E = np.zeros((15, 4))
    E[4:8] = -np.eye(4)
    E[11:15] = np.diag(params.c_t / params.m_u)
    u = np.concatenate([n, n, np.zeros(7)]) / math.sqrt(2.0)
    warp = -n[None, :] / math.sqrt(2.0)                 # c = warp @ z_r
    Gv = np.zeros((nx, 4))
    Gv[:14] = V.T @ E
    dc = np.zeros(nx)                                   # d X' / d c
    dc[:14] = V.T @ A @ u
    dc[14:] = bw @ (m['Ca'] @ u)
    Gh = np.outer(dc, warp)
    # cost outputs of the warp: z = Cz X + Dz F + cz c
    cz = np.zeros(m['Cz'].shape[0])
    cz[0:3] = dw @ (m['Ca'] @ u)
    cz[3:6] = m['Cy'] @ u
    cz[6:14] = u[0:8]
    Hh = np.outer(cz, warp)
    W = m['W']
    return {'Gv': Gv, 'Gh': Gh, 'Sxh': m['Cz'].T @ W @ Hh, 'Suh': m['Dz'].T @ W @ Hh}


def full_car_lq_preview(design, params, horizon_s=DEFAULT_PREVIEW_HORIZON_S,
                        step_s=DEFAULT_PREVIEW_STEP_S):
    """
    LQ preview of ``full-car-clipped-optimal-wk``'s design: taps on the four wheels' road.

    Parameters
    ----------
    design : FullCarLqrWkDesign
        Design (:func:`~semi_active_control.laws.full_car_lqr_wk.full_car_lqr_wk_design`).
    params : FullCarParams
        The car it was designed on.
    horizon_s, step_s : float
        Preview horizon and sample spacing [s].

    Returns
    -------
    semi_active_control.laws.preview.LqPreview
        ``taps`` (p + 1, 4, 4): corner forces ``fl, fr, rl, rr`` per wheel height ``fl, fr,
        rl, rr`` [N/m]; ``gain`` the design's on the reduced state.

    """
    m = design.model
    if m is None:
        raise ValueError('the design carries no model (full_car_lqr_wk_design builds one)')
    r = full_car_road_inputs(design, params)
    return lq_preview(m['A'], m['B'], m['Q'], m['R'], m['N'], r['Gv'], Gh=r['Gh'],
                      Sxh=r['Sxh'], Suh=r['Suh'], horizon_s=horizon_s, step_s=step_s)


def make_road_preview(params, **kwargs):
    """
    Road preview of a full car: tracks left and right, wheels ``fl, fr, rl, rr``.

    The rear wheels sit ``params.wheelbase`` behind the front axle on the map; keywords go to
    :class:`~semi_active_control.estimation.road_preview.RoadPreview`.
    """
    L = params.wheelbase
    return RoadPreview(2, [(0, 0.0), (1, 0.0), (0, -L), (1, -L)], **kwargs)


class FullCarPreviewLaw(ForceLaw):
    """
    ``full-car-clipped-optimal-wk`` with LQ road preview (see the module docstring).

    Parameters
    ----------
    base : FullCarClippedOptimalWk
        The law without preview (its design is the preview's).
    preview : LqPreview
        Taps (:func:`full_car_lq_preview` of ``base.design``).
    road : RoadPreview
        The car's road preview (:func:`make_road_preview`), fed with the speed signal (and,
        for ``'look-ahead'``, the sensor's frames) before each step.
    source : {'wheelbase', 'look-ahead'}
        Where the road ahead comes from.
    name : str
        Law name.

    """

    state_fields = ('z_u', 'z_r')

    def __init__(self, base, preview, road, *, source='look-ahead', name=None):
        if source not in PREVIEW_SOURCES:
            raise ValueError(f'`source` must be one of {", ".join(PREVIEW_SOURCES)}, '
                             f'got {source!r}')
        taps = np.asarray(preview.taps, dtype=float)
        if taps.ndim != 3 or taps.shape[1:] != (4, 4):
            raise ValueError('`preview.taps` must have shape (p + 1, 4, 4)')
        if len(road.wheels) != 4:
            raise ValueError('`road` must preview the four wheels (make_road_preview)')
        self.base, self.preview, self.road, self.source = base, preview, road, source
        self.name = name or f'{base.name}-preview-{source}'
        self._times = preview.times_s
        self._taps = taps
        self._trivial = taps.shape[0] == 1 and not taps.any()
        self.front = FrontRoadEstimate(2) if source == 'wheelbase' else None
        self.stats = PreviewStats()
        super().__init__()

    def reset(self):
        """Clear the base law, the road preview, the front estimate and the counters."""
        super().reset()
        self.base.reset()
        self.road.reset()
        if self.front is not None:
            self.front.reset()
        self.stats.reset()
        self.feedforward = np.zeros(4)
        self.preview_enabled = True
        self.last_previewed = False

    def window(self, state):
        """Return the heights (p + 1, 4) under the wheels at the preview times, or None."""
        if self.front is not None:
            z = self.front.update(state.t, state.v[3:5], state.q[3:5] - state.z_r[0:2])
            if z is not None:
                self.road.offer_axle_road(state.t, z)
        return self.road.window(self._times)

    def desired_forces(self, state):
        """Return the LQR forces plus the feedforward [N] (the LQR's alone without a window)."""
        f = self.base.desired_forces(state)
        if self._trivial:
            self.last_previewed = True
            self.stats.count(True)
            self.feedforward = np.zeros(4)
            return f
        z = self.window(state)
        if not self.preview_enabled:            # the live input's timeout (PreviewInput)
            z = None
        self.last_previewed = z is not None
        self.stats.count(self.last_previewed)
        self.feedforward = np.zeros(4) if z is None else np.einsum('jmw,jw->m', self._taps, z)
        return f + self.feedforward

    def status(self):
        """Counters of the law, its road preview and its front estimate (JSON-ready)."""
        out = {'law': self.stats.as_dict(), 'road_preview': self.road.status()}
        if self.front is not None:
            out['front_estimate_rejected'] = self.front.rejected
        return out


def make_full_car_preview_law(params, *, source='look-ahead',
                              horizon_s=DEFAULT_PREVIEW_HORIZON_S, step_s=DEFAULT_PREVIEW_STEP_S,
                              dt=1e-3, name=None, **weights):
    """
    Build :class:`FullCarPreviewLaw` on ``full-car-clipped-optimal-wk`` (defaults or weights).

    Parameters
    ----------
    params : FullCarParams
        Car.
    source : {'wheelbase', 'look-ahead'}
        Preview source.
    horizon_s, step_s : float
        Preview horizon and sample spacing [s] (the map reaches ``horizon_s`` x speed ahead
        only with a sensor of that range).
    dt : float
        Control period [s] (the base law's filters).
    name : str, optional
        Law name.
    **weights
        Overrides of ``DEFAULT_FULL_LQR_WK_WEIGHTS``.

    Returns
    -------
    FullCarPreviewLaw

    """
    from semi_active_control.laws.full_car_lqr_wk import FullCarClippedOptimalWk
    base = FullCarClippedOptimalWk.from_car(params, dt=dt, **weights)
    preview = full_car_lq_preview(base.design, params, horizon_s, step_s)
    return FullCarPreviewLaw(base, preview, make_road_preview(params), source=source,
                             name=name)


class FedFullCarLaw:
    """
    A full-car preview law fed by a look-ahead sensor's feed (offline).

    The feed is a :class:`~quarter_car_sim.plant.preview_sensor.PreviewFeed`.

    Before each step the feed delivers the speed sample and the frames due (measured with the
    body pitch of the state), as a node would from its topics; then the law runs.

    Parameters
    ----------
    law : FullCarPreviewLaw
        The law.
    feed : quarter_car_sim.plant.preview_sensor.PreviewFeed
        Its feed (of ``law.road``).

    """

    def __init__(self, law, feed):
        if feed.road_preview is not law.road:
            raise ValueError('the feed must feed the law\'s own road preview')
        self.law, self.feed = law, feed
        self.name = law.name
        self.corner_laws = law.corner_laws

    def prepare(self, state):
        """Feed the speed and the frames due now, then compute the law's corner forces."""
        self.feed.feed(state.t, pitch=float(state.q[1]))
        return self.law.prepare(state)

    def reset(self):
        """Reset the law and the sensor."""
        self.law.reset()
        self.feed.reset()

    def status(self):
        """Counters of the law, its road preview and the sensor (JSON-ready)."""
        return {**self.law.status(), 'sensor_frames': self.feed.status()}
