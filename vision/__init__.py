"""beambench vision: camera model, registration/rectification, centre-line
extraction, hub angle and deflection, and the scene renderer. numpy/scipy/OpenCV
only; imports neither ``sim`` nor ``daq``."""
