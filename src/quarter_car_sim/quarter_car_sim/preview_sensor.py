"""
Look-ahead road sensor and vehicle speed signal, simulated from the true road (issue 36).

The simulator's side of road preview: :class:`LookAheadSensor` makes the frames a production
stereo camera gives (:class:`quarter_car_sim.road_preview.PreviewFrame`: a height profile per
track from ``range_m[0]`` to ``range_m[1]`` ahead of the front axle, ``rate_hz`` frames a
second) from the road the car drives, with the errors of :class:`LookAheadSpec`;
:class:`SpeedSignal` the vehicle speed with its scale error. :class:`PreviewFeed` delivers both
to a law's :class:`~quarter_car_sim.road_preview.RoadPreview` at each control step, as a node
would from its topics.

Error model (each off in :data:`IDEAL_LOOK_AHEAD`):

- **latency** ``latency_s``: a frame measured at ``t`` (its stamp) arrives at ``t + latency``;
- **height noise** ``height_noise_m`` (white, RMS per point) and **bias** ``height_bias_m``
  (one offset for the run, e.g. a camera height calibration error);
- **longitudinal position**: the speed signal's scale error ``SpeedSignal.scale_error`` (the
  odometer places every point and the rear wheels by distance), and the uncompensated body
  pitch ``pitch_error_gain * theta``: a camera ``camera_height_m`` above the road, tilted by a
  small angle ``e``, puts a road point at distance ``D`` at ``D + D^2 e / h`` and ``D e`` too
  high (flat-road geometry);
- **dropouts**: each frame lost with probability ``dropout_prob``, and whole outages
  (``outages``: ``(start, end)`` times [s]) in which the sensor reports invalid frames.

Defaults and their sources (:data:`REALISTIC_LOOK_AHEAD`):

- range 0.5-15 m: Mercedes-Benz Magic Body Control, "ROAD SURFACE SCAN ... measures the road up
  to 15 metres in front of the vehicle", up to 130 km/h
  (https://www.mercedes-benz.com/en/mercedes-benz/innovation/magic-body-control/); the
  development system scanned 4.5-14 m ahead (Mercedes' J. Haab in carsales.com.au, "Magic ride
  for new S-Class"); 0.5 m is the issue's near end;
- 18 frames a second: Audi A8 predictive active suspension, "the camera generates information
  about the surface properties 18 times a second" (Audi press release, 18 Jul 2019); BMW's
  Executive Drive Pro uses its KAFAS stereo camera with the EDC semi-active dampers at about
  15-100 km/h (BMW G12 technical training manual, "Detection of the road condition");
- 3 mm RMS height noise: stereo road-surface reconstruction "accuracy is around 3 mm" (Fan et
  al., "Real-time stereo vision for road surface 3-D reconstruction", 2018, arXiv:1807.07433);
  a production multi-purpose camera was worse, 1.2 cm at 5-8 m (Shen et al. 2014, cited by
  Deigmoeller et al., "Road surface scanning using stereo cameras for motorcycles", VISAPP
  2018, whose own method reaches millimetres in a single frame);
- 20 ms latency and a 2 % speed error: the figures of issue 36's realistic case (a frame is
  processed within its 56 ms period; a wheel-speed odometer is off by the tyre's rolling
  radius, which changes with load, pressure and wear by a few per cent).
"""
import dataclasses
import math

import numpy as np

from quarter_car_sim.road_preview import PreviewFrame


@dataclasses.dataclass(frozen=True)
class LookAheadSpec:
    """
    A look-ahead road sensor (see the module docstring for the error model and sources).

    Attributes
    ----------
    range_m : (float, float)
        Nearest and farthest distance ahead of the front axle [m].
    point_spacing_m : float
        Distance between the profile's points [m].
    rate_hz : float
        Frames per second.
    latency_s : float
        Delay from measurement (the stamp) to delivery [s].
    height_noise_m : float
        RMS white noise on each height [m].
    height_bias_m : float
        Constant height offset [m].
    pitch_error_gain : float
        Fraction of the body pitch the sensor does not compensate [-] (0: compensated).
    camera_height_m : float
        Camera height above the road [m] (pitch geometry).
    dropout_prob : float
        Probability that a frame is lost [-].
    outages : tuple of (float, float)
        Intervals [s] in which the sensor reports invalid frames.

    """

    range_m: tuple = (0.5, 15.0)
    point_spacing_m: float = 0.1
    rate_hz: float = 18.0
    latency_s: float = 0.0
    height_noise_m: float = 0.0
    height_bias_m: float = 0.0
    pitch_error_gain: float = 0.0
    camera_height_m: float = 1.3
    dropout_prob: float = 0.0
    outages: tuple = ()

    def __post_init__(self):
        near, far = (float(v) for v in self.range_m)
        if not (0.0 <= near < far and math.isfinite(far)):
            raise ValueError(f'`range_m` must be 0 <= near < far, got {self.range_m}')
        checks = {'point_spacing_m': self.point_spacing_m > 0, 'rate_hz': self.rate_hz > 0,
                  'latency_s': self.latency_s >= 0, 'height_noise_m': self.height_noise_m >= 0,
                  'camera_height_m': self.camera_height_m > 0,
                  'dropout_prob': 0 <= self.dropout_prob <= 1}
        for name, ok in checks.items():
            if not (ok and math.isfinite(getattr(self, name))):
                raise ValueError(f'`{name}` out of range: {getattr(self, name)}')
        for name in ('height_bias_m', 'pitch_error_gain'):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f'`{name}` must be finite')

    def to_dict(self):
        """Return the settings (JSON-ready)."""
        d = dataclasses.asdict(self)
        d['range_m'] = list(self.range_m)
        d['outages'] = [list(o) for o in self.outages]
        return d


#: A perfect look-ahead sensor: exact heights, no latency, no frame lost (range and rate of
#: the production systems).
IDEAL_LOOK_AHEAD = LookAheadSpec()

#: Issue 36's realistic case: 20 ms latency, 3 mm RMS height noise (with the 2 % speed error
#: of :data:`REALISTIC_SPEED_ERROR` on the speed signal).
REALISTIC_LOOK_AHEAD = LookAheadSpec(latency_s=0.02, height_noise_m=0.003)

#: Scale error of the realistic speed signal [-].
REALISTIC_SPEED_ERROR = 0.02


class SpeedSignal:
    """
    Vehicle speed as a car measures it: the true speed times ``1 + scale_error``.

    Parameters
    ----------
    scale_error : float
        Relative error [-] (0.02: reads 2 % fast).

    """

    def __init__(self, scale_error=0.0):
        self.scale_error = float(scale_error)
        if not (math.isfinite(self.scale_error) and self.scale_error > -1.0):
            raise ValueError(f'`scale_error` must be > -1, got {scale_error}')

    def read(self, true_speed_m_s):
        """Return the measured speed [m/s]."""
        return true_speed_m_s * (1.0 + self.scale_error)


class TrackTimeline:
    """
    The true road as a function of distance ahead of the front axle, per track.

    Parameters
    ----------
    t : ndarray with shape (n,)
        Track time [s] (uniform).
    heights : ndarray with shape (tracks, n)
        Track heights [m].
    speed_m_s : float
        Speed [m/s] (distance = speed x track time).
    front_lead_s : float
        Track time of the front axle ahead of the simulation's time [s] (the two-track road's
        ``delay_s``; 0 for a quarter car).

    """

    def __init__(self, t, heights, speed_m_s, front_lead_s=0.0):
        self.t = np.asarray(t, dtype=float)
        self.heights = np.atleast_2d(np.asarray(heights, dtype=float))
        self.speed = float(speed_m_s)
        if not (math.isfinite(self.speed) and self.speed > 0.0):
            raise ValueError('the road has no speed: a look-ahead sensor needs one')
        self.lead = float(front_lead_s)

    @classmethod
    def of(cls, road):
        """Timeline of a quarter-car ``RoadProfile`` or a full-car ``TwoTrackRoad``."""
        if hasattr(road, 'z_left'):
            return cls(road.t, np.vstack([road.z_left, road.z_right]), road.speed_m_s,
                       road.delay_s)
        return cls(road.t, road.z[None, :], road.speed_m_s)

    @property
    def n_tracks(self):
        """Number of tracks."""
        return self.heights.shape[0]

    def ahead(self, t, distance_m):
        """Heights (tracks, m) at distances ahead of the front axle at time ``t``."""
        s = t + self.lead + np.asarray(distance_m, dtype=float) / self.speed
        return np.vstack([np.interp(s, self.t, h) for h in self.heights])


class LookAheadSensor:
    """
    Frames of a look-ahead sensor from the true road and the car's pitch.

    Parameters
    ----------
    spec : LookAheadSpec
        Sensor.
    road : RoadProfile or TwoTrackRoad
        The true road (with its speed).
    rng : int or numpy.random.Generator
        Seed of the noise and the dropouts.

    """

    def __init__(self, spec, road, rng=1):
        self.spec = spec
        self.timeline = TrackTimeline.of(road)
        self.rng = np.random.default_rng(rng)
        near, far = spec.range_m
        m = int(math.floor((far - near) / spec.point_spacing_m + 1e-9)) + 1
        self.distance = near + spec.point_spacing_m * np.arange(m)
        self.period = 1.0 / spec.rate_hz
        self.reset()

    def reset(self, t0=None):
        """Restart the frame schedule (the first frame at ``t0``, default the first call)."""
        self._t0, self._k = t0, 0
        self._pending = []
        self.counts = {'measured': 0, 'lost': 0, 'outage': 0, 'delivered': 0}

    def _measure(self, t, pitch):
        sp = self.spec
        e = sp.pitch_error_gain * pitch
        d_true = self.distance + self.distance ** 2 * e / sp.camera_height_m
        z = self.timeline.ahead(t, d_true) + sp.height_bias_m + self.distance * e
        if sp.height_noise_m > 0.0:
            z = z + self.rng.normal(0.0, sp.height_noise_m, z.shape)
        return z

    def frames_until(self, t, pitch=0.0):
        """
        Measure the frames due up to time ``t`` and return those delivered by ``t``.

        Parameters
        ----------
        t : float
            Present time [s] (called once per control step, ``t`` increasing).
        pitch : float
            Body pitch now [rad] (nose down +), for the pitch error.

        Returns
        -------
        list of PreviewFrame

        """
        sp = self.spec
        if self._t0 is None:
            self._t0 = t
        while self._t0 + self._k * self.period <= t + 1e-12:
            ts = self._t0 + self._k * self.period        # the k-th frame (no summed drift)
            self._k += 1
            self.counts['measured'] += 1
            if any(a <= ts < b for a, b in sp.outages):
                self.counts['outage'] += 1
                frame = PreviewFrame(ts, self.distance,
                                     np.full((self.timeline.n_tracks, self.distance.size),
                                             math.nan), valid=False)
            elif sp.dropout_prob > 0.0 and self.rng.random() < sp.dropout_prob:
                self.counts['lost'] += 1
                continue
            else:
                frame = PreviewFrame(ts, self.distance, self._measure(ts, pitch))
            self._pending.append((ts + sp.latency_s, frame))
        out = [f for ta, f in self._pending if ta <= t + 1e-12]
        self._pending = [(ta, f) for ta, f in self._pending if ta > t + 1e-12]
        self.counts['delivered'] += len(out)
        return out


class PreviewFeed:
    """
    What a node does with the preview topics, offline: speed and frames into a road preview.

    Called once per control step before the law (:meth:`feed`); the frames are measured at the
    sensor's own times (the body pitch of the step in which they fall).

    Parameters
    ----------
    road_preview : quarter_car_sim.road_preview.RoadPreview
        The law's road preview.
    road : RoadProfile or TwoTrackRoad
        The true road (its speed is the true speed).
    sensor : LookAheadSpec, optional
        Look-ahead sensor (None: speed only, e.g. for wheelbase preview).
    speed_signal : SpeedSignal, optional
        Speed signal (default exact).
    rng : int
        Seed of the sensor.

    """

    def __init__(self, road_preview, road, sensor=None, speed_signal=None, rng=1):
        self.road_preview = road_preview
        self.speed = float(road.speed_m_s)
        if not (math.isfinite(self.speed) and self.speed > 0.0):
            raise ValueError('the road has no speed: road preview needs one')
        self.speed_signal = speed_signal or SpeedSignal()
        self.sensor = None if sensor is None else LookAheadSensor(sensor, road, rng)

    def reset(self):
        """Restart the sensor (the road preview is the law's to reset)."""
        if self.sensor is not None:
            self.sensor.reset()

    def feed(self, t, pitch=0.0):
        """Deliver the speed sample and the frames due at time ``t`` [s]."""
        rp = self.road_preview
        rp.offer_speed(t, self.speed_signal.read(self.speed))
        if self.sensor is not None:
            for frame in self.sensor.frames_until(t, pitch):
                rp.offer_frame(frame)

    def status(self):
        """Sensor counters (JSON-ready)."""
        return {} if self.sensor is None else dict(self.sensor.counts)


class FedController:
    """
    A quarter-car preview law fed by a :class:`PreviewFeed` before each of its steps (offline).

    Parameters
    ----------
    law : quarter_car_sim.controllers.preview.ClippedOptimalWkPreview
        The law (its ``road`` is the feed's road preview).
    feed : PreviewFeed
        Speed and frames of the true road.

    """

    kind = 'semi-active'

    def __init__(self, law, feed):
        if feed.road_preview is not law.road:
            raise ValueError('the feed must feed the law\'s own road preview')
        self.law, self.feed = law, feed
        self.name = law.name
        self.state_fields = getattr(law, 'state_fields', ())

    def reset(self):
        """Reset the law and the sensor."""
        self.law.reset()
        self.feed.reset()

    def demand(self, state):
        """Feed the speed and the frames due now, then return the law's demand [N]."""
        self.feed.feed(state.t)
        return self.law.demand(state)

    def status(self):
        """Law counters, road-preview counters and sensor counters (JSON-ready)."""
        return {'law': self.law.stats.as_dict(), 'road_preview': self.law.road.status(),
                'sensor_frames': self.feed.status()}
