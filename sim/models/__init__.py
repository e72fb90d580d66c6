"""Beam models driven by a prescribed hub angle, and the registry that names them.

- ``registry``: the models by name (``MODELS``: auto, rigid, modal, fe), one signature;
- ``rigid``: no deflection, the baseline;
- ``modal``, ``modal_nonlinear``: assumed modes, linear and to third order;
- ``fe``: the exact nonlinear finite elements, dynamics and statics, in two formulations,
  ``fe_ancf`` (``"corot"``, with the damping laws) and ``fe_flxdyn`` (the paper's element);
- ``model_choice``: ``auto``, the cheapest model whose estimated error is below a tolerance.
"""
