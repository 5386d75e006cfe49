"""
The offline road-preview rows of ``quarter-car-sim`` and ``full-car-sim --compare`` (issue 36).

Each row is a preview law fed by a simulated sensor (:mod:`quarter_car_sim.preview_sensor`)
from the true road, built here for both tools so both run the same rows with the same
settings:

- ``preview-wheelbase`` (full car only): no sensor; the rear wheels get the road the law
  estimated under the front wheels, one wheelbase later by the odometer (speed signal with
  ``speed_error``);
- ``preview-look-ahead-ideal``: a look-ahead sensor without errors
  (:data:`~quarter_car_sim.preview_sensor.IDEAL_LOOK_AHEAD`), exact speed;
- ``preview-look-ahead``: the sensor with realistic errors
  (:data:`~quarter_car_sim.preview_sensor.REALISTIC_LOOK_AHEAD` unless changed: 20 ms latency,
  3 mm RMS height noise) and a speed signal 2 % off;
- ``preview-mpc-look-ahead-ideal``, ``preview-mpc-look-ahead`` (full car only): the same two
  sensors feeding the receding-horizon MPC with the dampers' limits
  (:mod:`quarter_car_sim.full_car.preview_mpc`) instead of the LQ preview; it needs each
  corner's identified set (its force map).

:class:`PreviewOptions` holds the settings; :meth:`PreviewOptions.to_dict` is what the tools'
``--json`` reports with each row.
"""
import dataclasses

from quarter_car_sim.controllers.preview import (DEFAULT_PREVIEW_HORIZON_S,
                                                 DEFAULT_PREVIEW_STEP_S)
from quarter_car_sim.preview_sensor import (FedController, IDEAL_LOOK_AHEAD, PreviewFeed,
                                            REALISTIC_LOOK_AHEAD, REALISTIC_SPEED_ERROR,
                                            SpeedSignal)

#: Preview rows of the full car, in table order.
FULL_CAR_ROWS = ('preview-wheelbase', 'preview-look-ahead-ideal', 'preview-look-ahead',
                 'preview-mpc-look-ahead-ideal', 'preview-mpc-look-ahead')
#: Preview rows of the quarter car (no wheelbase: one wheel).
QUARTER_CAR_ROWS = ('preview-look-ahead-ideal', 'preview-look-ahead')


@dataclasses.dataclass(frozen=True)
class PreviewOptions:
    """
    Settings of the preview rows.

    Attributes
    ----------
    horizon_s, step_s : float
        Preview horizon and spacing of the previewed heights [s].
    sensor : LookAheadSpec
        The realistic row's sensor.
    speed_error : float
        Scale error of the realistic rows' speed signal (``preview-look-ahead`` and
        ``preview-wheelbase``) [-].
    seed : int
        Seed of the sensor's noise and dropouts.

    """

    horizon_s: float = DEFAULT_PREVIEW_HORIZON_S
    step_s: float = DEFAULT_PREVIEW_STEP_S
    sensor: object = REALISTIC_LOOK_AHEAD
    speed_error: float = REALISTIC_SPEED_ERROR
    seed: int = 1

    def row(self, name):
        """Return ``(sensor spec or None, speed scale error)`` of a row."""
        if name == 'preview-wheelbase':
            return None, self.speed_error
        if name.endswith('look-ahead-ideal') and name in FULL_CAR_ROWS:
            return IDEAL_LOOK_AHEAD, 0.0
        if name.endswith('look-ahead') and name in FULL_CAR_ROWS:
            return self.sensor, self.speed_error
        raise ValueError(f'unknown preview row {name!r} (use {", ".join(FULL_CAR_ROWS)})')

    def to_dict(self, name):
        """Return the settings of one row (JSON-ready)."""
        spec, err = self.row(name)
        out = {'source': 'wheelbase' if spec is None else 'look-ahead',
               'law': 'mpc' if is_mpc(name) else 'lq', 'horizon_s': self.horizon_s,
               'step_s': self.step_s, 'sensor': None if spec is None else spec.to_dict(),
               'speed_scale_error': err, 'seed': self.seed}
        if is_mpc(name):
            from quarter_car_sim.full_car.preview_mpc import DEFAULT_MPC
            out.update(horizon_s=DEFAULT_MPC['horizon_s'], step_s=None,
                       mpc={k: v for k, v in DEFAULT_MPC.items() if k != 'horizon_s'})
        return out


def is_mpc(name):
    """Return True for the MPC rows."""
    return name.startswith('preview-mpc-')


def quarter_car_preview_row(name, params, road, inverse, options=PreviewOptions(), *,
                            dt=1e-3):
    """
    Build a quarter-car preview row: ``clipped-optimal-wk`` with LQ preview, fed from ``road``.

    Parameters
    ----------
    name : str
        One of :data:`QUARTER_CAR_ROWS`.
    params : QuarterCarParams
        Car (the design's).
    road : RoadProfile
        The true road (with its speed).
    inverse : KwokCurrentInverse
        Identified model (the law's range clip, as ``clipped-optimal-wk``).
    options : PreviewOptions
        Settings.
    dt : float
        Control period [s].

    Returns
    -------
    FedController
        A controller for :func:`quarter_car_sim.simulate.simulate` (named ``name``).

    """
    from quarter_car_sim.controllers.optimal import ClippedOptimalWk, wk_lqr_design
    from quarter_car_sim.controllers.preview import (ClippedOptimalWkPreview,
                                                     quarter_car_lq_preview)
    from quarter_car_sim.road_preview import RoadPreview
    if name not in QUARTER_CAR_ROWS:
        raise ValueError(f'unknown quarter-car preview row {name!r} (use '
                         f'{", ".join(QUARTER_CAR_ROWS)})')
    spec, err = options.row(name)
    design = wk_lqr_design(params)
    base = ClippedOptimalWk(design, None if inverse is None else inverse.body_force_range,
                            dt=dt)
    preview = quarter_car_lq_preview(design, params, options.horizon_s, options.step_s)
    rp = RoadPreview(1, [(0, 0.0)])
    law = ClippedOptimalWkPreview(base, preview, rp, name=name)
    return FedController(law, PreviewFeed(rp, road, spec, SpeedSignal(err), rng=options.seed))


def full_car_preview_row(name, params, road, options=PreviewOptions(), *, dt=1e-3,
                         damper=None):
    """
    Build a full-car preview row: ``full-car-clipped-optimal-wk`` with LQ preview, fed by ``road``.

    Parameters
    ----------
    name : str
        One of :data:`FULL_CAR_ROWS`.
    params : FullCarParams
        Car.
    road : TwoTrackRoad
        The true road (with its speed).
    options, dt
        As :func:`quarter_car_preview_row`.
    damper : sequence of 4, optional
        Each corner's identified set (``fl, fr, rl, rr``; the MPC rows' force maps,
        :func:`~quarter_car_sim.full_car.bound.corner_force_model`).

    Returns
    -------
    quarter_car_sim.full_car.preview.FedFullCarLaw
        A law for :func:`quarter_car_sim.full_car.simulate.simulate_full_car` (named ``name``).

    """
    from quarter_car_sim.full_car.preview import FedFullCarLaw, make_full_car_preview_law
    spec, err = options.row(name)
    if is_mpc(name):
        from quarter_car_sim.full_car.bound import corner_force_model
        from quarter_car_sim.full_car.preview_mpc import make_full_car_mpc_preview
        if damper is None or len(damper) != 4:
            raise ValueError(f'{name} needs the four corners\' identified sets')
        law = make_full_car_mpc_preview(params, [corner_force_model(d, params) for d in damper],
                                        dt=dt, name=name)
    else:
        law = make_full_car_preview_law(params,
                                        source='wheelbase' if spec is None else 'look-ahead',
                                        horizon_s=options.horizon_s, step_s=options.step_s,
                                        dt=dt, name=name)
    return FedFullCarLaw(law, PreviewFeed(law.road, road, spec, SpeedSignal(err),
                                          rng=options.seed))
