"""CanCarLink: the car's sensors on the bus every cycle, the drivers' set points to its plants."""
import math

import can
import numpy as np

from mr_damper_can import codec
from mr_damper_can.vehicle_bridge import VehicleBridge
from quarter_car_sim.full_car.can_link import CanCarLink
from quarter_car_sim.full_car.dynamics import FullCar
from quarter_car_sim.full_car.params import PASSENGER_CAR
from quarter_car_sim.full_car.road import make_two_track_road
from mr_damper_model.models.plant import make_plant

DB = codec.load_database()


def _msg(frame_id, data):
    return can.Message(arbitration_id=frame_id, data=data, is_extended_id=False)


def test_the_bus_carries_the_cars_sensors_and_the_drivers_drive_its_plants():
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=1.0,
                               dt=1e-3, rng=2)
    car = FullCar(PASSENGER_CAR, [make_plant('kwok-current') for _ in range(4)], road)
    link = CanCarLink(None, dt=1e-3, sensor_noise=False, driver_timeout_s=0.02,
                      driver_safe_current_a=0.3)
    cycles = []
    bridge = VehicleBridge(None, db=DB, on_cycle=cycles.append, clock=link.now)
    bridge.activate()
    s = car.state
    targets = []
    answering = True
    for k in range(400):
        currents = link.step(s)
        targets.append(currents)
        if link.ecu.sent:
            sent_from = s
        for msg in link.ecu.sent:                      # car -> vehicle computer
            bridge.on_frame(msg)
        link.ecu.sent.clear()
        if answering and cycles and cycles[-1].sequence > bridge._last_answered:
            # the vehicle computer answers each cycle with its sequence's currents
            bridge.command_all([0.2, 0.4, 0.6, 0.8], [False] * 4, cycles[-1].sequence)
        for frame_id, data in bridge.sent:             # vehicle computer -> drivers
            link.ecu.on_frame(_msg(frame_id, data))
        bridge.sent.clear()
        if k == 299:
            answering = False
        s = car.step(1e-3, currents)
    # one sensor cycle every 2 ms of car time; the travels on the bus are the car's
    assert 195 <= len(cycles) <= 201 and [c.sequence for c in cycles] == list(
        range(1, len(cycles) + 1))
    np.testing.assert_allclose(cycles[-1].susp_pos, sent_from.travel, atol=5.1e-5)
    # the plants took the commands once the first cycle was answered, then the drivers' safe
    # current after their own timeout (20 ms) once the answers stopped
    assert targets[250] == [0.2, 0.4, 0.6, 0.8]
    assert targets[-1] == [0.3] * 4
    st = link.status()
    assert 0 < st['t_normal'] < 0.01
    assert st['driver_timeouts_after_normal'] == dict.fromkeys(codec.CORNERS, 1)
    assert not math.isnan(st['t_normal'])
