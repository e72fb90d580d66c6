"""The run log's format, version 1 (``shared/design.md``): topics, schemas and the
encoding of each record. Used by the writer, reader and recovery modules.

- Header: profile ``beambench``, library ``beambench <version>``.
- Metadata ``rig``: ``json`` = ``Rig.to_json()`` plus one JSON string per section;
  ``run``: strings as they are, other values as JSON (keys listed in ``_json_keys``).
- ``log_time``: run clock, int ns (zero = the DAQ's first sample; sample times have the
  anti-alias group delay removed). ``publish_time``: UTC wall clock of the write, ns.
- ``sequence``: ``/daq/samples`` the output-sample index, ``/camera/image`` the camera's
  frame counter, ``/events`` a counter: a jump is a loss.
- ``/daq/samples``: JSON (schema ``beambench.DaqSample``), one message per sample, each
  gauge's strain also as its own field and the sample's UTC time in ``header.stamp``;
  ``/camera/image``, ``/camera/info``, ``/events``: protobuf ``foxglove.CompressedImage``,
  ``foxglove.CameraCalibration``, ``foxglove.Log`` (``name`` = event name).
- Chunks: zstd; frames go in chunks of their own (up to 8 frames) so reading samples
  never decompresses images; every flush ends a chunk and fsyncs.
"""

from __future__ import annotations

import json
import math
import operator
import re
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from itertools import chain
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.Log_pb2 import Log
from google.protobuf.message import DecodeError
from mcap_protobuf.schema import build_file_descriptor_set

from daq.errors import DaqInputError
from daq.imageinfo import image_encoding, image_size_px
from daq.records import Event

PROFILE = "beambench"
FORMAT_VERSION = "1"
TOPIC_SAMPLES = "/daq/samples"
TOPIC_IMAGE = "/camera/image"
TOPIC_CAMERA_INFO = "/camera/info"
TOPIC_EVENTS = "/events"
TOPICS = (TOPIC_SAMPLES, TOPIC_IMAGE, TOPIC_CAMERA_INFO, TOPIC_EVENTS)
CAMERA_FRAME_ID = "camera"

SAMPLE_SCHEMA_NAME = "beambench.DaqSample"
SAMPLE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": SAMPLE_SCHEMA_NAME,
    "description": "One sample of the 400 Hz DAQ stream after anti-alias filtering and "
    "decimation. Strains are in gauge order from the clamp.",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "description": "acquisition time on the run clock",
            "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
            "required": ["sec", "nsec"],
        },
        "rocker_angle_rad": {"type": ["number", "null"], "description": "rad"},
        "strain": {
            "type": "array",
            "items": {"type": ["number", "null"]},
            "minItems": 4,
            "maxItems": 4,
            "description": "m/m, gauges 1-4",
        },
        "raw_volts": {
            "type": "array",
            "items": {"type": ["number", "null"]},
            "minItems": 5,
            "maxItems": 5,
            "description": "V: potentiometer, then gauges 1-4",
        },
        **{
            f"strain_g{j}": {
                "type": ["number", "null"],
                "description": f"m/m, gauge {j} (= strain[{j - 1}]: one field path per "
                "signal, for plotting tools)",
            }
            for j in range(1, 5)
        },
        "header": {
            "type": "object",
            "description": "the sample's UTC time (stamp = the run's UTC start + the run-clock "
            "timestamp), for tools that show wall-clock time (Foxglove: 'header stamp')",
            "properties": {
                "stamp": {
                    "type": "object",
                    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
                },
                "frame_id": {"type": "string"},
            },
        },
    },
    "required": ["timestamp", "rocker_angle_rad", "strain", "raw_volts"],
}
SAMPLE_SCHEMA_BYTES = json.dumps(SAMPLE_SCHEMA, separators=(",", ":")).encode()

_SAMPLE_FORMAT = (
    '{"timestamp":{"sec":%d,"nsec":%d},"rocker_angle_rad":%r,'
    '"strain":[%r,%r,%r,%r],"raw_volts":[%r,%r,%r,%r,%r],'
    '"strain_g1":%r,"strain_g2":%r,"strain_g3":%r,"strain_g4":%r'
)
# the values already as text (repr, or null when not finite)
_SAMPLE_TEXT = _SAMPLE_FORMAT.replace("%r", "%s")
_HEADER_FORMAT = ',"header":{"stamp":{"sec":%d,"nsec":%d},"frame_id":"daq"}}'
_NO_HEADER = "}"

LEVEL_TO_PROTO = {"info": Log.INFO, "warning": Log.WARNING, "error": Log.ERROR}
PROTO_TO_LEVEL = {v: k for k, v in LEVEL_TO_PROTO.items()}


def software_version() -> str:
    try:
        return version("beambench")
    except PackageNotFoundError:  # a source tree that is not installed
        return "0.0.0+unknown"


def protobuf_schema(message_class: Any) -> tuple[str, bytes]:
    """(schema name, serialized FileDescriptorSet) of a protobuf message class."""
    fds = build_file_descriptor_set(message_class)
    return message_class.DESCRIPTOR.full_name, fds.SerializeToString()


def utc_zero_ns(run_info: dict[str, Any]) -> int | None:
    """The UTC time of run-clock zero, ns since the epoch: the run's ``start_utc`` (when the
    DAQ started) plus its ``preroll_s``; None when the run record does not say."""
    start = run_info.get("start_utc")
    if not isinstance(start, str):
        return None
    try:
        when = datetime.fromisoformat(start.replace("Z", "+00:00"))
    except ValueError:
        return None
    if when.tzinfo is None:
        return None
    preroll = run_info.get("preroll_s", 0.0)
    preroll_s = float(preroll) if isinstance(preroll, int | float) else 0.0
    since = when - datetime(1970, 1, 1, tzinfo=UTC)  # exact, unlike a float timestamp
    whole_us = (since.days * 86_400 + since.seconds) * 1_000_000 + since.microseconds
    return whole_us * 1000 + (round(preroll_s * 1e9) if math.isfinite(preroll_s) else 0)


def encode_samples(
    t_ns: np.ndarray,
    angle: np.ndarray,
    strain: np.ndarray,
    volts: np.ndarray,
    utc_zero_ns: int | None = None,
) -> list[bytes]:
    """One JSON message per sample. Floats use ``repr`` (shortest exact round trip);
    non-finite values become ``null`` (read back as NaN). Each gauge's strain is also its
    own field (``strain_g1`` ...), and with ``utc_zero_ns`` (the UTC time of run-clock
    zero, ns since the epoch) the sample's UTC time is in ``header.stamp``."""
    sec, nsec = np.divmod(t_ns, 1_000_000_000)
    # each value's text once (the four strains appear twice in a message), by C-level map
    values = np.column_stack([angle, strain, volts])  # (n, 10)
    flat = values.ravel().tolist()
    if np.isfinite(values).all():
        text = list(map(repr, flat))
    else:
        text = [repr(x) if math.isfinite(x) else "null" for x in flat]
    k = values.shape[1]
    rows = [text[i : i + k] for i in range(0, len(text), k)]
    if utc_zero_ns is None:
        fmt = _SAMPLE_TEXT + _NO_HEADER
        return [
            (fmt % (s, ns, *r, *r[1:5])).encode()
            for s, ns, r in zip(sec.tolist(), nsec.tolist(), rows, strict=True)
        ]
    usec, unsec = np.divmod(np.asarray(t_ns, np.int64) + np.int64(utc_zero_ns), 1_000_000_000)
    fmt = _SAMPLE_TEXT + _HEADER_FORMAT
    return [
        (fmt % (s, ns, *r, *r[1:5], us, uns)).encode()
        for s, ns, r, us, uns in zip(
            sec.tolist(), nsec.tolist(), rows, usec.tolist(), unsec.tolist(), strict=True
        )
    ]


# Bounds of a plausible /daq/samples value, beyond any bench (not a tolerance): a
# potentiometer turns at most ten times (63 rad), a foil gauge fails below 0.1 m/m, a DAQ
# input range is at most tens of volts. Values outside are damage, not data.
MAX_ABS_ANGLE_RAD = 1e3
MAX_ABS_STRAIN = 1.0
MAX_ABS_VOLTS = 1e3
# the largest image a frame may claim (pixels are decoded later: 64 Mpx is 192 MB as RGB)
MAX_IMAGE_SIDE_PX = 16384
MAX_IMAGE_PIXELS = 64_000_000
MAX_LOG_TIME_NS = 2**63 - 1
_BOUNDS = (MAX_ABS_ANGLE_RAD, *[MAX_ABS_STRAIN] * 4, *[MAX_ABS_VOLTS] * 5)


class BadMessageError(ValueError):
    """A message whose contents break its schema (the reader names the message)."""


def _no_constant(name: str) -> Any:
    raise BadMessageError(f"{name} is not a JSON number")


# ``json.loads(data, parse_constant=_no_constant)`` builds a decoder at each call: one for
# all samples (a bench minute holds 24 000)
_SAMPLE_JSON = json.JSONDecoder(parse_constant=_no_constant)


def _loads_sample(data: bytes) -> Any:
    """``json.loads(data, parse_constant=_no_constant)``, with one decoder."""
    if not isinstance(data, bytes | bytearray):
        return json.loads(data, parse_constant=_no_constant)
    return _SAMPLE_JSON.decode(data.decode(json.detect_encoding(data), "surrogatepass"))


def _number(value: Any, what: str, bound: float) -> float:
    if value is None:  # the writer's spelling of a missing (non-finite) value
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise BadMessageError(f"{what} must be a number or null, got {_kind(value)}")
    try:
        x = float(value)
    except OverflowError:  # an integer beyond any float
        x = math.inf
    if not math.isfinite(x) or abs(x) > bound:
        raise BadMessageError(f"{what} = {value!r} is outside +-{bound:g}")
    return x


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string {value[:20]!r}"
    if value is None:
        return "null"
    if isinstance(value, list | dict):
        return f"a JSON {'array' if isinstance(value, list) else 'object'}"
    return repr(value)


def _count(value: Any, what: str, n: int) -> list[Any]:
    if not isinstance(value, list):
        raise BadMessageError(f"{what} must be an array of {n} numbers, got {_kind(value)}")
    if len(value) != n:
        raise BadMessageError(f"{what} must hold {n} numbers, got {len(value)}")
    return value


def _integer(value: Any, what: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise BadMessageError(f"{what} must be an integer, got {_kind(value)}")
    if not lo <= value <= hi:
        raise BadMessageError(f"{what} = {value} is outside [{lo}, {hi}]")
    return value


def decode_sample(data: bytes) -> tuple[int, list[float]]:
    """(t_ns, [angle, strain x4, volts x5]) of one sample message, checked against the
    schema: a JSON object with an integer timestamp (sec >= 0, 0 <= nsec < 1e9), one
    angle, four strains and five volts, each a finite number within the bounds above
    or null (read as NaN). Raises ``BadMessageError`` (a ``ValueError``)."""
    try:
        d = _loads_sample(data)
    except UnicodeDecodeError as exc:
        raise BadMessageError(f"not UTF-8 JSON ({exc.reason} at byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise BadMessageError(f"not JSON ({exc.msg} at byte {exc.pos})") from None
    except ValueError as exc:  # an integer too long to convert
        raise BadMessageError(f"not JSON ({exc})") from None
    except RecursionError:
        raise BadMessageError("not JSON (nested too deeply)") from None
    if not isinstance(d, dict):
        raise BadMessageError(f"must be a JSON object, got {_kind(d)}")
    for key in ("timestamp", "rocker_angle_rad", "strain", "raw_volts"):
        if key not in d:
            raise BadMessageError(f"lacks '{key}'")
    ts = d["timestamp"]
    if not isinstance(ts, dict) or "sec" not in ts or "nsec" not in ts:
        raise BadMessageError(f"timestamp must be an object with sec and nsec, got {_kind(ts)}")
    sec = _integer(ts["sec"], "timestamp.sec", 0, MAX_LOG_TIME_NS // 1_000_000_000 - 1)
    nsec = _integer(ts["nsec"], "timestamp.nsec", 0, 999_999_999)
    angle, strain, volts = d["rocker_angle_rad"], d["strain"], d["raw_volts"]
    if type(strain) is list and type(volts) is list and len(strain) == 4 and len(volts) == 5:
        values = [angle, *strain, *volts]
        # the common case, ten floats within bounds (NaN and inf fail the comparison)
        if all(type(x) is float and -b <= x <= b for x, b in zip(values, _BOUNDS, strict=True)):
            return sec * 1_000_000_000 + nsec, values
    values = [_number(d["rocker_angle_rad"], "rocker_angle_rad", MAX_ABS_ANGLE_RAD)]
    strain = _count(d["strain"], "strain", 4)
    volts = _count(d["raw_volts"], "raw_volts", 5)
    values += [_number(x, f"strain[{i}]", MAX_ABS_STRAIN) for i, x in enumerate(strain)]
    values += [_number(x, f"raw_volts[{i}]", MAX_ABS_VOLTS) for i, x in enumerate(volts)]
    return sec * 1_000_000_000 + nsec, values


# The writer's own form of a sample (``encode_samples``; logs written before the
# ``strain_gN`` fields and the header hold neither), as a pattern over the whole payload:
# a payload it matches is a JSON object of exactly these keys, in this order, with no
# whitespace, whose ten values are JSON numbers with a fraction or an exponent (floats,
# not ints, to json) and whose times are integers of at most 18 digits. Groups 1 and 2
# are timestamp.sec and .nsec, 3-12 the angle, strains and volts as written. Possessive
# quantifiers (a number never gives back a character: what follows it is never part of
# one) keep the engine from saving states it cannot use, a quarter of its time.
_SEC = rb"(0|[1-9][0-9]{0,17}+)"
_STAMP = rb"-?+(?:0|[1-9][0-9]{0,17}+)"
_FLOAT = rb"-?+(?:0|[1-9][0-9]*+)(?:\.[0-9]++(?:[eE][-+]?+[0-9]++)?+|[eE][-+]?+[0-9]++)"
_WRITTEN_SAMPLE = re.compile(
    rb'\{"timestamp":\{"sec":' + _SEC + rb',"nsec":' + _SEC + rb"\},"
    rb'"rocker_angle_rad":(' + _FLOAT + rb"),"
    rb'"strain":\[' + rb",".join([rb"(" + _FLOAT + rb")"] * 4) + rb"\],"
    rb'"raw_volts":\[' + rb",".join([rb"(" + _FLOAT + rb")"] * 5) + rb"\]"
    + rb"(?:" + b"".join(rb',"strain_g%d":' % j + _FLOAT for j in range(1, 5)) + rb")?+"
    + rb'(?:,"header":\{"stamp":\{"sec":' + _STAMP + rb',"nsec":' + _STAMP
    + rb'\},"frame_id":"daq"\})?+\}'
)  # fmt: skip
_TIMES_TEXT = operator.methodcaller("group", 1, 2)
_VALUES_TEXT = operator.methodcaller("group", *range(3, 13))
_MAX_SEC = MAX_LOG_TIME_NS // 1_000_000_000 - 1


def decode_written_samples(data: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``decode_sample`` of many messages at once, for those in the writer's own form:
    (t_ns int64 (n,), values float64 (n, 10), ok bool (n,)). Where ``ok``, the payload
    matches the writer's form and ``decode_sample`` would return exactly (t_ns, values)
    (the same text to the same ``float``); elsewhere t_ns and values are 0 and only
    ``decode_sample`` says what the message holds or what is wrong with it (a null, an
    integer, a value out of bounds, another recorder's spacing, damage)."""
    n = len(data)
    t_ns = np.zeros(n, np.int64)
    values = np.zeros((n, 10), np.float64)
    try:
        matches = list(map(_WRITTEN_SAMPLE.fullmatch, data))
    except TypeError:  # not bytes: decode_sample's business
        return t_ns, values, np.zeros(n, bool)
    found = [m for m in matches if m is not None]
    if len(found) < n:
        ok = np.fromiter((m is not None for m in matches), bool, n)
    else:
        ok = np.ones(n, bool)
    # at most 18 digits: int64 holds the times; each value's text to float as json does
    times = np.fromiter(map(int, chain.from_iterable(map(_TIMES_TEXT, found))), np.int64)
    sec, nsec = times[0::2], times[1::2]
    got = np.fromiter(map(float, chain.from_iterable(map(_VALUES_TEXT, found))), np.float64)
    got = got.reshape(-1, 10)
    # decode_sample's common case: the times within range, ten floats within bounds
    # (the largest exponents read as inf, which fails)
    within = (sec <= _MAX_SEC) & (nsec <= 999_999_999)
    within &= (np.abs(got) <= np.asarray(_BOUNDS)).all(axis=1)
    ok[ok] = within
    t_ns[ok] = sec[within] * 1_000_000_000 + nsec[within]
    values[ok] = got[within]
    return t_ns, values, ok


def _parse(message: Any, data: bytes, what: str) -> Any:
    try:
        message.ParseFromString(data)
    except DecodeError as exc:
        raise BadMessageError(f"not a {what} protobuf ({exc})") from None
    return message


def _stamp_ns(ts: Any) -> int:
    """The protobuf timestamp in ns (checked: non-negative, nanos within a second)."""
    if ts.seconds < 0 or not 0 <= ts.nanos < 1_000_000_000:
        raise BadMessageError(f"timestamp {ts.seconds} s {ts.nanos} ns is not a run-clock time")
    return int(ts.seconds) * 1_000_000_000 + int(ts.nanos)


def _set_timestamp(ts: Any, t_ns: int) -> None:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    ts.seconds = sec
    ts.nanos = nsec


def encode_image(t_ns: int, data: bytes, encoding: str) -> bytes:
    msg = CompressedImage(frame_id=CAMERA_FRAME_ID, data=data, format=encoding)
    _set_timestamp(msg.timestamp, t_ns)
    return msg.SerializeToString()


def encode_image_parts(t_ns: int, data: bytes, encoding: str) -> tuple[bytes, bytes, bytes]:
    """``encode_image``'s bytes as (before the image, the image itself, after it), so a
    writer can pass the image on without copying it, encoded by hand (building protobuf
    messages for each frame cost more than the rest of its way to the file). Protobuf
    writes known fields in field-number order (timestamp 1, data 2, format 3, frame_id
    4) and leaves out proto3 defaults, so the three joined are ``encode_image``'s output
    byte for byte (a test checks it)."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    stamp = (b"\x08" + _varint(sec) if sec else b"") + (b"\x10" + _varint(nsec) if nsec else b"")
    head = b"\x0a" + _varint(len(stamp)) + stamp
    if data:
        head += b"\x12" + _varint(len(data))
    fmt = encoding.encode()
    tail = (b"\x1a" + _varint(len(fmt)) + fmt if fmt else b"") + _FRAME_ID_FIELD
    return head, data, tail


_FRAME_ID_FIELD = b"\x22" + bytes([len(CAMERA_FRAME_ID)]) + CAMERA_FRAME_ID.encode()


def _varint(n: int) -> bytes:
    """Protobuf's base-128 varint of a non-negative int (times before 1970 never occur:
    log times are unsigned)."""
    if n < 0x80:
        return bytes((n,))
    out = bytearray()
    while n >= 0x80:
        out.append((n & 0x7F) | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def decode_image(data: bytes) -> tuple[int, bytes, str, int, int]:
    """(t_ns, image bytes, "jpeg" | "png", width_px, height_px) of one
    ``foxglove.CompressedImage``, checked: a protobuf that parses, a JPEG or PNG payload
    whose signature matches ``format``, a header with a size within the limits above.
    Raises ``BadMessageError``."""
    msg = _parse(CompressedImage(), data, "foxglove.CompressedImage")
    t_ns = _stamp_ns(msg.timestamp)
    image = msg.data  # each read of the field copies the image
    kind = image_encoding(image)
    if kind is None:
        raise BadMessageError(
            f"the image ({len(image)} bytes, format {msg.format[:20]!r}) is not a JPEG or PNG"
        )
    if msg.format != kind:
        raise BadMessageError(f"format says {msg.format[:20]!r} but the image is a {kind}")
    try:
        width, height = image_size_px(image)
    except DaqInputError as exc:
        raise BadMessageError(str(exc).removeprefix("data: ")) from None
    if not (
        1 <= width <= MAX_IMAGE_SIDE_PX
        and 1 <= height <= MAX_IMAGE_SIDE_PX
        and width * height <= MAX_IMAGE_PIXELS
    ):
        raise BadMessageError(
            f"the {kind} header claims {width} x {height} px (at most {MAX_IMAGE_SIDE_PX} a "
            f"side and {MAX_IMAGE_PIXELS / 1e6:g} Mpx)"
        )
    return t_ns, image, kind, width, height


def encode_event(event: Event) -> bytes:
    msg = Log(level=LEVEL_TO_PROTO[event.level], message=event.message, name=event.name)
    _set_timestamp(msg.timestamp, event.t_ns)
    return msg.SerializeToString()


def decode_event(data: bytes) -> Event:
    """One ``foxglove.Log`` as an ``Event`` (levels other than warning and error read as
    info; a negative time is allowed: the writer logs events before the run clock's zero
    at log time 0). Raises ``BadMessageError``."""
    msg = _parse(Log(), data, "foxglove.Log")
    if not 0 <= msg.timestamp.nanos < 1_000_000_000:
        raise BadMessageError(f"timestamp nanos {msg.timestamp.nanos} outside [0, 1e9)")
    if not msg.name:
        raise BadMessageError("an event needs a name")
    t_ns = msg.timestamp.seconds * 1_000_000_000 + msg.timestamp.nanos
    return Event(t_ns, PROTO_TO_LEVEL.get(msg.level, "info"), msg.name, msg.message)


def check_camera_info(info: dict[str, Any]) -> dict[str, Any]:
    """Validate the ``camera_info`` dict (foxglove.CameraCalibration content)."""
    for key in ("width", "height", "K"):
        if key not in info:
            raise DaqInputError(f"camera_info must have '{key}', got keys {sorted(info)}")
    k = [float(x) for x in info["K"]]
    if len(k) != 9:
        raise DaqInputError(f"camera_info['K'] must have 9 numbers, got {len(k)}")
    return {
        "width": int(info["width"]),
        "height": int(info["height"]),
        "K": k,
        "D": [float(x) for x in info.get("D", ())],
        "distortion_model": str(info.get("distortion_model", "plumb_bob")),
    }


def encode_camera_info(info: dict[str, Any], t_ns: int = 0) -> bytes:
    k = info["K"]
    msg = CameraCalibration(
        frame_id=CAMERA_FRAME_ID,
        width=info["width"],
        height=info["height"],
        distortion_model=info["distortion_model"],
        D=info["D"],
        K=k,
        R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        P=[k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0],
    )
    _set_timestamp(msg.timestamp, t_ns)
    return msg.SerializeToString()


def decode_camera_info(data: bytes) -> dict[str, Any]:
    """``foxglove.CameraCalibration`` content, checked: a size within the image limits,
    nine finite numbers in K, finite D. Raises ``BadMessageError``."""
    msg = _parse(CameraCalibration(), data, "foxglove.CameraCalibration")
    if not (1 <= msg.width <= MAX_IMAGE_SIDE_PX and 1 <= msg.height <= MAX_IMAGE_SIDE_PX):
        raise BadMessageError(f"camera size {msg.width} x {msg.height} px is not plausible")
    if len(msg.K) != 9 or not all(math.isfinite(k) for k in msg.K):
        raise BadMessageError(f"K must hold 9 finite numbers, got {list(msg.K)[:12]}")
    if not all(math.isfinite(d) for d in msg.D):
        raise BadMessageError("D holds a non-finite number")
    return {
        "width": int(msg.width),
        "height": int(msg.height),
        "K": list(msg.K),
        "D": list(msg.D),
        "distortion_model": msg.distortion_model,
    }


def encode_metadata(values: dict[str, Any]) -> dict[str, str]:
    """String values for an MCAP metadata record: strings as they are, anything else as
    JSON, with the JSON-encoded keys listed under ``_json_keys`` so reading is exact."""
    out: dict[str, str] = {}
    json_keys = []
    for key, value in values.items():
        if not isinstance(key, str) or key == "_json_keys":
            raise DaqInputError(f"metadata keys must be strings other than '_json_keys': {key!r}")
        if isinstance(value, str):
            out[key] = value
        else:
            out[key] = json.dumps(value, sort_keys=True)
            json_keys.append(key)
    out["_json_keys"] = ",".join(json_keys)
    return out


def decode_metadata(values: dict[str, str]) -> dict[str, Any]:
    """The values of a metadata record (``encode_metadata``'s inverse). Raises
    ``BadMessageError`` naming the key whose value is not the JSON it claims to be."""
    json_keys = set(filter(None, values.get("_json_keys", "").split(",")))
    out: dict[str, Any] = {}
    for key, value in values.items():
        if key == "_json_keys":
            continue
        if key in json_keys:
            try:
                out[key] = json.loads(value, parse_constant=_no_constant)
            except ValueError as exc:
                raise BadMessageError(f"{key!r} is not valid JSON ({exc})") from None
            except RecursionError:
                raise BadMessageError(f"{key!r} is JSON nested too deeply") from None
        else:
            out[key] = value
    return out


def decode_rig_record(values: dict[str, str]) -> str:
    """The rig configuration of a ``rig`` metadata record as a JSON string: the
    ``json`` entry, checked to be a JSON object (unknown keys are the rig loader's
    business, not the log's); "" when the record has no ``json`` entry. The one place
    the log's rig record is interpreted. Raises ``BadMessageError``."""
    text = values.get("json")
    if text is None:
        return ""
    try:
        rig = json.loads(text, parse_constant=_no_constant)
    except ValueError as exc:
        raise BadMessageError(f"'json' is not valid JSON ({exc})") from None
    except RecursionError:
        raise BadMessageError("'json' is JSON nested too deeply") from None
    if not isinstance(rig, dict):
        raise BadMessageError(f"'json' must be a JSON object, got {_kind(rig)}")
    return text
