"""Time integrators: ``radau5`` (adaptive Radau IIA, order 5), the batched fixed-step
Radau IIA for linear time-varying systems, and ``integrate``, the one entry point the models use."""
