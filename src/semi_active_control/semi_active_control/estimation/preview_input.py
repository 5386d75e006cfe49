"""
The road-preview topic's input of a controller (issue 36): frames to the law's road map.

:class:`PreviewInput` takes the decoded ``full_car/road_preview`` messages
(``mr_damper_interfaces/RoadPreview``, converted by :mod:`mr_damper_common.messages`) in any
thread order and hands them to the map only at a control step whose state is at least as new
as the frame's stamp (so a frame never lands ahead of the odometer); the speed signal is held
between messages and integrated at each step's stamp. Refused and counted: a repeated or older
sequence number, a frame older than ``max_age_s`` when its step comes (stale), a stamp more
than ``FUTURE_S`` ahead of the car, a non-finite speed, more than ``max_pending`` frames
waiting. The preview is **usable** while the newest frame the map took is at most
``timeout_s`` old; otherwise (no frame yet, a dropout, invalid or stale frames) the law runs
without preview for that step and the reason is counted.
"""
import collections
import math

from mr_damper_common.sequence import SequenceTracker
from semi_active_control.estimation.road_preview import PreviewFrame

#: A frame stamped further ahead of the car's state than this is refused [s].
FUTURE_S = 1.0


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
