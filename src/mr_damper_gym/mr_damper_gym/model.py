"""
The car of an environment as the arrays the compiled step reads (:mod:`mr_damper_gym.kernel`).

:class:`CarModel` is built from the simulator's own pieces, never a second copy of them: the
car's parameters (:class:`quarter_car_sim.params.QuarterCarParams` or
:class:`quarter_car_sim.full_car.params.FullCarParams`), the exact discretisation tables of
its linear part (``quarter_car_sim.dynamics.discretise`` /
``quarter_car_sim.full_car.dynamics.discretise``, one per pattern of wheels in contact), the
damper plants (:mod:`mr_damper_model.models.plant`), the ISO 2631-1 filters
(``ride_metrics.wk_sos``, ``full_car.metrics.we_sos``, the axis factors) and the sensors'
error models (:mod:`quarter_car_sim.sensors`).

Observation rows (SI units; :attr:`CarModel.obs_names`): the true state first, then the
sensors (the environments hand out one of the two parts).

- true state, per corner: suspension travel [m] (extension +), tyre deflection ``z_u - z_r``
  [m], suspension velocity [m/s], body velocity and acceleration above the wheel [m/s, m/s^2],
  wheel velocity [m/s], damper force on the body [N] (+ up), actual coil current [A], the
  current command in force [A]; for the full car then the body: heave above the mean road
  under the wheels [m], pitch [rad] (nose down +), roll [rad] (left up +), their rates and
  accelerations;
- sensors: each sensor's latest reading (accelerometers: vertical specific force [m/s^2],
  +9.81 at rest; position sensors: travel [m]), held when a sample is lost; then 1/0 per
  sensor: a reading arrived at this step; then the current command in force [A] per corner.
"""
import math

import numpy as np

from mr_damper_gym import kernel as K
from mr_damper_model.models.plant import KwokCurrentPlant, SpencerPlant
from quarter_car_sim.dynamics import discretise as discretise_quarter
from quarter_car_sim.full_car.dynamics import corner_maps, discretise as discretise_full
from quarter_car_sim.full_car.metrics import AXIS_FACTORS, we_sos
from quarter_car_sim.full_car.params import CORNERS
from quarter_car_sim.ride_metrics import wk_sos

#: Envelope of the observation entries by quantity: no physical run reaches these (the
#: kernel clips to them and counts the entries clipped, info ``obs_clipped``).
ENVELOPE = {'m': 1.0, 'm/s': 20.0, 'm/s^2': 2000.0, 'N': 5.0e4, 'rad': 1.0, 'rad/s': 20.0,
            'rad/s^2': 2000.0}

CORNER_QUANTITIES = (('travel', 'm'), ('tyre_deflection', 'm'), ('suspension_velocity', 'm/s'),
                     ('body_velocity', 'm/s'), ('body_acceleration', 'm/s^2'),
                     ('wheel_velocity', 'm/s'), ('damper_force', 'N'), ('coil_current', 'A'),
                     ('current_command', 'A'))
BODY_QUANTITIES = (('heave_above_road', 'm'), ('pitch', 'rad'), ('roll', 'rad'),
                   ('heave_rate', 'm/s'), ('pitch_rate', 'rad/s'), ('roll_rate', 'rad/s'),
                   ('heave_acceleration', 'm/s^2'), ('pitch_acceleration', 'rad/s^2'),
                   ('roll_acceleration', 'rad/s^2'))


class ModelError(ValueError):
    """A car, plant or sensor setting the environment cannot run (the message says which)."""


def plant_row(plant):
    """
    Return the kernel's row (:data:`kernel.PP_N` floats) of a streaming damper plant.

    Parameters
    ----------
    plant : SpencerPlant or KwokCurrentPlant
        The "true" damper of a corner (:func:`mr_damper_model.models.plant.make_plant`).

    """
    row = np.zeros(K.PP_N)
    row[K.PP_SLEW] = math.inf if plant.slew_a_per_s is None else plant.slew_a_per_s
    if isinstance(plant, SpencerPlant):
        row[K.PP_KIND] = 0.0
        row[K.PP_SUB_OR_TAU] = plant.max_substep_s
        row[K.PP_Y0_OR_IREF] = math.nan if plant.y0_m is None else plant.y0_m
        row[K.PP_PARAMS:K.PP_PARAMS + 13] = plant._p
    elif isinstance(plant, KwokCurrentPlant):
        row[K.PP_KIND] = 1.0
        row[K.PP_SUB_OR_TAU] = plant.coil_tau_s
        row[K.PP_Y0_OR_IREF] = plant._inv_ref
        row[K.PP_PARAMS:K.PP_PARAMS + 10] = plant._p
    else:
        raise ModelError(f'the environment runs SpencerPlant and KwokCurrentPlant dampers, '
                         f'got {type(plant).__name__}')
    return row


def sensor_row(spec, dt):
    """
    Return the kernel's floats and ``(latency, period)`` in control periods of a sensor.

    Parameters
    ----------
    spec : quarter_car_sim.sensors.SensorSpec
        Error model (faults are not supported in the environment).
    dt : float
        Control period [s].

    """
    if spec.faults:
        raise ModelError('injected sensor faults are not supported in the environment')
    ratio = 1.0 / (spec.rate_hz * dt)
    period = int(round(ratio))
    if period < 1 or abs(ratio - period) > 1e-6:
        raise ModelError(f'a sensor rate ({spec.rate_hz:g} Hz) must be the control rate '
                         f'({1.0 / dt:g} Hz) divided by a whole number')
    row = [spec.noise_std, spec.bias_rw * math.sqrt(period * dt), spec.bias_drift,
           spec.scale_error, spec.offset, spec.quantum, spec.dropout_prob,
           1.0 if spec.dropout_mode == 'hold' else 0.0]
    return row, int(round(spec.latency_s / dt)), period


class CarModel:
    """
    One environment's car as arrays: discretisation tables, constants, plants, sensors.

    Parameters
    ----------
    kind : {'quarter', 'full'}
        Car.
    params : QuarterCarParams or FullCarParams
        Car parameters.
    plants : sequence of DamperPlant
        The "true" damper of each corner (1 or 4).
    sensors : sequence of (name, kind, corner, SensorSpec)
        Sensors: kind ``'accel'`` (body vertical accelerometer above the corner) or
        ``'travel'`` (suspension position sensor).
    dt : float
        Control period [s].
    substeps : int
        Integration sub-steps per period (plants stepped each sub-step).
    seat : (float, float)
        Seat ``(x, y)`` from the CG [m] of the full car's ISO 2631-1 figures.
    tyre_weight : float
        Weight ``rho`` of the dynamic tyre loads in the reward.

    Attributes
    ----------
    G : ndarray (2**nc, nx, nx + 4 nc + 1)
        Discretisation table per pattern of wheels in contact (bit i: wheel i on the road).
    mi, mf : ndarray
        The kernel's integers and floats (layout: :mod:`mr_damper_gym.kernel`).
    pp : ndarray (nc, kernel.PP_N)
        The plants' rows (also the end of ``mf``).
    blocks : dict
        ``{block: (first column, width)}`` of a car's row of the state array
        (:data:`mr_damper_gym.kernel.S_BLOCKS`); ``width`` the row's length.
    obs_names, obs_units : tuple of str
        Name and unit of each observation entry (true state, then sensors).
    n_state_obs : int
        Entries of the true-state part.
    channels : tuple of str
        Names of the ISO-weighted channels (``'wk'``; full car ``'wk_z'``, ``'we_pitch'``,
        ``'we_roll'``).

    """

    def __init__(self, kind, params, plants, sensors, *, dt=1e-3, substeps=1, seat=(0.0, 0.0),
                 tyre_weight=0.0):
        if kind not in ('quarter', 'full'):
            raise ModelError(f"`kind` must be 'quarter' or 'full', got {kind!r}")
        if not (math.isfinite(dt) and dt > 0):
            raise ModelError(f'`dt` must be > 0 s, got {dt}')
        if int(substeps) < 1:
            raise ModelError(f'`substeps` must be >= 1, got {substeps}')
        if not (math.isfinite(tyre_weight) and tyre_weight >= 0):
            raise ModelError(f'`tyre_weight` must be >= 0, got {tyre_weight}')
        self.kind, self.params, self.dt = kind, params, float(dt)
        self.substeps = int(substeps)
        self.plants = list(plants)
        self.tyre_weight = float(tyre_weight)
        h = self.dt / self.substeps
        fs = 1.0 / self.dt
        if kind == 'quarter':
            nc, nb, nx = 1, 1, 4
            self.G = np.stack([discretise_quarter(params, h, contact=bool(p))
                               for p in range(2)])
            idx = ([0], [1], [2], [3])
            T = np.ones((1, 1))
            Ks = np.array([[params.k_s]])
            cs, W = np.array([params.c_s]), np.array([params.static_tyre_load])
            mu, minv_b = np.array([params.m_u]), np.array([1.0 / params.m_s])
            track, delayed = [0], [0]
            Cw, kw, sos = np.ones((1, 1)), np.ones(1), [wk_sos(fs)]
            self.channels = ('wk',)
            self.corners = ('corner',)
        else:
            nc, nb, nx = 4, 3, 14
            self.G = np.stack([
                discretise_full(params, h, tuple(bool(p >> i & 1) for i in range(4)))
                for p in range(16)])
            idx = ([0, 1, 2], [7, 8, 9], [3, 4, 5, 6], [10, 11, 12, 13])
            T = corner_maps(params)[0]
            Ks, cs = params.spring_matrix(), params.c_s
            W, mu = params.static_tyre_loads, params.m_u
            minv_b = 1.0 / np.array([params.m_s, params.i_pitch, params.i_roll])
            track, delayed = [0, 1, 0, 1], [1, 1, 0, 0]
            x_s, y_s = seat
            Cw = np.array([[1.0, -x_s, y_s], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            kw = np.array([AXIS_FACTORS['z'], AXIS_FACTORS['pitch'], AXIS_FACTORS['roll']])
            sos = [wk_sos(fs), we_sos(fs), we_sos(fs)]
            self.channels = ('wk_z', 'we_pitch', 'we_roll')
            self.corners = CORNERS
        if len(self.plants) != nc:
            raise ModelError(f'the {kind} car needs {nc} plants, got {len(self.plants)}')
        self.nc, self.nb, self.nx, self.nw = nc, nb, nx, len(self.channels)
        # the filters of every channel padded to the same number of sections with identity
        # sections (b0 = 1, a0 = 1): exactly a pass-through
        nsec = max(s.shape[0] for s in sos)
        sos_arr = np.zeros((self.nw, nsec, 6))
        sos_arr[:, :, 0] = sos_arr[:, :, 3] = 1.0
        for j, s in enumerate(sos):
            sos_arr[j, :s.shape[0]] = s
        self.nsec = nsec
        self.pp = np.stack([plant_row(p) for p in self.plants])
        self.sensor_names = tuple(s[0] for s in sensors)
        self.sensor_specs = tuple(s[3] for s in sensors)
        rows, lat, per = [], [], []
        for name, skind, corner, spec in sensors:
            if skind not in ('accel', 'travel') or not 0 <= corner < nc:
                raise ModelError(f'sensor {name!r}: kind must be accel or travel on a corner')
            r, latency, period = sensor_row(spec, self.dt)
            rows.append(r)
            lat.append(latency)
            per.append(period)
        self.ns = len(sensors)
        self.max_latency = max(lat) if lat else 0
        names, units = [], []
        for q, unit in CORNER_QUANTITIES:
            for c in self.corners:
                names.append(f'{q}_{c}' if nc > 1 else q)
                units.append(unit)
        if nb > 1:
            for q, unit in BODY_QUANTITIES:
                names.append(q)
                units.append(unit)
        self.n_state_obs = len(names)
        for name, skind, _, _ in sensors:
            names.append(f'{name}_reading')
            units.append('m/s^2' if skind == 'accel' else 'm')
        for name in self.sensor_names:
            names.append(f'{name}_fresh')
            units.append('1')
        for c in self.corners:
            names.append(f'current_command_{c}' if nc > 1 else 'current_command')
            units.append('A')
        self.obs_names, self.obs_units = tuple(names), tuple(units)
        lo, hi = self._bounds()
        self.obs_low, self.obs_high = lo, hi
        self.sum_slots, self.n_sums = K.sum_slots(self.nw, nc, nb)
        self.sens_len = K.SE_BUF + self.max_latency + 1
        widths = {'x': nx, 'f': nc, 'clock': 3, 'road': 2, 'cmd': nc, 'plant': nc * K.PL_N,
                  'filt': self.nw * nsec * 2, 'sums': self.n_sums,
                  'sens': self.ns * self.sens_len, 'obs': len(names), 'reward': 1}
        self.blocks, start = {}, 0
        for name in K.S_BLOCKS:
            self.blocks[name] = (start, widths[name])
            start += widths[name]
        self.width = start
        mi = [nc, nb, nx, self.nw, nsec, self.ns, self.substeps, self.n_state_obs, len(names),
              self.sens_len, self.n_sums]
        mi += [self.blocks[name][0] for name in K.S_BLOCKS]
        for group in idx:
            mi.extend(group)
        mi += track + delayed
        mi += [0 if s[1] == 'accel' else 1 for s in sensors]
        mi += [s[2] for s in sensors]
        mi += lat + per
        self.mi = np.asarray(mi, dtype=np.int64)
        head = np.zeros(K.MF_HEAD)
        head[K.MF_DT], head[K.MF_H], head[K.MF_ROAD_DT] = self.dt, h, self.dt
        head[K.MF_A0] = head[K.MF_T0] = 1.0
        head[K.MF_RHO] = self.tyre_weight
        head[K.MF_IMIN], head[K.MF_IMAX] = params.i_min, params.i_max
        head[K.MF_KT], head[K.MF_CT] = params.k_t, params.c_t
        self.mf = np.concatenate([
            head, np.ravel(T), np.ravel(Ks), cs, W, mu, minv_b, np.ravel(Cw), kw,
            np.ravel(sos_arr), np.ravel(np.asarray(rows, dtype=float).reshape(-1)), lo, hi,
            np.ravel(self.pp)])
        self.static_loads = np.asarray(W, dtype=float)
        self.axis_factors = np.asarray(kw, dtype=float)

    def _bounds(self):
        """Finite envelope of every observation entry (currents: the coil range)."""
        p = self.params
        lo, hi = [], []
        for name, unit in zip(self.obs_names, self.obs_units):
            if unit == 'A':
                a, b = min(p.i_min, 0.0), p.i_max
            elif unit == '1':
                a, b = 0.0, 1.0
            else:
                b = ENVELOPE[unit]
                a = -b
            lo.append(a)
            hi.append(b)
        return np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)

    def set_normalisation(self, a0, t0):
        """
        Set the reward's normalisation: mean squared comfort and tyre terms of the reference.

        Parameters
        ----------
        a0 : float
            Mean of ``sum_j (k_j a_w,j)^2`` [(m/s^2)^2] of the reference run.
        t0 : float
            Mean over samples and wheels of the squared dynamic tyre load ratio [-].

        """
        if not (a0 > 0 and t0 > 0 and math.isfinite(a0) and math.isfinite(t0)):
            raise ModelError(f'the reference run gives no normalisation ({a0}, {t0})')
        self.mf[K.MF_A0] = a0
        self.mf[K.MF_T0] = t0

    @property
    def normalisation(self):
        """``(a0, t0)`` of the reward (see :meth:`set_normalisation`)."""
        return float(self.mf[K.MF_A0]), float(self.mf[K.MF_T0])

    def figures(self, sums):
        """
        ISO 2631-1 and ride figures of running sums (one car's ``sums`` row).

        Returns
        -------
        dict
            Quarter car: ``rms_body_accel_wk``, ``vdv_wk``, ``crest_wk``, ``rms_body_accel``
            [m/s^2]; full car: ``a_wz`` [m/s^2], ``a_w_pitch``, ``a_w_roll`` [rad/s^2],
            ``a_v`` [m/s^2], ``vdv_total`` [m/s^1.75], ``crest_max``. Both: per corner
            ``rms_tyre_load_ratio``, ``rms_suspension_travel`` [m], ``mean_current_a`` [A]
            (lists for the full car), ``max_rms_tyre_load_ratio``, ``contact_loss_fraction``
            (of the worst wheel), ``cost`` (the mean of minus the reward), ``n_samples``,
            ``duration_s``.

        """
        s = np.asarray(sums, dtype=float)
        off = self.sum_slots
        n = s[off['n']]
        if n <= 0:
            return {'n_samples': 0}
        ch = s[off['ch']:off['tyre']].reshape(self.nw, 3)
        rms = np.sqrt(ch[:, 0] / n)
        vdv = (ch[:, 1] * self.dt) ** 0.25
        crest = np.where(rms > 0, ch[:, 2] / np.where(rms > 0, rms, 1.0), math.nan)
        tyre = s[off['tyre']:off['corner']].reshape(self.nc, 3)
        corner = s[off['corner']:off['raw']].reshape(self.nc, 3)
        rms_tyre = np.sqrt(tyre[:, 0] / n)
        out = {}
        if self.kind == 'quarter':
            out.update(rms_body_accel_wk=float(rms[0]), vdv_wk=float(vdv[0]),
                       crest_wk=float(crest[0]),
                       rms_body_accel=float(math.sqrt(s[off['raw']] / n)),
                       rms_tyre_load_ratio=float(rms_tyre[0]),
                       rms_suspension_travel=float(math.sqrt(corner[0, 0] / n)),
                       mean_current_a=float(corner[0, 2] / n))
        else:
            k = self.axis_factors
            out.update(a_wz=float(rms[0]), a_w_pitch=float(rms[1]), a_w_roll=float(rms[2]),
                       a_v=float(math.sqrt(np.sum((k * rms) ** 2))),
                       vdv_total=float(np.sum((k * vdv) ** 4) ** 0.25),
                       crest_max=float(np.nanmax(crest)),
                       rms_tyre_load_ratio=[float(v) for v in rms_tyre],
                       rms_suspension_travel=[float(v) for v in np.sqrt(corner[:, 0] / n)],
                       mean_current_a=[float(v) for v in corner[:, 2] / n])
        out['max_rms_tyre_load_ratio'] = float(np.max(rms_tyre))
        out['contact_loss_fraction'] = float(np.max(tyre[:, 2]) / n)
        a0, t0 = self.normalisation
        comfort = float(np.sum(self.axis_factors ** 2 * ch[:, 0]) / n)
        tyre_ms = float(np.mean(tyre[:, 0]) / n)
        out['cost'] = (comfort / a0 + self.tyre_weight * tyre_ms / t0) / (1.0 + self.tyre_weight)
        out['n_samples'] = int(n)
        out['duration_s'] = float(n * self.dt)
        return out
