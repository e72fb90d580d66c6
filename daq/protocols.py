"""Device interfaces: what the capture loop needs from a strain DAQ and a camera.

Real drivers (``daq.drivers.nidaq``, ``daq.drivers.opencv_camera``) and fakes
(``daq.fakes``) implement these; the capture loop only ever sees the Protocol.
"""

from __future__ import annotations

from types import TracebackType
from typing import Protocol, runtime_checkable

from daq.records import Frame, RawBlock


@runtime_checkable
class StrainDaq(Protocol):
    """One hardware-timed task reading the potentiometer and the four bridges.

    ``sample_rate_hz`` is the rate the hardware really uses (valid after ``start``).
    ``read_block`` returns the next block of raw volts at that rate, with int64 ns times
    on the run clock; raises ``DeviceTimeoutError`` when nothing arrives within
    ``timeout_s``. ``start(first_sample_ns)`` puts the first sample at that run-clock
    time: capture starts the acquisition before the run clock's zero (a negative time,
    the pre-roll) so the anti-alias filter has settled by zero.
    """

    backend: str

    @property
    def sample_rate_hz(self) -> float: ...

    def start(self, first_sample_ns: int = 0) -> None: ...

    def read_block(self, timeout_s: float) -> RawBlock: ...

    def stop(self) -> None: ...

    def describe(self) -> dict[str, object]: ...

    def __enter__(self) -> StrainDaq: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


@runtime_checkable
class Camera(Protocol):
    """A camera delivering encoded frames stamped at mid-exposure on the run clock.

    ``read_frame`` returns the next frame, ``None`` when the source is exhausted (a
    video file or folder of stills), and raises ``DeviceTimeoutError`` when nothing
    arrives within ``timeout_s``. A jump in ``Frame.sequence`` means dropped frames.
    """

    backend: str

    def start(self) -> None: ...

    def read_frame(self, timeout_s: float) -> Frame | None: ...

    def stop(self) -> None: ...

    def describe(self) -> dict[str, object]: ...

    def __enter__(self) -> Camera: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...
