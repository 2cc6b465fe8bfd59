"""Synthetic scenes with known truth: sensors, terrain, points and rendered images.

A library of building blocks for tests, benchmarks and the demo; nothing here is an
application. The modules:

* :mod:`~geoblock.simulate.sensors`: orbits, true and on-board linescan models;
* :mod:`~geoblock.simulate.onboard`: on-board errors as real satellites have them (attitude
  wander, look-angle and orbital-period ephemeris errors), measured on real products;
* :mod:`~geoblock.simulate.terrain`: true terrain (ridged, fractal) and measured DEMs;
* :mod:`~geoblock.simulate.points`: GCPs, ICPs, TPs and ICTPs with their truth;
* :mod:`~geoblock.simulate.render`: raw images rendered through a model;
* :mod:`~geoblock.simulate.reference`: reference orthos rendered from the ground truth, with
  a known misregistration;
* :mod:`~geoblock.simulate.scenario` and :mod:`~geoblock.simulate.presets`: a whole block
  as one frozen value, read from TOML or taken from the papers' presets;
* :mod:`~geoblock.simulate.scene`: a scenario's components built in memory;
* :mod:`~geoblock.simulate.study`: on-board accuracy and refinement studies on the truth.

Running a scenario into files (``geoblock simulate``) and the demo are workflows:
:mod:`geoblock.workflows`.
"""
