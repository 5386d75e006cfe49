"""
Road preview on the vehicle: odometer, look-ahead frames, a road map by distance, preview windows.

What a car knows of the road ahead (issue 36), ROS-free, fed per step by a node or an offline
loop:

- :meth:`RoadPreview.offer_speed`: the vehicle speed signal [m/s] (wheel speeds / CAN); the
  odometer integrates it, so a speed error becomes a position error of everything placed by
  distance (the wheelbase delay, the look-ahead points);
- :meth:`RoadPreview.offer_frame`: a look-ahead :class:`PreviewFrame` (a stereo camera's height
  profile per track at distances ahead of the front axle, stamped with its measurement time):
  each point goes to the odometer position the front axle had at the stamp plus its distance;
- :meth:`RoadPreview.offer_axle_road`: the road height under the front wheels at a time (the
  wheelbase preview's estimate, :class:`FrontRoadEstimate`), placed at the front axle.

The map holds one height profile per track on a grid of ``spacing_m`` (a ring buffer
``behind_m`` behind and ``ahead_m`` ahead of the front axle). A look-ahead sensor sees each
road point in many frames (15 m of range, about 1.1 m driven between frames at 20 m/s and
18 Hz: some 13 times); each cell keeps a running mean of its observations, the newest
weighted ``1 / min(n, fuse)``, so the frames' independent height noise averages out. The
memory is short (``fuse`` 4) because a speed-signal error places the same road point a little
further on in each frame (2 % of the distance driven between them): on the full car with the
MPC, 3 s of ISO C at 20 m/s, 3 mm noise and a 2 % speed error, a_v 0.500 / 0.479 / 0.479 /
0.495 / 0.502 with ``fuse`` 1 / 2 / 4 / 8 / 16 (3 mm noise alone: 0.508 / 0.485 / 0.470 /
0.464 / 0.463; no error: 0.458). The wheelbase estimate is written as it is.
:meth:`RoadPreview.window` samples the map for each wheel (front axle at distance 0, rear at
``-wheelbase``) at the times ``t + j h`` ahead, the spacing from the speed signal. A
window is valid when the road under every wheel is in the map; beyond the measured part the
last measured height is held (no road velocity), which is also what the preview law assumes
after its horizon. Nothing here knows the true road.

Bad input is refused and counted (``status()``): a frame with a stamp ahead of the odometer's
clock or older than its history, non-increasing distances, a wrong track count, an invalid
frame; non-finite points are skipped (counted); a non-finite speed is ignored (counted).
"""
import collections
import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True)
class PreviewFrame:
    """
    One look-ahead frame: road heights per track at distances ahead of the front axle.

    Attributes
    ----------
    stamp : float
        Measurement time [s] (the frame arrives later: the sensor's latency).
    distance_m : ndarray with shape (m,)
        Distances ahead of the front axle at the stamp [m], increasing.
    heights_m : ndarray with shape (tracks, m)
        Road height of each track (left, right; one track for a quarter car) [m], up +; NaN
        where not measured.
    valid : bool
        The sensor's own validity flag (False: blinded, no profile).

    """

    stamp: float
    distance_m: np.ndarray
    heights_m: np.ndarray
    valid: bool = True


class FrontRoadEstimate:
    """
    Road height under each front wheel from the state a law already reads (wheelbase preview).

    The tyre's kinematics: ``d = z_u - z_r`` (tyre deflection, a state of the LQR laws) and the
    wheel's absolute velocity ``v_u`` give ``z_r = integral(v_u) - d``. The integral drifts with
    a velocity error; the preview laws only use height differences over their horizon (their
    FIR taps sum to zero), and a leak with time constant ``leak_s`` keeps the drift bounded.
    Exact on the true state (to the trapezoidal rule); on an estimated state it is as good as
    the estimate of ``v_u`` and ``d``.

    Parameters
    ----------
    n_wheels : int
        Wheels (front axle: 2; quarter car: 1).
    leak_s : float
        Time constant of the integral's leak [s] (inf: none).

    """

    def __init__(self, n_wheels, *, leak_s=10.0):
        self.n = int(n_wheels)
        self.leak_s = float(leak_s)
        if not self.leak_s > 0.0:
            raise ValueError(f'`leak_s` must be > 0, got {leak_s}')
        self.reset()

    def reset(self):
        """Forget the integral."""
        self._t = None
        self._zu = np.zeros(self.n)
        self._vu = np.zeros(self.n)
        self.rejected = 0

    def update(self, t, v_u, tyre_deflection):
        """
        Return the road heights under the wheels at ``t`` [m], or None (bad sample).

        Parameters
        ----------
        t : float
            Time [s]; a time that does not advance does not integrate again.
        v_u : array_like with shape (n_wheels,)
            Wheel vertical velocities [m/s].
        tyre_deflection : array_like with shape (n_wheels,)
            ``z_u - z_r`` [m].

        """
        vu = np.asarray(v_u, dtype=float).reshape(self.n)
        d = np.asarray(tyre_deflection, dtype=float).reshape(self.n)
        if not (math.isfinite(t) and np.all(np.isfinite(vu)) and np.all(np.isfinite(d))):
            self.rejected += 1
            return None
        if self._t is None:
            self._zu = d.copy()                 # start on a road at height 0
        elif t > self._t:
            h = t - self._t
            decay = math.exp(-h / self.leak_s) if math.isfinite(self.leak_s) else 1.0
            self._zu = decay * self._zu + 0.5 * h * (vu + self._vu)
        self._t, self._vu = t, vu
        return self._zu - d


class RoadPreview:
    """
    Odometer and road map of a car: what the preview laws know of the road ahead.

    Parameters
    ----------
    n_tracks : int
        Tracks (2: left, right; 1: a quarter car).
    wheels : sequence of (int, float)
        Per wheel, its track and its position along the car from the front axle [m] (0 front,
        ``-wheelbase`` rear), in the order the law's taps expect.
    spacing_m : float
        Grid spacing of the map [m].
    behind_m, ahead_m : float
        Extent of the map behind and ahead of the front axle [m].
    history_s : float
        Odometer history kept to place frames by their stamps [s] (longer than the latency).
    fuse : int
        Observations of a cell averaged (running mean over at most ``fuse``; 1: the newest
        frame only).

    """

    def __init__(self, n_tracks, wheels, *, spacing_m=0.02, behind_m=4.0, ahead_m=20.0,
                 history_s=2.0, fuse=4):
        self.fuse = int(fuse)
        if self.fuse < 1:
            raise ValueError(f'`fuse` must be >= 1, got {fuse}')
        self.n_tracks = int(n_tracks)
        self.wheels = [(int(k), float(a)) for k, a in wheels]
        if self.n_tracks < 1 or not self.wheels:
            raise ValueError('`n_tracks` and `wheels` must not be empty')
        if any(not 0 <= k < self.n_tracks for k, _ in self.wheels):
            raise ValueError('a wheel\'s track is out of range')
        self.spacing_m = float(spacing_m)
        if not self.spacing_m > 0.0:
            raise ValueError(f'`spacing_m` must be > 0, got {spacing_m}')
        if -min(a for _, a in self.wheels) >= behind_m:
            raise ValueError('`behind_m` must reach behind the rearmost wheel')
        self.n_cells = int(math.ceil((behind_m + ahead_m) / self.spacing_m)) + 2
        self.history_s = float(history_s)
        self._tracks = np.array([k for k, _ in self.wheels])
        self._offsets = np.array([a for _, a in self.wheels])
        self.reset()

    def reset(self):
        """Forget the map, the odometer and the counters."""
        self._h = np.full((self.n_tracks, self.n_cells), math.nan)
        self._cell = np.full((self.n_tracks, self.n_cells), np.iinfo(np.int64).min,
                             dtype=np.int64)         # absolute cell index written, per cell
        self._n = np.zeros((self.n_tracks, self.n_cells))    # observations averaged
        self._odo = collections.deque()
        self._t = None
        self._x = 0.0
        self._v = math.nan
        self.counts = collections.Counter()

    # -- odometer -------------------------------------------------------------------------

    @property
    def speed(self):
        """Latest speed signal [m/s] (nan before the first)."""
        return self._v

    @property
    def position(self):
        """Odometer reading [m] (the front axle's position on the map)."""
        return self._x

    def offer_speed(self, t, v_m_s):
        """
        Take a speed sample [m/s] at time ``t`` [s]; the odometer integrates it (trapezoid).

        Returns
        -------
        bool
            False when refused (non-finite, negative, or a time going back).

        """
        if not (math.isfinite(t) and math.isfinite(v_m_s) and v_m_s >= 0.0):
            self.counts['speed_rejected'] += 1
            return False
        if self._t is not None:
            if t < self._t:
                self.counts['speed_rejected'] += 1
                return False
            self._x += 0.5 * (t - self._t) * (v_m_s + self._v)
        self._t, self._v = float(t), float(v_m_s)
        self._odo.append((self._t, self._x))
        while len(self._odo) > 2 and self._odo[1][0] < self._t - self.history_s:
            self._odo.popleft()
        return True

    def position_at(self, t):
        """Odometer reading at a past time ``t`` [s] (interpolated), or None if not known."""
        if self._t is None or t > self._t + 1e-9 or t < self._odo[0][0] - 1e-9:
            return None
        ts = [p[0] for p in self._odo]
        xs = [p[1] for p in self._odo]
        return float(np.interp(t, ts, xs))

    # -- map --------------------------------------------------------------------------------

    def _write(self, track, x, h):
        """Write heights ``h`` at positions ``x`` (increasing) of a track on the grid cells."""
        k0 = int(math.ceil(x[0] / self.spacing_m))
        k1 = int(math.floor(x[-1] / self.spacing_m))
        if k1 < k0:
            return 0
        k = np.arange(k0, k1 + 1)
        vals = np.interp(k * self.spacing_m, x, h)
        idx = k % self.n_cells
        seen = self._cell[track, idx] == k
        n = np.where(seen, np.minimum(self._n[track, idx] + 1.0, self.fuse), 1.0)
        old = np.where(seen, self._h[track, idx], vals)
        self._h[track, idx] = old + (vals - old) / n
        self._n[track, idx] = n
        self._cell[track, idx] = k
        return k.size

    def offer_frame(self, frame):
        """
        Place a look-ahead frame on the map.

        Returns
        -------
        bool
            True when taken; else the reason is counted in ``counts`` (``frame_invalid``,
            ``frame_future``, ``frame_too_old``, ``frame_bad_shape``, ``frame_no_speed``).

        """
        self.counts['frames'] += 1
        if not frame.valid:
            self.counts['frame_invalid'] += 1
            return False
        d = np.asarray(frame.distance_m, dtype=float).ravel()
        h = np.asarray(frame.heights_m, dtype=float)
        if (h.ndim != 2 or h.shape != (self.n_tracks, d.size) or d.size < 2
                or not np.all(np.isfinite(d)) or np.any(np.diff(d) <= 0.0)):
            self.counts['frame_bad_shape'] += 1
            return False
        if self._t is None:
            self.counts['frame_no_speed'] += 1
            return False
        if not math.isfinite(frame.stamp) or frame.stamp > self._t + 1e-9:
            self.counts['frame_future'] += 1
            return False
        x0 = self.position_at(frame.stamp)
        if x0 is None:
            self.counts['frame_too_old'] += 1
            return False
        for track in range(self.n_tracks):
            ok = np.isfinite(h[track])
            if not ok.all():
                self.counts['points_not_finite'] += int((~ok).sum())
            if ok.sum() >= 2:
                self._write(track, x0 + d[ok], h[track, ok])
        self.counts['frames_taken'] += 1
        return True

    def offer_axle_road(self, t, heights):
        """
        Place the road heights under the front axle at time ``t`` (one per track) on the map.

        The time must be the odometer's latest (the estimate of the present step).
        """
        z = np.asarray(heights, dtype=float).reshape(self.n_tracks)
        if self._t is None or not np.all(np.isfinite(z)) or abs(t - self._t) > 1e-9:
            self.counts['axle_road_rejected'] += 1
            return False
        k = int(round(self._x / self.spacing_m))
        idx = k % self.n_cells
        self._h[:, idx] = z
        self._n[:, idx] = 1.0
        self._cell[:, idx] = k
        # fill the cells the axle crossed since its last sample (linear in between)
        for track in range(self.n_tracks):
            j = k - 1
            while j > k - 64 and self._cell[track, j % self.n_cells] != j:
                j -= 1
            if self._cell[track, j % self.n_cells] == j and j < k - 1:
                ks = np.arange(j + 1, k)
                hj = self._h[track, j % self.n_cells]
                self._h[track, ks % self.n_cells] = hj + (z[track] - hj) * (ks - j) / (k - j)
                self._n[track, ks % self.n_cells] = 1.0
                self._cell[track, ks % self.n_cells] = ks
        return True

    def window(self, times_s):
        """
        Road heights under each wheel at the times ahead ``times_s`` (from now), or None.

        Parameters
        ----------
        times_s : array_like with shape (p,)
            Times ahead [s], increasing from 0.

        Returns
        -------
        ndarray with shape (p, n_wheels) or None
            Heights [m], linear between the map's cells and held beyond the last measured cell
            ahead of each wheel; None when the road under some wheel is not in the map (no
            speed yet, or the map does not reach it: a dropout longer than the map ahead).

        """
        if self._t is None:
            return None
        s = np.asarray(times_s, dtype=float)
        u = (self._x + self._offsets[:, None] + self._v * s[None, :]) / self.spacing_m
        k = np.floor(u).astype(np.int64)                          # (wheels, p)
        tr = self._tracks[:, None]
        ok0 = self._cell[tr, k % self.n_cells] == k
        if not ok0[:, 0].all():
            return None
        ok1 = self._cell[tr, (k + 1) % self.n_cells] == k + 1
        h0 = self._h[tr, k % self.n_cells]
        h1 = self._h[tr, (k + 1) % self.n_cells]
        z = h0 + (u - k) * (h1 - h0)
        known = ok0 & ok1
        for w in np.flatnonzero(~known.all(axis=1)):
            j = int(np.argmin(known[w]))                        # first sample not between cells
            # hold the last cell measured without a gap from the wheel (the map's frontier)
            last = int(k[w, j]) if ok0[w, j] else int(k[w, j - 1]) + 1
            cells, track = self._cell[self._tracks[w]], self._tracks[w]
            while cells[(last + 1) % self.n_cells] == last + 1 and last < k[w, -1] + 1:
                last += 1
            z[w, j:] = self._h[track, last % self.n_cells]
        return z.T

    def status(self):
        """Counters (JSON-ready): frames taken and refused by reason, speed and points."""
        return dict(self.counts)
