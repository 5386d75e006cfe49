"""The full-car run's configuration: four rig / identifier stacks and one car, ROS-free."""
from types import SimpleNamespace

import pytest

from mr_damper_bringup.config import IDENT, QC, resolve_config, RIG
from mr_damper_bringup.full_car_suite import (BODY_LOG, FULL_CAR, FULL_CAR_CORNERS,
                                              full_car_configs)


def _args(duration):
    return SimpleNamespace(config='full-car', params=None, rate_factor=None, duration=duration,
                           file=None, set=None, external_controller=False, corners=None)


def test_four_stacks_without_cars_and_one_car_with_a_long_enough_road(tmp_path):
    cfg = resolve_config(_args(600.0), tmp_path)
    corners, car = full_car_configs(cfg, tmp_path, 600.0)   # > the node's 300 s road
    assert tuple(corners) == FULL_CAR_CORNERS
    seeds = []
    for k, c in enumerate(FULL_CAR_CORNERS):
        sections = set(corners[c]) - {'/**'}
        assert sections == {f'/{c}/{RIG}', f'/{c}/{IDENT}'}            # no quarter car
        seeds.append(corners[c][f'/{c}/{RIG}']['ros__parameters']['seed'])
    assert len(set(seeds)) == 4                                        # rig noise differs
    assert set(car) == {'/**', FULL_CAR} and QC not in car
    p = car[FULL_CAR]['ros__parameters']
    assert p['log_file'] == str(tmp_path / BODY_LOG)
    assert p['road_duration_s'] >= 600.0 and p['log_max_s'] >= 600.0
    assert car['/**']['ros__parameters']['plant'] == 'spencer'


def test_rate_factor_sets_the_cars_speed_too(tmp_path):
    args = _args(30.0)
    args.rate_factor = 2.0
    _, car = full_car_configs(resolve_config(args, tmp_path), tmp_path, 30.0)
    assert car[FULL_CAR]['ros__parameters']['real_time_factor'] == 2.0


def test_external_controller_takes_the_law_and_the_car_becomes_the_plant(tmp_path):
    from mr_damper_bringup.full_car_suite import (external_full_car, FULL_CAR_CTRL,
                                                  FULL_CAR_MANAGER)
    args = _args(30.0)
    args.set = ['full_car_node.controller=per-corner-skyhook']
    cfg = resolve_config(args, tmp_path)
    _, car = full_car_configs(cfg, tmp_path, 30.0)
    assert not external_full_car(car) and FULL_CAR_CTRL not in car
    _, car = full_car_configs(cfg, tmp_path, 30.0, external=True)
    assert external_full_car(car)
    law = car[FULL_CAR_CTRL]['ros__parameters']
    plant = car[FULL_CAR]['ros__parameters']
    assert law['controller'] == 'per-corner-skyhook' and plant['controller'] == 'external'
    for name in ('safe_current_a', 'param_timeout_s', 'min_current_span_a'):
        assert law[name] == plant[name]                    # the same supervisor settings
    # the vehicle controller on every corner's live identifier, at the car's cycle, brought
    # up by the lifecycle manager
    assert law['model_files'] == [''] * 4 and law['cycle_s'] == 0.002
    assert car[FULL_CAR_MANAGER]['ros__parameters']['node_names'] == [FULL_CAR_CTRL]
    # a configuration already external keeps its controller section's law
    _, again = full_car_configs(cfg | car, tmp_path, 30.0)
    assert again[FULL_CAR_CTRL]['ros__parameters']['controller'] == 'per-corner-skyhook'


def test_preview_runs_the_preview_law_in_the_controller_on_the_cars_frames(tmp_path):
    from mr_damper_bringup.full_car_suite import external_full_car, FULL_CAR_CTRL, PREVIEW_LAW
    from mr_damper_bringup.launcher import parse_args
    cfg = resolve_config(_args(30.0), tmp_path)
    _, car = full_car_configs(cfg, tmp_path, 30.0, preview=True)
    assert external_full_car(car)
    law = car[FULL_CAR_CTRL]['ros__parameters']
    plant = car[FULL_CAR]['ros__parameters']
    assert law['controller'] == PREVIEW_LAW == 'preview-look-ahead'
    assert plant['controller'] == 'external' and plant['road_preview'] is True
    assert law['safe_current_a'] == plant['safe_current_a']
    assert parse_args(['--config', 'full-car', '--preview']).preview
    with pytest.raises(SystemExit):
        parse_args(['--config', 'sim', '--preview'])
