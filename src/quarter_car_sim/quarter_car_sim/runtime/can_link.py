"""
The simulated car's chassis bus: its sensor cluster and four damper drivers on CAN (no ROS).

:class:`CanCarLink` is the car's side of a vehicle computer: each car step it reads the
production sensors on the true state (four body accelerometers and four ride height sensors
with the automotive error models of :mod:`semi_active_control.estimation.sensor_specs`,
sampled every bus cycle: :func:`~quarter_car_sim.plant.sensors.bus_sensor_cluster`) and hands
them, gravity removed, to a :class:`mr_damper_can.driver_sim.SimulatedEcu` on the bus, which
sends the three sensor frames every ``cycle_s`` and its drivers' status every
``status_period_s``, takes the command frames (``DAMPER_CMD_ALL``, or one per corner) and falls
back on its own safe current when no valid command came for ``driver_timeout_s``. The link
returns the four drivers' set points, which the car's damper plants take as their coil
commands (each plant has its coil lag).

The ECU runs on the car's time (the link's clock is the state's ``t``), so a car slower than
real time gives a slower bus, not stale sensor frames; its command timeout is in car time too.
:attr:`CanCarLink.t_normal` is the first car time at which every driver had a fresh command
without its fail-safe bit (the vehicle computer in control): the driver timeouts counted from
then on are the ones of a running chain.
"""
import math

from quarter_car_sim.plant.sensors import bus_sensor_cluster
from semi_active_control.car.full_car import CORNERS
from semi_active_control.estimation.sensor_specs import G0


class CanCarLink:
    """
    The car's sensor ECU and damper drivers on a CAN bus (see the module docstring).

    Parameters
    ----------
    bus : can.BusABC or None
        The bus (None: frames collected by the ECU, for tests).
    dt : float
        Car step [s].
    cycle_s : float
        Sensor frame cycle [s].
    status_period_s : float
        Driver status period [s].
    driver_timeout_s : float
        A driver without a valid command for this long takes its own safe current [s].
    driver_safe_current_a : float
        That current [A].
    sensor_noise : bool
        Automotive sensor errors (noise, bias, quantisation; seeded) or exact readings.
    seed : int
        Sensor seed.

    """

    def __init__(self, bus, *, dt=0.001, cycle_s=0.002, status_period_s=0.01,
                 driver_timeout_s=0.05, driver_safe_current_a=0.5, sensor_noise=True, seed=1):
        from mr_damper_can.driver_sim import SimulatedEcu
        self._t = 0.0
        self.ecu = SimulatedEcu(bus, CORNERS, tau_s=1.0 / 190.0,
                                safe_current_a=driver_safe_current_a,
                                command_timeout_s=driver_timeout_s,
                                status_period_s=status_period_s, sensor_period_s=cycle_s,
                                clock=self.now)
        self.sensors = None
        if sensor_noise:
            self.sensors = bus_sensor_cluster(dt, cycle_s, seed)
        self._acc_names = [f'accel_{c}' for c in CORNERS]
        self._pos_names = [f'travel_{c}' for c in CORNERS]
        self.t_normal = math.nan
        self._timeouts_at_normal = None
        self.steps = 0

    def now(self):
        """Return the link's (and its ECU's) clock: the car's time [s]."""
        return self._t

    def start(self, reader_priority=0):
        """
        Read the bus (the ECU's Notifier thread); its cycle runs in :meth:`step`.

        ``reader_priority`` > 0: the reader thread at SCHED_FIFO that priority (below the
        car's control thread: :meth:`mr_damper_can.driver_sim.SimulatedEcu.start`).
        """
        self.ecu.start(cycle=False, reader_priority=reader_priority)

    def stop(self, drain=True):
        """Stop reading the bus (taking what is still queued with ``drain``)."""
        self.ecu.stop(drain=drain)

    def step(self, state):
        """
        Read the sensors on ``state``, run the ECU to its time; return the drivers' set points.

        Returns
        -------
        list of 4 float
            Each driver's coil current set point [A] (the command, or its safe current).

        """
        self._t = float(state.t)
        ecu = self.ecu
        if self.sensors is not None:
            r = self.sensors.step(state.t, state)
            if r:
                acc = [r.get(n, math.nan) - G0 for n in self._acc_names]
                pos = [r.get(n, math.nan) for n in self._pos_names]
                self._set(acc, state.acc[3:], pos)
        else:
            self._set(state.body_a, state.acc[3:], state.travel)
        ecu.step(self._t)
        targets = ecu.drive_targets(self._t)
        self.steps += 1
        if math.isnan(self.t_normal) and ecu.commanded():
            self.t_normal = self._t
            self._timeouts_at_normal = [ecu.ch[c].timeouts for c in CORNERS]
        return targets

    def _set(self, body_accel, wheel_accel, travel):
        for k, c in enumerate(CORNERS):
            self.ecu.set_sensors(c, float(body_accel[k]), float(wheel_accel[k]),
                                 float(travel[k]))

    def status(self):
        """
        Return the ECU's status with ``t_normal`` and the driver timeouts after it.

        ``driver_timeouts_after_normal``: per corner the command timeouts of its driver since
        :attr:`t_normal` (None before it).
        """
        st = self.ecu.status()
        st['t_normal'] = self.t_normal
        st['steps'] = self.steps
        if self._timeouts_at_normal is None:
            st['driver_timeouts_after_normal'] = None
        else:
            st['driver_timeouts_after_normal'] = {
                c: self.ecu.ch[c].timeouts - n0
                for c, n0 in zip(CORNERS, self._timeouts_at_normal)}
        return st
