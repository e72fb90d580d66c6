"""beambench acquisition: device protocols, real drivers, fakes, anti-alias
filtering and decimation, and the MCAP run log. No physics, no image analysis;
imports neither ``sim`` nor ``vision`` (nor ``pipelines``).

Modules, in the order data flows through them:

- ``records``: ``RawBlock``, ``SampleBlock``, ``Frame``, ``Event`` (int64 ns, run clock)
- ``config``: gauges, potentiometer and DAQ settings (frozen, validated dataclasses)
- ``errors``: the one exception tree under ``DaqError`` (``DaqInputError`` for a bad
  setting or argument, ``DeviceError``, ``DriverUnavailableError``, ``LogError``)
- ``protocols``: ``StrainDaq`` and ``Camera`` (what capture needs from a device)
- ``drivers/``: real devices, vendor SDKs imported lazily: ``nidaq`` (NI-DAQmx),
  ``opencv_camera`` (V4L2 device, video file, folder of stills), ``exif`` (still times)
- ``fakes``: ``FakeStrainDaq``, ``FakeCamera`` fed by callables, with fault switches
- ``clock``: injectable clocks for fakes and replay
- ``bridge``: bridge volts <-> strain (exact), potentiometer volts <-> angle
- ``antialias``: Butterworth design at the acquisition rate, streaming decimator
- ``stream``: raw blocks -> calibrated 400 Hz ``SampleBlock``
- ``imageinfo``: size and encoding of a JPEG or PNG from its header
- ``log/``: the MCAP run log: ``format`` (topics, schemas, encodings), ``writer``,
  ``reader``, ``recover``, ``summary`` (what ``beambench info`` prints); its names are
  gathered in ``daq.log``
- ``replay``: a log back as records, merged in log-time order, optionally paced (the
  engine ``beambench replay`` uses)
"""
