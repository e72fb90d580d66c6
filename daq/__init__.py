"""beambench acquisition: device protocols, real drivers, fakes, anti-alias
filtering and decimation, and the MCAP run log. No physics, no image analysis;
imports neither ``sim`` nor ``vision``.

Modules:

- ``records``: ``RawBlock``, ``SampleBlock``, ``Frame``, ``Event`` (int64 ns, run clock)
- ``protocols``: ``StrainDaq`` and ``Camera`` (what capture needs from a device)
- ``calibration``: bridge volts <-> strain (exact), potentiometer volts <-> angle
- ``antialias``: Butterworth design at the acquisition rate, streaming decimator
- ``stream``: raw blocks -> calibrated 400 Hz ``SampleBlock``
- ``fakes``: ``FakeStrainDaq``, ``FakeCamera`` fed by callables, with fault switches
- ``nidaq``: NI-DAQmx driver (``nidaqmx`` imported lazily)
- ``opencv_camera``: V4L2 device, video file, folder of stills (``exif``, ``imageinfo``)
- ``log``: the MCAP run log (``log_format``, ``log_writer``, ``log_reader``, ``log_recover``)
- ``replay``: a log back as records, merged in log-time order, optionally paced
- ``clock``, ``errors``: injectable clocks; the package's exceptions
"""
