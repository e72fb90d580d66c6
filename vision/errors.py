"""The vision package's exceptions: one small tree, messages built by the constructors.

Everything ``vision`` raises on purpose is a :class:`VisionError`. The errors a caller
can trigger with bad input (a configuration value, a calibration file, image bytes,
degenerate points) are also ``ValueError``, the contract of vision's public boundary
that callers rely on (``except ValueError``). A frame that gives no measurement is a
:class:`FrameFailure`, which :meth:`vision.measure.Measurer.measure` turns into
``ok=False`` with the reason; it is not a ``ValueError``.
"""

from __future__ import annotations


class VisionError(Exception):
    """Base class of every error raised by ``vision``."""


class ParameterError(VisionError, ValueError):
    """A value ``vision`` cannot use: a configuration field, an argument. The message
    starts with the parameter's name."""

    def __init__(self, name: str, problem: str) -> None:
        self.name = name
        self.problem = problem
        super().__init__(f"{name} {problem}")


class CalibrationError(VisionError, ValueError):
    """A calibration that cannot be made or used: a CAL.json file that cannot be read or
    says something impossible, registration points that give no usable mapping, a
    checkerboard not found. The message says why without naming the file (the caller
    knows it); ``section`` is the part of the calibration at fault, when it is one."""

    def __init__(self, problem: str, *, section: str | None = None) -> None:
        self.problem = problem
        self.section = section
        super().__init__(f"{section}: {problem}" if section else problem)


class DegeneratePointsError(VisionError, ValueError):
    """Point sets that cannot determine a collineation; ``points`` names the set."""

    def __init__(self, points: str | None, problem: str) -> None:
        self.points = points
        self.problem = problem
        super().__init__(f"{points}: {problem}" if points else problem)


class RegistrationError(VisionError, ValueError):
    """The registration object is not in an image (``found`` False), or what was found
    does not fit it; ``problem`` says what was seen."""

    def __init__(self, problem: str, *, found: bool) -> None:
        self.problem = problem
        self.found = found
        subject = "registration object" if found else "registration object not found"
        super().__init__(f"{subject}: {problem}")


class DecodeError(VisionError, ValueError):
    """Image bytes that do not decode (``n_bytes`` of them)."""

    def __init__(self, n_bytes: int) -> None:
        self.n_bytes = n_bytes
        super().__init__(
            "empty image data" if n_bytes == 0 else "not a readable image (JPEG/PNG/...)"
        )


class CorruptImageError(VisionError, ValueError):
    """Image bytes whose own checks fail (a PNG chunk's CRC, a PNG cut short)."""

    def __init__(self, problem: str) -> None:
        self.problem = problem
        super().__init__(f"a damaged image: {problem}")


class ImageSizeError(VisionError, ValueError):
    """Image bytes whose header claims a size beyond what beambench decodes."""

    def __init__(self, width_px: int, height_px: int, max_side_px: int) -> None:
        self.width_px = width_px
        self.height_px = height_px
        mb = width_px * height_px / 1e6
        super().__init__(
            f"the image header claims {width_px} x {height_px} px (would decode to {mb:.0f} MB); "
            f"images of at most {max_side_px} px a side are read"
        )


class EncodeError(VisionError, ValueError):
    """An image the codec library refused to compress."""

    def __init__(self, encoding: str) -> None:
        self.encoding = encoding
        super().__init__(f"the image could not be encoded as {encoding}")


class BehindCameraError(VisionError, ValueError):
    """A beam-plane point that the synthetic camera cannot see: it lies behind it."""

    def __init__(self) -> None:
        super().__init__("a point lies behind the camera")


class FrameFailure(VisionError):
    """A frame that gives no measurement; ``reason`` says why (it becomes the
    measurement's ``reason``)."""

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(reason)
