"""
N cars of one :class:`~mr_damper_gym.model.CarModel` stepped together (numpy arrays + numba).

:class:`CarBatch` holds every car's state (mechanics, plants, ISO filters, running sums,
sensors, road) as arrays and advances the cars with the compiled step
(:func:`mr_damper_gym.kernel.advance_cars`). The single environment is a batch of one car; the
vector environment a batch of N. A car is reset on its own road (:meth:`CarBatch.reset_car`):
it settles for ``settle_s`` at a constant current on the road's first heights (as the offline
tools' ``settle_s``), then its filters and sums restart and its first sample (t = 0) is taken.

Random numbers of the sensors are drawn in numpy, per car from its own generator, in blocks of
:data:`DRAW_BLOCK` samples (the random-walk and noise normals and the loss uniform of each
sample), so the compiled step never touches a random state.
"""
from concurrent.futures import ThreadPoolExecutor
import math
import os

import numpy as np

from mr_damper_gym import kernel as K

#: Sensor samples whose random numbers are drawn at once.
DRAW_BLOCK = 1024
#: Cars from which a batch steps them on several threads by default.
PARALLEL_MIN = 8


class CarBatch:
    """
    The state of N cars and their step.

    Parameters
    ----------
    model : CarModel
        The car.
    n : int
        Number of cars.
    threads : int or None
        Threads that step the cars side by side, each a contiguous share of them (the
        compiled step releases the GIL); None: one per core from :data:`PARALLEL_MIN` cars
        on, else one.

    Attributes
    ----------
    obs : ndarray (n, nobs)
        Observation rows after the last step (true state, then sensors).
    reward : ndarray (n,)
        Reward of the last step.
    sums : ndarray (n, model.n_sums)
        Running sums since each car's t = 0 (:meth:`figures`).
    cmd : ndarray (n, nc)
        Current commands held over the last step [A].

    """

    def __init__(self, model, n=1, threads=None):
        m = model
        self.model = m
        self.n = int(n)
        if self.n < 1:
            raise ValueError(f'need at least one car, got {n}')
        # every car's state in one row of S (one array for the compiled step); the named
        # blocks are views into it
        self.S = np.zeros((self.n, m.width))

        def block(name, *shape):
            a, w = m.blocks[name]
            view = self.S[:, a:a + w].reshape((self.n,) + shape) if shape else self.S[:, a]
            assert np.shares_memory(view, self.S)
            return view

        self.x = block('x', m.nx)
        self.f = block('f', m.nc)
        self.clock = block('clock', 3)
        self.road_meta = block('road', 2)
        self.cmd = block('cmd', m.nc)
        self.plant = block('plant', m.nc, K.PL_N)
        self.filt = block('filt', m.nw, m.nsec, 2)
        self.sums = block('sums', m.n_sums)
        self.sens = block('sens', m.ns, m.sens_len)
        self.obs = block('obs', len(m.obs_names))
        self.reward = block('reward')
        self.road = np.zeros((self.n, 4 if m.nc > 1 else 2, 2))
        self.road_meta[:, K.RD_N] = 2.0
        self.draws = np.zeros((self.n, DRAW_BLOCK, m.ns, 3))
        self.rngs = [None] * self.n
        self._sensing = np.zeros(self.n, dtype=bool)
        self._left = 0          # steps every sensing car can take before a block refill
        self._all = np.ones(self.n, dtype=np.uint8)
        self._one = np.zeros(self.n, dtype=np.uint8)
        self._kernel = K.compiled_step()
        if threads is None:
            threads = (os.cpu_count() or 1) if self.n >= PARALLEL_MIN else 1
        self.threads = max(1, min(int(threads), self.n))
        self._pool = None
        if self.threads > 1:
            self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix='car_batch')
            bounds = np.linspace(0, self.n, self.threads + 1).astype(int)
            self._shares = [(a, b) for a, b in zip(bounds[:-1], bounds[1:])]

    # --- roads and resets ------------------------------------------------------------------
    def set_road(self, k, tracks, delay_s=0.0):
        """
        Give car ``k`` its road: a list of ``(z, zdot)`` arrays per track, sampled every dt.

        Quarter car: one track; full car: left and right as the rear axle meets them, the
        front wheels reading them ``delay_s`` [s] ahead (:class:`quarter_car_sim.plant.
        road.TwoTrackRoad`).
        """
        n = len(tracks[0][0])
        if n < 2:
            raise ValueError('a road needs at least 2 samples')
        if n > self.road.shape[2]:
            grown = np.zeros((self.n, self.road.shape[1], n))
            grown[:, :, :self.road.shape[2]] = self.road
            self.road = grown
        for j, (z, zd) in enumerate(tracks):
            self.road[k, 2 * j, :n] = z
            self.road[k, 2 * j + 1, :n] = zd
        self.road_meta[k, K.RD_N] = n
        self.road_meta[k, K.RD_DELAY] = delay_s

    def reset_car(self, k, x0, t0, *, settle_steps, settle_current, rng=None):
        """
        Reset car ``k`` at rest on its road, settle it, then take its t = 0 sample.

        Parameters
        ----------
        k : int
            Car.
        x0 : ndarray (nx,)
            Initial mechanical state (the simulator's car at rest on the road at ``t0``).
        t0 : float
            Time of the start [s] (``-settle_steps * dt``).
        settle_steps : int
            Control periods before t = 0 (sensors running, nothing recorded).
        settle_current : float
            Current commanded while settling [A].
        rng : numpy.random.Generator or None
            The car's sensor random numbers (None: sensors off; their readings stay 0).

        """
        m = self.model
        self.x[k] = x0
        self.f[k] = 0.0
        self.clock[k] = (t0, 0.0, 0.0)
        for i, p in enumerate(m.plants):
            self.plant[k, i] = 0.0
            self.plant[k, i, K.PL_U] = p.initial_current_a
            self.plant[k, i, K.PL_DRIVE] = p.initial_current_a
        self.filt[k] = 0.0
        self.sums[k] = 0.0
        self.sens[k] = 0.0
        self.rngs[k] = rng
        self._sensing[k] = rng is not None
        self._left = 0
        if rng is not None:
            for s, spec in enumerate(m.sensor_specs):
                bias = spec.bias + (rng.normal(0.0, spec.bias_std) if spec.bias_std else 0.0)
                self.sens[k, s, K.SE_BIAS] = bias
                self.sens[k, s, K.SE_LAST] = math.nan
            self.sens[k, :, K.SE_BUF:] = math.inf
        self.cmd[k] = settle_current
        only = self._one
        only[:] = 0
        only[k] = 1
        self._run(only, settle_steps, record_first=0, record=0)
        self.filt[k] = 0.0
        self.sums[k] = 0.0
        self._run(only, 0, record_first=1, record=0)
        only[k] = 0

    # --- stepping --------------------------------------------------------------------------
    def _refill(self, cars):
        ns = self.model.ns
        for k in cars:
            rng = self.rngs[k]
            self.draws[k, :, :, K.DR_RW:K.DR_NOISE + 1] = rng.standard_normal((DRAW_BLOCK, ns, 2))
            self.draws[k, :, :, K.DR_LOSS] = rng.random((DRAW_BLOCK, ns))

    def _refill_all(self, cars):
        """Draw the next block of each of ``cars`` (on the batch's threads, a share each)."""
        if self._pool is None or len(cars) < 2 * self.threads:
            self._refill(cars)
            return
        # each car's numbers from its own generator, so the split does not change them; numpy
        # fills the arrays with the GIL released
        jobs = [self._pool.submit(self._refill, part)
                for part in np.array_split(cars, self.threads)]
        for job in jobs:
            job.result()

    def _call(self, active, nsteps, record_first, record, sense):
        m = self.model
        if self._pool is None or np.count_nonzero(active) < 2:
            self._kernel(nsteps, record_first, record, sense, active, m.G, m.mf, m.mi, self.S,
                         self.road, self.draws)
            return
        # each thread a contiguous share of the cars (their rows of S, road and draws)
        jobs = [self._pool.submit(self._kernel, nsteps, record_first, record, sense,
                                  active[a:b], m.G, m.mf, m.mi, self.S[a:b], self.road[a:b],
                                  self.draws[a:b])
                for a, b in self._shares]
        for job in jobs:
            job.result()

    def close(self):
        """Stop the batch's threads (if any)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def _run(self, active, nsteps, *, record_first, record):
        """Advance the active cars ``nsteps`` periods, sensing where a car has a generator."""
        if nsteps == 0 or not self._sensing.any() or self.model.ns == 0:
            self._call(active, nsteps, record_first, record, 0)
            return
        done = 0
        while done < nsteps:
            if self._left <= 0:
                # every sensing car gets its block's random numbers for the coming steps
                sensing = np.flatnonzero(self._sensing)
                pos = self.clock[sensing, K.CL_SAMPLES].astype(np.int64) % DRAW_BLOCK
                self._refill_all(sensing[pos == 0])
                self._left = DRAW_BLOCK - int(pos.max())
            chunk = min(nsteps - done, self._left)
            self._call(active, chunk, record_first if done == 0 else 0, record, 1)
            # a car not stepped keeps its place in its block: the next call may recheck early
            self._left -= chunk if active is self._all else DRAW_BLOCK
            done += chunk

    def step(self, currents=None, active=None):
        """
        Advance the cars one control period with ``currents`` (n, nc) [A] held.

        The currents must already be within the coil range (the environments clip and flag);
        None: the commands already in :attr:`cmd`. ``active`` (n,) of bool: the cars to step
        (default all).
        """
        if currents is not None:
            self.cmd[:] = currents
        act = self._all if active is None else np.asarray(active, dtype=np.uint8)
        self._run(act, 1, record_first=0, record=1)

    def run(self, currents, nsteps):
        """Advance every car ``nsteps`` periods with constant ``currents`` (recorded)."""
        self.cmd[:] = currents
        self._run(self._all, int(nsteps), record_first=0, record=1)

    def figures(self, k):
        """ISO 2631-1 and ride figures of car ``k`` since its t = 0 (:meth:`CarModel.figures`)."""
        return self.model.figures(self.sums[k])

    def samples(self, k):
        """Return the samples recorded by car ``k`` since its t = 0."""
        return int(self.sums[k, self.model.sum_slots['n']])

    def obs_clipped(self, k):
        """Return the observation entries of car ``k`` clipped to the space since t = 0."""
        return int(self.sums[k, self.model.sum_slots['clipped']])
