"""
The simulated car's look-ahead sensor on the nodes (issue 36), for ``full_car_node``.

:class:`SimulatedLookAhead` gives the frames a look-ahead sensor of
:class:`~quarter_car_sim.plant.preview_sensor.LookAheadSpec` delivers from the car's true road,
each numbered by its place in the sensor's schedule (a frame the sensor lost leaves a gap in
the numbers) and sent with the car's speed signal
(:class:`~quarter_car_sim.plant.preview_sensor.SpeedSignal`, its scale error), for the
``full_car/road_preview`` topic (``mr_damper_interfaces/RoadPreview``, converted by
:mod:`mr_damper_common.messages`). The controller's side of the topic is
:class:`semi_active_control.estimation.preview_input.PreviewInput`.
"""
from quarter_car_sim.plant.preview_sensor import LookAheadSensor, LookAheadSpec, SpeedSignal


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
