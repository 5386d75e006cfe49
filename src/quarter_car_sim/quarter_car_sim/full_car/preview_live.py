"""
Road preview on the nodes (issue 36): the car's look-ahead sensor, the controller's input.

Two ROS-free objects, one per side of the ``full_car/road_preview`` topic
(``mr_damper_interfaces/RoadPreview``, converted by :mod:`mr_damper_common.messages`):

- :class:`SimulatedLookAhead` (``full_car_node``): the frames a look-ahead sensor of
  :class:`~quarter_car_sim.preview_sensor.LookAheadSpec` delivers from the car's true road, each
  numbered by its place in the sensor's schedule (a frame the sensor lost leaves a gap in the
  numbers) and sent with the car's speed signal (:class:`~quarter_car_sim.preview_sensor.
  SpeedSignal`, its scale error);
- :class:`PreviewControllerCore` (``full_car_controller_node``): the four-corner controller
  core (:class:`~quarter_car_sim.full_car.controller_core.FullCarControllerCore`) running the
  LQ preview law (:class:`~quarter_car_sim.full_car.preview.FullCarPreviewLaw`, look-ahead)
  with a :class:`PreviewInput` between the topic and the law's road map.

:class:`PreviewInput` takes the decoded messages in any thread order and hands them to the
map only at a control step whose state is at least as new as the frame's stamp (so a frame
never lands ahead of the odometer); the speed signal is held between messages and integrated
at each step's stamp. Refused and counted: a repeated or older sequence number, a frame older
than ``max_age_s`` when its step comes (stale), a stamp more than ``FUTURE_S`` ahead of the
car, a non-finite speed, more than ``max_pending`` frames waiting. The preview is **usable**
while the newest frame the map took is at most ``timeout_s`` old; otherwise (no frame yet, a
dropout, invalid or stale frames) the law runs without preview for that step and the reason is
counted; the law itself also falls back when the map does not reach under a wheel. Every force
still goes through each corner's inverse and supervisor (the core's controller).
"""
import collections
import math

from mr_damper_common.sequence import SequenceTracker
from quarter_car_sim.full_car.controller_core import FullCarControllerCore
from quarter_car_sim.full_car.preview import make_full_car_preview_law
from quarter_car_sim.preview_sensor import LookAheadSensor, LookAheadSpec, SpeedSignal
from quarter_car_sim.road_preview import PreviewFrame

#: Live law names of ``full_car_controller_node`` that take the road-preview topic.
LIVE_PREVIEW_LAWS = ('preview-look-ahead',)
#: A frame stamped further ahead of the car's state than this is refused [s].
FUTURE_S = 1.0


class SimulatedLookAhead:
    """
    A look-ahead sensor on the simulated car: numbered frames of the true road, with the speed.

    Parameters
    ----------
    spec : LookAheadSpec
        Sensor and its errors.
    road : TwoTrackRoad
        The car's true road (with its speed).
    speed_error : float
        Scale error of the car's speed signal [-].
    rng : int
        Seed of the sensor's noise and dropouts.
    start_s : float
        No frame is measured before this time [s] (the road starts at 0; before it the car
        settles).

    """

    def __init__(self, spec, road, *, speed_error=0.0, rng=1, start_s=0.0):
        self.sensor = LookAheadSensor(spec, road, rng)
        self.speed_signal = SpeedSignal(speed_error)
        self.true_speed = float(road.speed_m_s)
        self.start_s = float(start_s)
        self._t0 = None

    @property
    def speed_m_s(self):
        """The speed signal [m/s] (the true speed times ``1 + speed_error``)."""
        return self.speed_signal.read(self.true_speed)

    def frames(self, t, pitch=0.0):
        """
        Return the frames delivered by time ``t`` [s] as ``(sequence, PreviewFrame)`` pairs.

        Called once per control step with ``t`` increasing; ``pitch`` is the body pitch now
        [rad] (the sensor's pitch error). The first frame (sequence 1) is measured at the first
        call at or after ``start_s``.
        """
        if t < self.start_s:
            return []
        if self._t0 is None:
            self._t0 = t
        period = self.sensor.period
        return [(int(round((f.stamp - self._t0) / period)) + 1, f)
                for f in self.sensor.frames_until(t, pitch)]

    def status(self):
        """Sensor counters (JSON-ready): frames measured, lost, in outage, delivered."""
        return dict(self.sensor.counts)


def simulated_look_ahead(settings, road):
    """
    Build the car's :class:`SimulatedLookAhead` from ``full_car_node``'s parameters.

    Parameters
    ----------
    settings : dict
        ``preview_near_m``, ``preview_far_m``, ``preview_point_spacing_m``,
        ``preview_rate_hz``, ``preview_latency_s``, ``preview_height_noise_m``,
        ``preview_height_bias_m``, ``preview_pitch_error_gain``, ``preview_dropout_prob``,
        ``preview_outage_start_s``, ``preview_outage_s`` (0: no outage), ``preview_seed`` and
        ``speed_error`` (SI, as the node's parameter table).
    road : TwoTrackRoad
        The car's road.

    Returns
    -------
    SimulatedLookAhead

    Raises
    ------
    ValueError
        Settings the sensor model refuses (e.g. near >= far).

    """
    g = settings.get
    start, length = float(g('preview_outage_start_s', 0.0)), float(g('preview_outage_s', 0.0))
    spec = LookAheadSpec(
        range_m=(float(g('preview_near_m', 0.5)), float(g('preview_far_m', 15.0))),
        point_spacing_m=float(g('preview_point_spacing_m', 0.1)),
        rate_hz=float(g('preview_rate_hz', 18.0)), latency_s=float(g('preview_latency_s', 0.0)),
        height_noise_m=float(g('preview_height_noise_m', 0.0)),
        height_bias_m=float(g('preview_height_bias_m', 0.0)),
        pitch_error_gain=float(g('preview_pitch_error_gain', 0.0)),
        dropout_prob=float(g('preview_dropout_prob', 0.0)),
        outages=((start, start + length),) if length > 0 else ())
    return SimulatedLookAhead(spec, road, speed_error=float(g('speed_error', 0.0)),
                              rng=int(g('preview_seed', 1)))


class PreviewInput:
    """
    Between the road-preview topic and a law's road map (see the module docstring).

    Parameters
    ----------
    road : RoadPreview
        The law's road preview (odometer and map).
    timeout_s : float
        The preview is usable while the newest frame taken is at most this old [s].
    max_age_s : float
        A frame older than this at its step is stale (refused) [s].
    max_pending : int
        Frames waiting for their step at most (the oldest is dropped, counted).

    """

    def __init__(self, road, *, timeout_s=0.25, max_age_s=0.1, max_pending=32):
        for name, value in (('timeout_s', timeout_s), ('max_age_s', max_age_s)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be > 0, got {value}')
        if int(max_pending) < 1:
            raise ValueError(f'`max_pending` must be >= 1, got {max_pending}')
        self.road = road
        self.timeout_s, self.max_age_s = float(timeout_s), float(max_age_s)
        self.max_pending = int(max_pending)
        self.sequence = SequenceTracker()
        self._pending = collections.deque()
        self._speed = math.nan
        self.last_frame_stamp = None
        self.usable = False
        self.refused = collections.Counter()
        self.fallback = collections.Counter()

    def offer(self, fields):
        """
        Take one decoded message (:func:`mr_damper_common.messages.road_preview_fields`).

        Returns
        -------
        bool
            False when refused (counted in ``refused``); True when it waits for its step.

        """
        if self.sequence.offer(fields['sequence']) < 0:
            self.refused['sequence'] += 1
            return False
        speed = fields['speed_m_s']
        if math.isfinite(speed) and speed >= 0.0:
            self._speed = float(speed)
            if math.isnan(self.road.speed) and math.isfinite(fields['stamp']):
                self.road.offer_speed(fields['stamp'], self._speed)   # odometer starts here
        else:
            self.refused['speed'] += 1
        if not fields['valid']:
            self.refused['invalid'] += 1
            return False
        if len(self._pending) >= self.max_pending:
            self._pending.popleft()
            self.refused['overflow'] += 1
        self._pending.append(PreviewFrame(fields['stamp'], fields['distance_m'],
                                          fields['heights_m'], True))
        return True

    def refuse(self, reason):
        """Count a message that could not be decoded (``reason``, e.g. ``'layout'``)."""
        self.refused[str(reason)] += 1

    def before_step(self, t):
        """
        Bring the map to the step at ``t`` [s]; return True when the preview is usable.

        The held speed is integrated to ``t``, the frames stamped at or before ``t`` go to the
        map (stale ones are refused), and the reason of a fallback is counted.
        """
        if math.isfinite(self._speed):
            self.road.offer_speed(t, self._speed)
        keep = collections.deque()
        while self._pending:
            frame = self._pending.popleft()
            if frame.stamp > t + FUTURE_S or not math.isfinite(frame.stamp):
                self.refused['future'] += 1
            elif frame.stamp > t:
                keep.append(frame)
            elif t - frame.stamp > self.max_age_s:
                self.refused['stale'] += 1
            elif self.road.offer_frame(frame):
                if self.last_frame_stamp is None or frame.stamp > self.last_frame_stamp:
                    self.last_frame_stamp = frame.stamp
            else:
                self.refused['map'] += 1        # the map's own reason is in its counters
        self._pending = keep
        if self.last_frame_stamp is None:
            self.usable = False
            self.fallback['no_frame_yet'] += 1
        else:
            self.usable = t - self.last_frame_stamp <= self.timeout_s
            if not self.usable:
                self.fallback['timeout'] += 1
        return self.usable

    def status(self):
        """Counters (JSON-ready)."""
        return {'messages': self.sequence.status(), 'refused': dict(self.refused),
                'fallback': dict(self.fallback), 'usable': self.usable,
                'pending': len(self._pending), 'last_frame_stamp': self.last_frame_stamp,
                'speed_m_s': self._speed}


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
        Preview horizon and tap spacing [s] (:func:`~quarter_car_sim.full_car.preview.
        make_full_car_preview_law`).
    preview_timeout_s, preview_max_age_s : float
        :class:`PreviewInput`'s ``timeout_s`` and ``max_age_s`` [s].
    **supervisor_settings
        As :class:`~quarter_car_sim.full_car.controller_core.FullCarControllerCore`.

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
        """Take one decoded road-preview message (:meth:`PreviewInput.offer`)."""
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
