"""sensorless-studies: the simulations, studies, benchmarks, documentation data and demo built on the
``sensorless`` library (which never imports this package).

* :mod:`.simulation`: MuJoCo scenes and simulated robots with known ground truth;
* :mod:`.experiments`: the papers' studies (``sensorless experiment …``);
* :mod:`.benchmarks`: speed, scale and accuracy benchmarks (``sensorless benchmark …``);
* :mod:`.example_data`: the data of the documented commands (``sensorless example NAME``);
* :mod:`.demo`: ``sensorless demo`` / ``make demo``;
* :mod:`.cli`: those commands, added to the ``sensorless`` CLI through entry points.
"""

__version__ = "0.1.0"
