"""Tests of quarter_car_sim.analysis.plots (files are written, figures have the panels)."""
import pytest

from semi_active_control import laws as ctl
from quarter_car_sim.plant.quarter_car import LinearDamperPlant
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.analysis.plots import plot_results, plot_tradeoff
from quarter_car_sim.plant.road import iso8608
from quarter_car_sim.simulate.quarter_car import compare


@pytest.mark.slow
def test_plot_results_and_tradeoff(tmp_path):
    road = iso8608('C', 20.0, 3.0, rng=1)
    res = compare(QuarterCarParams(), road, [ctl.Passive(0.0)], LinearDamperPlant(1000.0))
    fig = plot_results(res, tmp_path / 'r.png')
    assert len(fig.axes) == 4 and (tmp_path / 'r.png').stat().st_size > 1000
    fig = plot_tradeoff({'passive': [(0.3, 1.0, '0 A'), (0.2, 1.5, '2 A')]}, tmp_path / 't.png',
                        points={'skyhook': (0.3, 0.9)})
    assert (tmp_path / 't.png').stat().st_size > 1000
