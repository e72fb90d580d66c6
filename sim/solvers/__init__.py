"""Time integrators.

- ``radau``: ``radau5``, adaptive Radau IIA (order 5) for the finite-element beams;
- ``linear_radau``: batched Radau IIA for linear time-varying systems (the modal models);
- ``radau_iia``: the one coefficient table both use;
- ``integrate``: the entry point the finite elements use (``radau5`` or scipy's, checked).
"""
