"""The rig configuration: every number of the bench, loaded from TOML.

Each section maps onto a frozen dataclass owned by the package that uses it
(``sim``: linkage, beam, damping, drive; ``daq``: gauges, potentiometer, daq;
``vision``: camera, camera_pose, registration; ``pipelines``: hub, synthetic). This
module does the generic part: unknown, missing or mistyped keys, ``_deg`` spellings
of ``_rad`` keys, and checks that cross sections. Any problem is a ``RigError``
naming the file and the key.

A log's ``rig`` record is read by :func:`rig_from_log_record`: our JSON form, another
recorder's flat string entries (``beam_length_m = "0.835"``), or no record at all.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from daq.config import DaqConfig, GaugeConfig, PotentiometerConfig
from pipelines.errors import RigError
from sim.config import BeamConfig, DampingConfig, DriveConfig, LinkageConfig
from sim.models.registry import MODELS
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig

DEFAULT_RIG_NAME = "rig.toml"
DEFAULT_SOURCE = f"<package>/{DEFAULT_RIG_NAME}"

log = logging.getLogger(__name__)


# reciprocating: the crank turns (the paper's dynamic runs); free_decay: the hub is held
# still and the tip is released from a static deflection (the paper's damping runs, §5.2.1)
SYNTHETIC_SCENES = ("reciprocating", "free_decay")


# Upper limits of the synthetic bench's imperfections, each with its reason: noise beyond
# them buries the signal; the warm-up is simulated before every capture starts (a modal
# beam settles in about 10 s; 10 min costs minutes of simulation before the first sample).
SYNTHETIC_LIMITS = {
    "strain_noise": (1e-3, "m/m RMS", "1000 microstrain: the beam yields near 3000"),
    "pot_noise_v": (1.0, "V RMS", "a fifth of the supply"),
    "clock_jitter_s": (1e-2, "s", "a sixth of a frame period at 15 frames/s"),
    "image_noise_dn": (64.0, "DN RMS", "a quarter of the 8-bit range"),
    "warmup_s": (600.0, "s", "simulated before the capture starts"),
    "stamp_latency_s": (0.25, "s", "processing searches the camera-to-DAQ offset within 0.5 s"),
}
# The synthetic camera's brightness levels (DN before lighting) are 8-bit values, the
# lighting's fractional gain must stay positive across the image (see SyntheticConfig).
MAX_DN = 255.0
MAX_LIGHTING_GRADIENT = 1.0  # gain 1 +/- 0.5 at the image's sides
MAX_RELEASE_AT_S = 4 * 3600.0


@dataclass(frozen=True)
class SyntheticConfig:
    """Imperfections of the built-in synthetic bench (fakes and rendered frames)."""

    seed: int = 20051005
    strain_noise: float = 2e-6
    pot_noise_v: float = 0.5e-3
    clock_drift_ppm: float = 20.0
    clock_jitter_s: float = 20e-6
    image_noise_dn: float = 2.0
    model: str = "auto"
    warmup_s: float = 6.0
    scene: str = "reciprocating"
    release_tip_m: float = 0.03
    release_at_s: float = 1.0
    strain_offset: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    # The synthetic camera's picture (vision.synthetic.scene.SceneSpec): the background's
    # and the beam's brightness in DN before lighting (the contrast is their difference;
    # the hub is drawn at the same fraction of it as on the default bench, 190 DN there),
    # and the lighting's fractional change across the image width, left to right.
    background_dn: float = 40.0
    beam_dn: float = 215.0
    lighting_gradient: float = 0.0
    # The synthetic camera stamps each frame this long after its mid-exposure (a camera
    # that stamps on arrival); processing must find it in the camera-to-DAQ offset.
    stamp_latency_s: float = 0.0
    # The hub the synthetic camera draws, m; 0: the rig's [hub] (the shipped rig draws a
    # 200 x 40 mm bar, a bench other than the paper's 68 x 51 mm block on purpose).
    drawn_hub_length_m: float = 0.2
    drawn_hub_width_m: float = 0.04

    def __post_init__(self) -> None:
        for name in (
            "strain_noise",
            "pot_noise_v",
            "clock_jitter_s",
            "image_noise_dn",
            "warmup_s",
            "stamp_latency_s",
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0.0:
                raise ValueError(f"{name} must be a non-negative finite number, got {v!r}")
            limit, unit, why = SYNTHETIC_LIMITS[name]
            if v > limit:
                raise ValueError(f"{name} must be at most {limit:g} {unit} ({why}), got {v!r}")
        for name, limit in (
            ("drawn_hub_length_m", MAX_HUB_LENGTH_M),
            ("drawn_hub_width_m", MAX_HUB_WIDTH_M),
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or not 0.0 <= v <= limit:
                raise ValueError(
                    f"{name} must be 0 (draw [hub]) or a length of at most {limit:g} m, got {v!r}"
                )
        if not math.isfinite(self.clock_drift_ppm) or abs(self.clock_drift_ppm) > 1000.0:
            raise ValueError(
                f"clock_drift_ppm must be within +/-1000, got {self.clock_drift_ppm!r}"
            )
        if self.model not in MODELS:
            raise ValueError(f"model must be auto, rigid, modal or fe, got {self.model!r}")
        if self.scene not in SYNTHETIC_SCENES:
            raise ValueError(f"scene must be {' or '.join(SYNTHETIC_SCENES)}, got {self.scene!r}")
        if not math.isfinite(self.release_tip_m) or not 0.0 < abs(self.release_tip_m) < 0.2:
            raise ValueError(
                f"release_tip_m must be within +/-0.2 m and not 0, got {self.release_tip_m!r}"
            )
        if len(self.strain_offset) != 4 or not all(
            math.isfinite(v) and abs(v) <= 0.01 for v in self.strain_offset
        ):
            raise ValueError(
                "strain_offset must be four finite strains within +/-0.01 (m/m), got "
                f"{list(self.strain_offset)!r}"
            )
        for name in ("background_dn", "beam_dn"):
            v = getattr(self, name)
            if not 0.0 <= v <= MAX_DN:
                raise ValueError(f"{name} must be within 0..{MAX_DN:g} DN (8 bits), got {v!r}")
        if not self.beam_dn > self.background_dn:
            raise ValueError(
                f"beam_dn ({self.beam_dn!r}) must exceed background_dn ({self.background_dn!r}): "
                "the synthetic bench's beam is lit against a dark background"
            )
        if not abs(self.lighting_gradient) <= MAX_LIGHTING_GRADIENT:
            raise ValueError(
                f"lighting_gradient must be within +/-{MAX_LIGHTING_GRADIENT:g} (the light's "
                f"fractional change across the image), got {self.lighting_gradient!r}"
            )
        if not 0.0 <= self.release_at_s <= MAX_RELEASE_AT_S:
            raise ValueError(
                f"release_at_s must be a finite number of seconds within 0..{MAX_RELEASE_AT_S:g} "
                f"(a capture's length), got {self.release_at_s!r}"
            )

    @property
    def hub_dn(self) -> float:
        """The hub's brightness: as far from the background's toward the beam's as on the
        default bench (190 DN between 40 and 215)."""
        return self.background_dn + (self.beam_dn - self.background_dn) * 150.0 / 175.0


# Limits of a hub's size (hints; each with its reason).
MAX_HUB_LENGTH_M = 1.0  # longer than the bench's crank-rocker linkage
MAX_HUB_WIDTH_M = 0.3  # wider than the registration plate


@dataclass(frozen=True)
class HubConfig:
    """The hub: the block the beam is clamped in (the paper's is about 68 mm long and
    51 mm wide). Hints for the image measurement only: it finds the hub in each frame
    (its edges when long, always the beam's root) and the processing compares what it
    found with these. The built-in synthetic bench draws this hub when ``[synthetic]``
    ``drawn_hub_length_m`` and ``drawn_hub_width_m`` are 0 (the shipped rig draws a 200 x
    40 mm bar). The pivot-to-clamp offset is ``[beam] hub_offset_m``."""

    length_m: float = 0.068
    width_m: float = 0.051

    def __post_init__(self) -> None:
        for name, limit, why in (
            ("length_m", MAX_HUB_LENGTH_M, "longer than the linkage"),
            ("width_m", MAX_HUB_WIDTH_M, "wider than the registration plate"),
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0.0:
                raise ValueError(f"{name} must be a positive finite number of m, got {v!r}")
            if v > limit:
                raise ValueError(f"{name} must be at most {limit:g} m ({why}), got {v!r}")


SECTIONS: dict[str, type] = {
    "linkage": LinkageConfig,
    "beam": BeamConfig,
    "damping": DampingConfig,
    "drive": DriveConfig,
    "gauges": GaugeConfig,
    "potentiometer": PotentiometerConfig,
    "daq": DaqConfig,
    "camera": CameraConfig,
    "camera_pose": CameraPoseConfig,
    "registration": RegistrationConfig,
    "hub": HubConfig,
    "synthetic": SyntheticConfig,
}
# Sections a rig file written before they existed may lack: filled from the shipped
# default with a warning naming them (hints only, nothing computed from them).
OPTIONAL_SECTIONS = ("hub",)


@dataclass(frozen=True)
class Rig:
    """The whole bench. ``source`` is where it was loaded from (for messages and logs)."""

    linkage: LinkageConfig = field(default_factory=LinkageConfig)
    beam: BeamConfig = field(default_factory=BeamConfig)
    damping: DampingConfig = field(default_factory=DampingConfig)
    drive: DriveConfig = field(default_factory=DriveConfig)
    gauges: GaugeConfig = field(default_factory=GaugeConfig)
    potentiometer: PotentiometerConfig = field(default_factory=PotentiometerConfig)
    daq: DaqConfig = field(default_factory=DaqConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    camera_pose: CameraPoseConfig = field(default_factory=CameraPoseConfig)
    registration: RegistrationConfig = field(default_factory=RegistrationConfig)
    hub: HubConfig = field(default_factory=HubConfig)
    synthetic: SyntheticConfig = field(default_factory=SyntheticConfig)
    source: str = "<defaults>"

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain dict of every section (SI values), as recorded in logs and results."""
        return {name: dataclasses.asdict(getattr(self, name)) for name in SECTIONS}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)


def default_rig_text() -> str:
    """The shipped rig.toml (the paper's bench)."""
    return resources.files("pipelines").joinpath("data", DEFAULT_RIG_NAME).read_text("utf-8")


def load_rig(path: str | Path | None = None) -> Rig:
    """Load and validate a rig file; ``None`` loads the shipped default."""
    if path is None:
        return parse_rig(default_rig_text(), source=DEFAULT_SOURCE)
    p = Path(path)
    try:
        text = p.read_text("utf-8")
    except FileNotFoundError:
        raise RigError(str(p), None, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(str(p), None, f"cannot read: {exc}") from None
    return parse_rig(text, source=str(p))


def rig_from_json(text: str, source: str = "<log>") -> Rig:
    """Rebuild a rig from ``Rig.to_json()`` output (e.g. the ``rig`` record of a log)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RigError(source, None, f"rig record is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise RigError(source, None, "rig record must be a JSON object")
    return _build(data, source)


# Entries of a log's rig record that describe the record, not the bench.
_RECORD_KEYS = ("json", "_json_keys")
# At most this many keys are named in the warning about a rig record.
_NAMED_KEYS = 8


def rig_from_log_record(
    record: dict[str, str] | None, *, source: str, given: Rig | None = None
) -> tuple[Rig, str | None]:
    """The rig of a run log and, when the record was not wholly understood, the one
    warning line saying what was taken from where (design.md, "Logs from other
    recorders").

    - our JSON form (a ``json`` entry): that rig; ``given`` (``--rig``) replaces it;
    - flat string entries (another recorder, e.g. ``beam_length_m = "0.835"``): each
      key read as ``section.key``, ``section/key``, ``section_key`` or a bare key that
      only one section has (``crank_frequency_hz``); values as JSON where they parse
      (``"0.835"``, ``"[0.005, 0.2]"``, ``"true"``), else as strings. The keys read
      override ``given`` (or the shipped default); the others are named in the warning.
      A value that is understood but not possible (``beam_length_m = "-1"``) is a
      ``RigError`` naming the source and the key, as in a rig file;
    - no record (``None``): ``given`` or the shipped default, with a warning.

    Raises ``RigError``.
    """
    base = given if given is not None else load_rig()
    if record is None:
        return base, f"{source}: the log has no rig record; using {_rig_name(base)}"
    if "json" in record:
        if given is not None:
            return given, None
        return rig_from_json(record["json"], source=source), None
    understood, not_understood = _read_flat(record)
    data = {name: dict(section) for name, section in base.to_dict().items()}
    for (section, key), value in understood.items():
        field_name = _field_of(key, {f.name for f in dataclasses.fields(SECTIONS[section])})
        data[section].pop(field_name, None)
        data[section][key] = value
    rig = _build(
        data, f"{source} (flat entries, the rest from {base.source})", synthetic_view=False
    )
    rig = dataclasses.replace(rig, source=source)
    read = sorted(f"{s}.{k}" for s, k in understood)
    line = (
        f"{source}: the rig record is flat entries, not beambench's JSON: read "
        f"{len(read)} ({_names(read)}), the rest from {_rig_name(base)}"
    )
    if not_understood:
        line += f"; not understood: {_names(not_understood)}"
    return rig, line


def _rig_name(rig: Rig) -> str:
    if rig.source == DEFAULT_SOURCE:
        return f"the shipped default rig ({DEFAULT_SOURCE}; pass --rig RIG.toml for yours)"
    return f"the rig of {rig.source}"


def _names(keys: list[str]) -> str:
    if not keys:
        return "none"
    shown = ", ".join(keys[:_NAMED_KEYS])
    return shown + (f" and {len(keys) - _NAMED_KEYS} more" if len(keys) > _NAMED_KEYS else "")


def _read_flat(record: dict[str, str]) -> tuple[dict[tuple[str, str], Any], list[str]]:
    """``{(section, key): value}`` of the flat entries understood, and the keys not
    understood (unknown, claimed by more than one section, such as ``width_m``, or a
    value that is not of the key's type, such as ``"0.835 m"``)."""
    fields = {name: {f.name for f in dataclasses.fields(cls)} for name, cls in SECTIONS.items()}
    understood: dict[tuple[str, str], Any] = {}
    unknown: list[str] = []
    for raw_key, raw_value in record.items():
        if raw_key in _RECORD_KEYS:
            continue
        places = _places(raw_key, fields)
        if len(places) != 1:
            unknown.append(raw_key + (" (ambiguous)" if places else ""))
            continue
        section, key = places[0]
        hint = typing.get_type_hints(SECTIONS[section])[_field_of(key, fields[section])]
        value = _flat_value(raw_value, hint)
        if not _type_ok(value, hint):  # the type only: values are validated with the rig
            unknown.append(f"{raw_key} ({raw_value[:20]!r} is not {_type_name(hint)})")
            continue
        understood[section, key] = value
    return understood, sorted(unknown)


def _type_ok(value: Any, hint: Any) -> bool:
    if typing.get_origin(hint) is tuple:
        (item,) = {a for a in typing.get_args(hint) if a is not Ellipsis}
        return isinstance(value, list) and all(_type_ok(v, item) for v in value)
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return value is None or any(
            _type_ok(value, a) for a in typing.get_args(hint) if a is not type(None)
        )
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, hint)


def _type_name(hint: Any) -> str:
    if typing.get_origin(hint) is tuple:
        return "a list"
    return {float: "a number", int: "an integer", bool: "true or false"}.get(hint, "a string")


def _places(key: str, fields: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Where a flat key can belong: ``(section, key)`` pairs."""
    k = key.strip().lower()
    for sep in (".", "/"):
        if sep in k:
            section, _, rest = k.partition(sep)
            if section in fields and _field_of(rest, fields[section]) in fields[section]:
                return [(section, rest)]
            return []
    places = {
        (section, k[len(section) + 1 :])
        for section in fields
        if k.startswith(section + "_")
        and _field_of(k[len(section) + 1 :], fields[section]) in fields[section]
    }
    places |= {(name, k) for name in fields if _field_of(k, fields[name]) in fields[name]}
    return sorted(places)


def _flat_value(text: str, hint: Any) -> Any:
    """A flat entry's value for a field of type ``hint``: a string field takes the text
    as it is (``device = "0"``); others parse as JSON (``"0.835"``, ``"true"``, a list
    with or without its brackets); what does not parse stays a string."""
    if hint is str or not isinstance(text, str):
        return text
    candidates = [text.strip()]
    if typing.get_origin(hint) is tuple and not text.strip().startswith("["):
        candidates.append(f"[{text}]")
    for candidate in candidates:
        try:
            value = json.loads(candidate)
        except (ValueError, RecursionError):
            continue
        if typing.get_origin(hint) is not tuple or isinstance(value, list):
            return value
    return text


def parse_rig(text: str, source: str = "<string>") -> Rig:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RigError(source, None, f"not valid TOML: {exc}") from None
    return _build(data, source)


def _build(data: dict[str, Any], source: str, *, synthetic_view: bool = True) -> Rig:
    """The rig of ``data`` checked; ``synthetic_view``: also that the synthetic camera
    (``camera_pose``) sees the registration plate (not asked of another recorder's
    log, whose camera pose the rig does not know)."""
    unknown = sorted(set(data) - set(SECTIONS))
    if unknown:
        raise RigError(
            source, unknown[0], f"unknown section; expected one of {', '.join(SECTIONS)}"
        )
    missing = [name for name in SECTIONS if name not in data and name not in OPTIONAL_SECTIONS]
    if missing:
        raise RigError(source, missing[0], "section is missing")
    defaults = {} if source == DEFAULT_SOURCE else tomllib.loads(default_rig_text())
    built: dict[str, Any] = {}
    for name, cls in SECTIONS.items():
        if name not in data:
            log.warning(
                "%s: [%s] is missing; using the shipped default %s",
                source,
                name,
                ", ".join(f"{k} = {v!r}" for k, v in defaults.get(name, {}).items()),
            )
        section = data[name] if name in data else dict(defaults.get(name, {}))
        if not isinstance(section, dict):
            raise RigError(source, name, "must be a table of key = value pairs")
        section = _fill_missing(cls, section, defaults.get(name, {}), source, name)
        built[name] = _build_section(cls, section, source, name)
    rig = Rig(**built, source=source)
    _cross_check(rig, synthetic_view=synthetic_view)
    return rig


def _field_of(key: str, fields: typing.Collection[str]) -> str:
    """The dataclass field a key sets: ``x_deg`` sets ``x_rad``."""
    if key.endswith("_deg") and key[:-4] + "_rad" in fields:
        return key[:-4] + "_rad"
    return key


def _fill_missing(
    cls: type, section: dict[str, Any], default: dict[str, Any], source: str, name: str
) -> dict[str, Any]:
    """``section`` with every key it lacks taken from the shipped rig's ``default``
    section, with a warning naming them (design.md: never filled without a word): one
    line a section (a log recorded before keys were added lacks all of them)."""
    fields = {f.name for f in dataclasses.fields(cls)}
    given = {_field_of(k, fields) for k in section}
    out = dict(section)
    missing = [key for key in default if _field_of(key, fields) not in given]
    for key in missing:
        out[key] = default[key]
    if len(missing) == 1:
        (key,) = missing
        log.warning(
            "%s: [%s.%s] is missing; using the shipped default %s = %r",
            source,
            name,
            key,
            key,
            default[key],
        )
    elif missing:
        log.warning(
            "%s: [%s] lacks %d keys; using the shipped defaults %s",
            source,
            name,
            len(missing),
            ", ".join(f"{key} = {default[key]!r}" for key in missing),
        )
    return out


def _build_section(cls: type, section: dict[str, Any], source: str, name: str) -> Any:
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for key, value in section.items():
        target = key
        if key.endswith("_deg") and key[:-4] + "_rad" in fields:
            target = key[:-4] + "_rad"
            value = _convert_degrees(value, source, f"{name}.{key}")
        if target not in fields:
            raise RigError(
                source,
                f"{name}.{key}",
                f"unknown key; expected one of {', '.join(sorted(fields))}",
            )
        if target in kwargs:
            raise RigError(source, f"{name}.{key}", "given twice (as _rad and _deg)")
        kwargs[target] = _coerce(value, hints[target], source, f"{name}.{key}")
    for fname, f in fields.items():
        no_default = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        if fname not in kwargs and no_default:
            raise RigError(source, f"{name}.{fname}", "key is missing")
    try:
        return cls(**kwargs)
    except ValueError as exc:
        raise RigError(source, name, str(exc)) from None


def _convert_degrees(value: Any, source: str, key: str) -> Any:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RigError(source, key, f"must be a number of degrees, got {value!r}")
    if not math.isfinite(value):
        raise RigError(source, key, f"must be a finite number of degrees, got {value!r}")
    return math.radians(float(value))


def _coerce(value: Any, hint: Any, source: str, key: str) -> Any:
    origin = typing.get_origin(hint)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise RigError(source, key, f"must be a number, got {type(value).__name__} {value!r}")
        if not math.isfinite(value):
            raise RigError(source, key, f"must be a finite number, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise RigError(source, key, f"must be an integer, got {type(value).__name__} {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise RigError(source, key, f"must be a string, got {type(value).__name__} {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise RigError(source, key, f"must be true or false, got {value!r}")
        return value
    if origin is tuple:
        (item,) = {a for a in typing.get_args(hint) if a is not Ellipsis}
        if not isinstance(value, list | tuple):
            raise RigError(source, key, f"must be a list, got {type(value).__name__} {value!r}")
        return tuple(_coerce(v, item, source, key) for v in value)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        return _coerce(value, args[0], source, key)
    raise TypeError(f"rig loader cannot handle the type {hint!r} of {key}")  # a bug, not input


def registration_corners_px(rig: Rig) -> Any:
    """(4, 2) pixels (x, y) of the registration plate's corners seen by the rig's camera
    pose (ideal pinhole; the lens is left out), or None when a corner is behind it."""
    import numpy as np

    from vision.camera import camera_matrix
    from vision.homography import apply_homography
    from vision.synthetic.pose import camera_extrinsics, ideal_from_plane

    reg, cam = rig.registration, rig.camera
    half = 0.5 * reg.plate_side_m
    c, s = math.cos(reg.angle_rad), math.sin(reg.angle_rad)
    local = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    corners = np.asarray(reg.center_m) + local @ np.array([[c, s], [-s, c]])
    rotation, translation = camera_extrinsics(rig.camera_pose)
    depth = corners @ rotation[2, :2] + translation[2]
    if not np.all(depth > 0.0):
        return None
    k = camera_matrix(cam.focal_length_px, cam.width_px, cam.height_px)
    return apply_homography(ideal_from_plane(k, rotation, translation), corners)


def _check_registration_in_view(rig: Rig) -> None:
    corners = registration_corners_px(rig)
    w, h = rig.camera.width_px, rig.camera.height_px
    if corners is None:
        raise RigError(
            rig.source,
            "registration.center_m",
            "the registration plate is behind the camera (camera_pose)",
        )
    inside = (corners[:, 0] >= 0) & (corners[:, 0] <= w) & (corners[:, 1] >= 0)
    inside &= corners[:, 1] <= h
    if not inside.all():
        worst = corners[~inside][0]
        raise RigError(
            rig.source,
            "registration.center_m",
            f"the registration plate is not wholly in the camera's view: a corner lands at "
            f"({worst[0]:.0f}, {worst[1]:.0f}) px, outside the {w} x {h} image "
            "(move the plate or the camera_pose)",
        )


def _cross_check(rig: Rig, *, synthetic_view: bool = True) -> None:
    """Checks that involve more than one section."""
    if synthetic_view:
        _check_registration_in_view(rig)
    if rig.hub.width_m <= rig.beam.width_m:
        raise RigError(
            rig.source,
            "hub.width_m",
            f"the hub ({rig.hub.width_m!r} m) must be wider than the beam it clamps "
            f"({rig.beam.width_m!r} m): the clamp is where the hub's shoulders end",
        )
    if rig.gauges.positions_m[-1] >= rig.beam.length_m:
        raise RigError(
            rig.source,
            "gauges.positions_m",
            f"the last gauge ({rig.gauges.positions_m[-1]!r} m) is not on the beam "
            f"(free length {rig.beam.length_m!r} m)",
        )
