"""
Core of the ``state_estimator_node`` without ROS: sensor readings in, one estimate per tick.

The node converts messages and calls this object; everything else happens here:

- :meth:`StateEstimatorCore.offer_reading` keeps the newest reading of each sensor since the
  last tick (an older one replaced before it was used is counted, ``readings_replaced``); with
  the reading's stamp it also counts the readings that never arrived (``readings_lost``: the
  sample periods skipped between consecutive stamps);
- :meth:`offer_current` keeps the last current command [A] (the coil current input);
- :meth:`offer_parameters` gives an identified Kwok-current parameter set to the fail-safe
  supervisor (:class:`semi_active_control.supervision.failsafe.ModelSupervisor`, the same rules as
  the controller's: invalid, out-of-bounds, pinned or stale sets are not used); the active set is
  the estimator's damper model (the known force input);
- :meth:`tick` (at the control rate) steps the Kalman filter
  (:class:`semi_active_control.estimation.quarter_car.QuarterCarEstimator`) with the readings that
  arrived and returns the :class:`~semi_active_control.estimation.quarter_car.Estimate`. Without a
  usable identified model the filter runs with the force of the safe current's model if one was
  ever accepted, else with no damper force, and the estimate is invalid (``no_model``), counted
  like the filter's own reasons.
"""
import math

from semi_active_control.estimation.quarter_car import design_estimator, QuarterCarEstimator
from semi_active_control.estimation.sensor_specs import SENSOR_NAMES

#: :meth:`StateEstimatorCore.tick_at`: a jump of the readings' time longer than this [s] re-bases
REBASE_S = 1.0
#: the node's filter returns to its steady-state gain once its covariance is within 0.1 % of the
#: DARE posterior (``steady_tol`` of QuarterCarEstimator): 100 periods after a lost reading
#: instead of about 7,500, each of them at twice the cost of a steady period, which made a
#: loaded node that lost a reading slower and lose more
STEADY_TOL = 1e-3


class StateEstimatorCore:
    """
    Readings, current and identified model in; an estimate per control tick out.

    Parameters
    ----------
    car_params : QuarterCarParams
        Car the filter assumes.
    dt : float
        Control period [s] (one :meth:`tick` per period).
    specs : dict
        ``{sensor: SensorSpec}`` of the vehicle's sensors (noise, latency).
    supervisor : semi_active_control.supervision.failsafe.ModelSupervisor
        Gatekeeper of the identified parameters.
    design_options : dict, optional
        Options of :func:`~semi_active_control.estimation.quarter_car.design_estimator`.
    run_options : dict, optional
        Options of :class:`~semi_active_control.estimation.quarter_car.QuarterCarEstimator`.

    Attributes
    ----------
    estimator : QuarterCarEstimator
    readings_received, readings_replaced : dict
        Per sensor: readings offered, and those replaced by a newer one before a tick.
    readings_lost : dict
        Per sensor: readings missing between the stamps of consecutive readings (a sensor's
        sample period is the control period, or its own if longer); a jump of more than
        :data:`REBASE_S` is a restart of the vehicle's clock, not a loss.
    no_model_entries, no_model_steps : int
        Entries into and ticks of an estimate invalid for want of a model.

    """

    def __init__(self, car_params, dt, specs, supervisor, *, design_options=None,
                 run_options=None):
        self.sup = supervisor
        self.design = design_estimator(car_params, dt, specs, **dict(design_options or {}))
        self.estimator = QuarterCarEstimator(self.design, self._body_force,
                                             **{'steady_tol': STEADY_TOL,
                                                **dict(run_options or {})})
        self.sensors = self.design.sensors
        self._pending = {}
        self.readings_received = dict.fromkeys(self.sensors, 0)
        self.readings_replaced = dict.fromkeys(self.sensors, 0)
        self.readings_lost = dict.fromkeys(self.sensors, 0)
        self._sample_period = {s: max(float(dt), 1.0 / specs[s].rate_hz) for s in self.sensors}
        self._stamp = {}
        self.current_a = supervisor.safe_current_a
        self._model = None
        self._model_of = None
        self.no_model_entries = 0
        self.no_model_steps = 0
        self._no_model = False
        self.last = None
        self.dt = float(dt)
        self._t_tick = None
        self.predict_steps = 0
        self.stale_ticks = 0
        self.rebases = 0

    def _body_force(self, i, x, v):
        if self._model is None:
            return 0.0
        return -self._model.force(i, x, v)

    def offer_reading(self, sensor, value, t=None):
        """
        Keep the newest reading of ``sensor`` (accelerometers: specific force, gravity in).

        NaN marks a sample the sensor reported lost. ``t`` is the reading's stamp [s]: the
        sample periods skipped since the previous stamp of that sensor are counted in
        ``readings_lost`` (readings the vehicle sent that never arrived). Raises ValueError for
        a sensor the filter was not designed with.
        """
        if sensor not in self.readings_received:
            raise ValueError(f'sensor {sensor!r} is not one of the estimator\'s '
                             f'({", ".join(self.sensors)}; all: {", ".join(SENSOR_NAMES)})')
        try:
            value = float(value)
        except (TypeError, ValueError):
            value = math.nan
        if t is not None:
            self._count_lost(sensor, float(t))
        if sensor in self._pending:
            self.readings_replaced[sensor] += 1
        self._pending[sensor] = value
        self.readings_received[sensor] += 1

    def _count_lost(self, sensor, t):
        last = self._stamp.get(sensor)
        if last is not None and abs(t - last) <= REBASE_S:
            if t <= last:
                return                  # not newer: nothing skipped (the stamp stays)
            missed = int(round((t - last) / self._sample_period[sensor])) - 1
            if missed > 0:
                self.readings_lost[sensor] += missed
        self._stamp[sensor] = t

    def offer_current(self, current_a):
        """Take the current command [A] in force (non-finite: ignored, the last one stays)."""
        try:
            current_a = float(current_a)
        except (TypeError, ValueError):
            return False
        if not math.isfinite(current_a):
            return False
        self.current_a = current_a
        return True

    def offer_parameters(self, values, t_now):
        """Offer an identified set (or its flat mapping) to the supervisor; return its verdict."""
        return self.sup.offer(values, t_now)

    def _update_model(self):
        params = self.sup.active
        if params is None:
            return False
        if params is not self._model_of:
            from mr_damper_model.models.inverse import KwokCurrentInverse
            self._model = KwokCurrentInverse(params.parameters, i_ref_a=params.i_ref_a,
                                             i_min=self.sup.i_min_a, i_max=self.sup.i_max_a)
            self._model_of = params
        return True

    def tick(self, t, t_clock=None):
        """
        Step the filter with the readings since the last tick; return the Estimate.

        Parameters
        ----------
        t : float
            Time of this control step [s] (the estimate's stamp).
        t_clock : float, optional
            Supervisor clock [s] (default ``t``).

        """
        self.sup.update(t if t_clock is None else t_clock)
        have_model = self._update_model()
        readings, self._pending = self._pending, {}
        est = self.estimator.step(t, readings, self.current_a)
        if not have_model:
            self.no_model_steps += 1
            if not self._no_model:
                self.no_model_entries += 1
            self._no_model = True
            if est.valid:
                est.valid, est.reason = False, 'no_model'
        else:
            self._no_model = False
        self.last = est
        return est

    def tick_at(self, t, t_clock=None):
        """
        Step the filter to the sensors' time ``t`` [s] (a reading's stamp); return the Estimate.

        For a loop clocked by the readings: the periods since the last tick that brought no
        reading (readings the middleware dropped, a late executor) are predicted through
        without readings (counted, ``predict_steps``), so the filter keeps the vehicle's time
        however fast it is called. A time not after the last tick returns None (counted,
        ``stale_ticks``; the readings wait for the next tick). A jump of more than
        :data:`REBASE_S` either way (the vehicle's clock restarted) re-bases the time line
        (counted, ``rebases``) instead.
        """
        t = float(t)
        if self._t_tick is not None and abs(t - self._t_tick) > REBASE_S:
            self._t_tick = None
            self.rebases += 1
        if self._t_tick is not None:
            n = int(round((t - self._t_tick) / self.dt))
            if n < 1:
                self.stale_ticks += 1
                return None
            pending, self._pending = self._pending, {}
            for k in range(1, n):
                self.tick(self._t_tick + k * self.dt, t_clock)
                self.predict_steps += 1
            self._pending = pending
        self._t_tick = t
        return self.tick(t, t_clock)

    def status(self):
        """Return the estimator's counters plus the model and reading counters (JSON-ready)."""
        st = self.estimator.status()
        if self.last is not None:
            st['valid'], st['reason'] = self.last.valid, self.last.reason
            st['std'] = dict(zip(('travel', 'v_s', 'tyre_def', 'v_u', 'v_rel'), self.last.std))
        st.update({'no_model_entries': self.no_model_entries,
                   'no_model_steps': self.no_model_steps,
                   'readings_received': dict(self.readings_received),
                   'readings_replaced': dict(self.readings_replaced),
                   'readings_lost': dict(self.readings_lost),
                   'predict_steps': self.predict_steps, 'stale_ticks': self.stale_ticks,
                   'rebases': self.rebases,
                   'current_a': self.current_a, 'model': self.sup.status()})
        return st
