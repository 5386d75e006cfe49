"""
ISO 8608 road roughness: the classes a design assumes (the estimators' process noise).

The standard's displacement PSD is ``Gd(n) = Gd(n0) (n / n0)^-2`` (waviness w = 2) with the
geometric-mean ``Gd(n0)`` of each class, A 16e-6 m^3 and each next class x4 up to H
262144e-6 m^3, over the band 0.011 to 2.83 cycles/m. The simulator's road generator
(:mod:`quarter_car_sim.plant.road`) draws its roads from the same constants.
"""

ISO8608_N0 = 0.1
"""Reference spatial frequency n0 [cycles/m]."""

ISO8608_GD_N0 = {c: 16e-6 * 4.0 ** k for k, c in enumerate('ABCDEFGH')}
"""Geometric-mean displacement PSD Gd(n0) per class [m^3] (A 16e-6 ... H 262144e-6)."""

ISO8608_BAND = (0.011, 2.83)
"""Spatial frequency band of ISO 8608 [cycles/m]."""
