"""The run log's format, version 1 (``shared/design.md``): topics, schemas and the
encoding of each record. Used by the writer, reader and recovery modules.

- Header: profile ``beambench``, library ``beambench <version>``.
- Metadata ``rig``: ``json`` = ``Rig.to_json()`` plus one JSON string per section;
  ``run``: strings as they are, other values as JSON (keys listed in ``_json_keys``).
- ``log_time``: run clock, int ns (zero = the DAQ's first sample; sample times have the
  anti-alias group delay removed). ``publish_time``: UTC wall clock of the write, ns.
- ``sequence``: ``/daq/samples`` the output-sample index, ``/camera/image`` the camera's
  frame counter, ``/events`` a counter: a jump is a loss.
- ``/daq/samples``: JSON (schema ``beambench.DaqSample``), one message per sample;
  ``/camera/image``, ``/camera/info``, ``/events``: protobuf ``foxglove.CompressedImage``,
  ``foxglove.CameraCalibration``, ``foxglove.Log`` (``name`` = event name).
- Chunks: zstd; frames go in chunks of their own (up to 8 frames) so reading samples
  never decompresses images; every flush ends a chunk and fsyncs.
"""

from __future__ import annotations

import json
import math
from importlib.metadata import PackageNotFoundError, version
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap_protobuf.schema import build_file_descriptor_set

from daq.errors import DaqInputError
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
    },
    "required": ["timestamp", "rocker_angle_rad", "strain", "raw_volts"],
}
SAMPLE_SCHEMA_BYTES = json.dumps(SAMPLE_SCHEMA, separators=(",", ":")).encode()

_SAMPLE_FORMAT = (
    '{"timestamp":{"sec":%d,"nsec":%d},"rocker_angle_rad":%r,'
    '"strain":[%r,%r,%r,%r],"raw_volts":[%r,%r,%r,%r,%r]}'
)

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


def encode_samples(
    t_ns: np.ndarray, angle: np.ndarray, strain: np.ndarray, volts: np.ndarray
) -> list[bytes]:
    """One JSON message per sample. Floats use ``repr`` (shortest exact round trip);
    non-finite values become ``null`` (read back as NaN)."""
    sec, nsec = np.divmod(t_ns, 1_000_000_000)
    rows = np.column_stack([angle, strain, volts])
    fmt = _SAMPLE_FORMAT
    if np.isfinite(rows).all():
        return [
            (fmt % (s, ns, *r)).encode()
            for s, ns, r in zip(sec.tolist(), nsec.tolist(), rows.tolist(), strict=True)
        ]
    out = []
    for s, ns, r in zip(sec.tolist(), nsec.tolist(), rows.tolist(), strict=True):
        text = fmt.replace("%r", "%s") % (
            s,
            ns,
            *(repr(x) if math.isfinite(x) else "null" for x in r),
        )
        out.append(text.encode())
    return out


def decode_sample(data: bytes) -> tuple[int, list[Any]]:
    """(t_ns, [angle, strain x4, volts x5]) of one sample message."""
    d = json.loads(data)
    ts = d["timestamp"]
    values = [d["rocker_angle_rad"], *d["strain"], *d["raw_volts"]]
    if len(values) != 10:
        raise ValueError("a DaqSample needs 1 angle, 4 strains and 5 volts")
    return int(ts["sec"]) * 1_000_000_000 + int(ts["nsec"]), values


def _set_timestamp(ts: Any, t_ns: int) -> None:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    ts.seconds = sec
    ts.nanos = nsec


def encode_image(t_ns: int, data: bytes, encoding: str) -> bytes:
    msg = CompressedImage(frame_id=CAMERA_FRAME_ID, data=data, format=encoding)
    _set_timestamp(msg.timestamp, t_ns)
    return msg.SerializeToString()


def decode_image(data: bytes) -> tuple[int, bytes, str]:
    msg = CompressedImage()
    msg.ParseFromString(data)
    return msg.timestamp.seconds * 1_000_000_000 + msg.timestamp.nanos, msg.data, msg.format


def encode_event(event: Event) -> bytes:
    msg = Log(level=LEVEL_TO_PROTO[event.level], message=event.message, name=event.name)
    _set_timestamp(msg.timestamp, event.t_ns)
    return msg.SerializeToString()


def decode_event(data: bytes) -> Event:
    msg = Log()
    msg.ParseFromString(data)
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
    msg = CameraCalibration()
    msg.ParseFromString(data)
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
    json_keys = set(filter(None, values.get("_json_keys", "").split(",")))
    return {
        k: (json.loads(v) if k in json_keys else v) for k, v in values.items() if k != "_json_keys"
    }
