"""
Episode roads: an ISO 8608 road (or an event road) from the environment's random generator.

The roads are the offline tools' own: :func:`quarter_car_sim.road.make_road` for the quarter
car (``quarter-car-sim``) and :func:`quarter_car_sim.full_car.road.make_two_track_road` for the
full car (``full-car-sim``), built from a road seed, so any episode can be driven again by the
offline tools (``--seed`` = the episode's ``road_seed``, info ``road``).

Reset options (``env.reset(seed=..., options={...})``; a value not given takes the
environment's default, a list or a ``(low, high)`` pair is drawn from the generator):

- ``road``: ``'iso8608'`` (default) or an event road of the offline tools (quarter car
  ``'bump'``, ``'sine'``, ``'step'``; full car ``'bump'``, ``'pothole'``, ``'single-bump'``);
- ``road_class``: ISO 8608 class ``'A'`` .. ``'H'``, or a list to draw from;
- ``speed_m_s``: speed [m/s], or ``(low, high)`` drawn uniformly;
- ``road_seed``: seed of the road's random phases (default drawn from the generator);
- ``events``: discrete events added to the ISO road, each a name (``'bump'``, and for the full
  car ``'pothole'``, ``'single-bump'``) or a dict ``{'kind', 'at_s', 'height_m',
  'length_m'}``; ``at_s`` (when the front wheels reach it [s]) is drawn in
  ``[0.5, duration - 1]`` s when not given;
- ``duration_s``: episode length [s].
"""
import dataclasses
import math

import numpy as np

from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.full_car.dynamics import FullCar
from quarter_car_sim.full_car.road import event_road, make_two_track_road
from quarter_car_sim.road import bump, make_road, RoadError

#: Event roads of each car (the offline tools' names).
EVENT_ROADS = {'quarter': ('bump', 'sine', 'step'), 'full': ('bump', 'pothole', 'single-bump')}
#: Events that can be added to an ISO road (half sines of the offline tools).
ADDED_EVENTS = {'quarter': ('bump',), 'full': ('bump', 'pothole', 'single-bump')}
ROAD_OPTIONS = ('road', 'road_class', 'speed_m_s', 'road_seed', 'events', 'duration_s')


def _draw(value, rng, what):
    """Return a value, or one drawn from a list (choice) or a ``(low, high)`` pair (uniform)."""
    if isinstance(value, (list, tuple)):
        if not value:
            raise RoadError(f'`{what}`: empty list')
        if what == 'speed_m_s':
            if len(value) != 2:
                raise RoadError('`speed_m_s`: give a speed or a (low, high) pair [m/s]')
            lo, hi = float(value[0]), float(value[1])
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
                raise RoadError(f'`speed_m_s`: need 0 < low <= high, got {value}')
            return float(rng.uniform(lo, hi))
        return value[int(rng.integers(len(value)))]
    return value


def road_spec(defaults, options, rng):
    """
    Describe the episode's road from the defaults, the reset options and the generator.

    Returns
    -------
    dict
        ``road``, ``road_class``, ``speed_m_s``, ``road_seed``, ``events`` (list of dicts),
        ``duration_s``.

    """
    options = dict(options or {})
    unknown = sorted(set(options) - set(ROAD_OPTIONS) - {'settle_current_a', 'reset_mask'})
    if unknown:
        raise RoadError(f'unknown reset option(s) {", ".join(unknown)} (use '
                        f'{", ".join(ROAD_OPTIONS)}, settle_current_a)')
    spec = {k: options.get(k, defaults[k]) for k in ROAD_OPTIONS}
    spec['road'] = str(spec['road']).strip().lower()
    spec['road_class'] = str(_draw(spec['road_class'], rng, 'road_class')).strip().upper()
    spec['speed_m_s'] = float(_draw(spec['speed_m_s'], rng, 'speed_m_s'))
    if not (math.isfinite(spec['speed_m_s']) and spec['speed_m_s'] > 0):
        raise RoadError(f'`speed_m_s` must be > 0, got {spec["speed_m_s"]}')
    spec['duration_s'] = float(spec['duration_s'])
    if not (math.isfinite(spec['duration_s']) and spec['duration_s'] >= 0.01):
        raise RoadError(f'`duration_s` must be >= 0.01 s, got {spec["duration_s"]}')
    if spec['road_seed'] is None:
        spec['road_seed'] = int(rng.integers(2 ** 31))
    spec['road_seed'] = int(spec['road_seed'])
    events = []
    for ev in spec['events'] or ():
        e = {'kind': ev} if isinstance(ev, str) else dict(ev)
        if 'at_s' not in e:
            e['at_s'] = float(rng.uniform(0.5, max(0.5, spec['duration_s'] - 1.0)))
        events.append(e)
    spec['events'] = events
    return spec


def build_road(kind, params, spec, dt):
    """
    Build the road of a spec: a ``RoadProfile`` (quarter car) or ``TwoTrackRoad`` (full car).

    Parameters
    ----------
    kind : {'quarter', 'full'}
        Car.
    params : QuarterCarParams or FullCarParams
        Car (the full car's wheelbase and track).
    spec : dict
        :func:`road_spec`.
    dt : float
        Sample interval [s] (the control period).

    """
    road, cls = spec['road'], spec['road_class']
    v, dur, seed = spec['speed_m_s'], spec['duration_s'], spec['road_seed']
    if road not in ('iso8608',) + EVENT_ROADS[kind]:
        raise RoadError(f'unknown road {road!r} (use iso8608 or {", ".join(EVENT_ROADS[kind])})')
    name = f'iso8608-{cls}' if road == 'iso8608' else road
    if kind == 'quarter':
        out = make_road(name, speed_m_s=v, duration_s=dur, dt=dt, rng=seed)
    else:
        out = make_two_track_road(name, params, speed_m_s=v, duration_s=dur, dt=dt, rng=seed)
    for ev in spec['events']:
        out = _add_event(kind, params, out, ev, v, dur, dt)
    return out


def _add_event(kind, params, road, ev, speed, duration, dt):
    """Return ``road`` with an event (half sine) added at ``ev['at_s']``."""
    k = ev.get('kind')
    if k not in ADDED_EVENTS[kind]:
        raise RoadError(f'unknown event {k!r} (use {", ".join(ADDED_EVENTS[kind])})')
    extra = {}
    if 'height_m' in ev:
        extra['height'] = float(ev['height_m'])
    if 'length_m' in ev:
        extra['length'] = float(ev['length_m'])
    at = float(ev['at_s'])
    if kind == 'quarter':
        e = bump(extra.get('height', 0.05), extra.get('length', 1.0), speed, duration, dt,
                 start_s=at)
        return dataclasses.replace(road, z=road.z + e.z, zdot=road.zdot + e.zdot,
                                   name=f'{road.name} + {k} at {at:.2f} s')
    e = event_road(k, speed, duration, wheelbase_m=params.wheelbase, dt=dt, start_s=at, **extra)
    return dataclasses.replace(road, z_left=road.z_left + e.z_left,
                               z_right=road.z_right + e.z_right,
                               zdot_left=road.zdot_left + e.zdot_left,
                               zdot_right=road.zdot_right + e.zdot_right,
                               name=f'{road.name} + {k} at {at:.2f} s')


def tracks(kind, road):
    """Return ``([(z, zdot) per track], delay_s)`` of a road for :meth:`CarBatch.set_road`."""
    if kind == 'quarter':
        return [(road.z, road.zdot)], 0.0
    return [(road.z_left, road.zdot_left), (road.z_right, road.zdot_right)], road.delay_s


def recorded_samples(road, dt):
    """Return the samples of the offline tools' run on ``road`` (t = 0 .. duration, both ends)."""
    return int(round(road.duration / dt)) + 1


def initial_state(kind, params, road, t0):
    """
    Return the simulator's car at rest on ``road`` at ``t0`` as the kernel's state vector.

    Built by :class:`quarter_car_sim.dynamics.QuarterCar` / :class:`quarter_car_sim.full_car.
    dynamics.FullCar` themselves (static equilibrium on the road's heights at ``t0``).
    """
    if kind == 'quarter':
        s = QuarterCar(params, None, road, t0=t0).state
        return np.array([s.z_s, s.v_s, s.z_u, s.v_u])
    s = FullCar(params, None, road, t0=t0).state
    return np.concatenate([s.q, s.v])
