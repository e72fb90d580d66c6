"""The results file's schema: the contract of ``shared/design.md`` ("Results").

- coordinates ``time`` (s since run start, the DAQ samples), ``frame_time`` (s, camera
  frames, on the DAQ run clock: the camera-to-DAQ offset is already applied) and
  ``gauge`` (gauge position from the clamp, m);
- the nine variables of :data:`VARIABLES`, each with ``units`` and ``long_name``;
- optional extras (:data:`OPTIONAL_VARIABLES`);
- global attributes: :data:`REQUIRED_ATTRS` given by the caller, plus the error
  summaries (:mod:`pipelines.results.compare`) and the frame counts, computed by
  :func:`pipelines.results.dataset.make_results` so they always agree with the variables.
"""

from __future__ import annotations

FORMAT_NAME = "beambench-results"


FORMAT_VERSION = 1


# name -> (dims, units, long_name); the order is the order in the file.
VARIABLES: dict[str, tuple[tuple[str, ...], str, str]] = {
    "rocker_angle": (("time",), "rad", "potentiometer (hub) angle"),
    "strain": (("time", "gauge"), "1", "measured surface strain"),
    "hub_angle_image": (("frame_time",), "rad", "hub angle measured in the image"),
    "tip_lateral": (
        ("frame_time",),
        "m",
        "lateral tip deflection relative to the rigid beam, from images",
    ),
    "tip_longitudinal": (("frame_time",), "m", "longitudinal tip deflection, from images"),
    "frame_ok": (("frame_time",), "bool", "whether the frame gave a measurement"),
    "tip_lateral_strain": (
        ("time",),
        "m",
        "lateral tip deflection reconstructed from the four strains",
    ),
    "sim_tip_lateral": (("time",), "m", "simulated lateral tip deflection"),
    "sim_strain": (("time", "gauge"), "1", "simulated strain at the gauges"),
}


OPTIONAL_VARIABLES: dict[str, tuple[tuple[str, ...], str, str]] = {
    # standard uncertainty of each image measurement (design.md; ``measure --json``
    # spells them hub_angle_sd_rad, tip_lateral_sd_m, tip_longitudinal_sd_m)
    "hub_angle_image_sd": (
        ("frame_time",),
        "rad",
        "standard uncertainty of the hub angle measured in the image",
    ),
    "tip_lateral_sd": (
        ("frame_time",),
        "m",
        "standard uncertainty of the lateral tip deflection from images",
    ),
    "tip_longitudinal_sd": (
        ("frame_time",),
        "m",
        "standard uncertainty of the longitudinal tip deflection from images",
    ),
    "sim_tip_longitudinal": (("time",), "m", "simulated longitudinal tip deflection"),
    "hub_angle_sim": (("time",), "rad", "hub angle that drove the simulation"),
    "lateral_at_stations_image": (
        ("frame_time", "station"),
        "m",
        "lateral deflection at stations along the beam, from images",
    ),
}


COORDS: dict[str, tuple[str, str]] = {
    "time": ("s", "time since run start (DAQ samples)"),
    "frame_time": ("s", "camera frame time since run start, on the DAQ clock"),
    "gauge": ("m", "gauge position from the clamp"),
    "station": ("m", "station position from the clamp"),
}


# Global attributes the caller must give to make_results, with their meaning.
REQUIRED_ATTRS: dict[str, str] = {
    "source_log": "path of the run log the results came from",
    "rig_json": "the rig configuration as JSON (pipelines.rig.Rig.to_json)",
    "software_version": "beambench version that processed the run",
    "sim_model": "simulation model used (e.g. 'modal', 'fe-corot')",
    "sim_settings": "simulation settings (dict, stored as JSON)",
    "camera_to_daq_offset_s": "offset added to camera timestamps to get DAQ time (s)",
}
