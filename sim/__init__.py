"""beambench simulator: four-bar kinematics, beam models (rigid, modal, nonlinear
finite element), drives, integration, statics, strain recovery, damping relations.
numpy/scipy only; imports neither ``vision`` nor ``daq``."""
