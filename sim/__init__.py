"""beambench simulator: the four-bar, the beam models on a prescribed hub, their time
integration, statics, strain recovery and damping relations. numpy/scipy only; imports
neither ``vision``, ``daq`` nor ``pipelines``.

Sub-packages:

- ``sim.solvers``: time integrators (adaptive and batched linear Radau IIA, ``integrate``).
- ``sim.models``: beam models (rigid, modal, modal_nonlinear, fe, ``auto``) and their registry.

Modules: ``errors`` (the ``SimError`` tree), ``config``, ``beam``, ``result``, ``checks``
(shared input checks), ``four_bar``, ``drives``, ``damping``, ``modes``, ``statics``,
``falling_body``, ``scenes`` (what ``beambench sim`` runs).
"""
