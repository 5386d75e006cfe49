"""
Full vehicle (7-DOF) with four MR dampers: car, two-track roads, modal control, ISO 2631 metrics.

The public API (``from quarter_car_sim.full_car import ...``); see docs/full-car.md.
"""
from quarter_car_sim.full_car.bound import full_car_bound
from semi_active_control.runtime.full_car_controller_core import FullCarController
from semi_active_control.laws.full_car import ModalSkyhook, PerCornerLaws
from semi_active_control.laws.registry import make_full_car_law
from quarter_car_sim.full_car.dynamics import FullCar, mechanical_energy
from semi_active_control.car.full_car_linear import FullCarState
from semi_active_control.laws.full_car_lqr import full_car_lqr_design, FullCarClippedOptimal
from quarter_car_sim.full_car.metrics import full_car_metrics, iso2631_seat
from semi_active_control.car.full_car import CORNERS, FullCarParams, PASSENGER_CAR, symmetric_car
from quarter_car_sim.full_car.road import (event_road, iso8608_two_tracks,
                                           make_two_track_road, TwoTrackRoad)
from quarter_car_sim.full_car.simulate import compare_laws, FullCarResult, simulate_full_car

__all__ = ['CORNERS', 'FullCar', 'FullCarClippedOptimal', 'FullCarController', 'FullCarParams',
           'FullCarResult', 'full_car_bound', 'full_car_lqr_design',
           'FullCarState', 'ModalSkyhook', 'PASSENGER_CAR', 'PerCornerLaws', 'TwoTrackRoad',
           'compare_laws', 'event_road', 'full_car_metrics', 'iso2631_seat',
           'iso8608_two_tracks', 'make_full_car_law', 'make_two_track_road',
           'mechanical_energy', 'simulate_full_car', 'symmetric_car']
