"""
Offline optimal semi-active bounds: the best ride any semi-active law could get (full preview).

Modules: ``quarter_car`` (:func:`~quarter_car_sim.bound.quarter_car.semi_active_bound`, the
force models and the replay on the plant), ``full_car``
(:func:`~quarter_car_sim.bound.full_car.full_car_bound`, four inputs, the ISO 2631-1 cost).
See docs/control-laws.md and docs/full-car.md.
"""
