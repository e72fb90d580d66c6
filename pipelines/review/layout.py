"""The Rerun layouts of a review: colours, units, entity names and the blueprints.

Two layouts, one per kind of recording (see ``pipelines.review.viewer`` for what is logged
where):

- ``processed``: the camera with the measurement and simulation overlays over the error
  summary (with the colour key; the event log in a tab beside it); rocker angle and, per
  gauge, the measured and simulated strain with their residual underneath; the tip deflection
  from images, strains and simulation with its residuals over the paper's Fig. 11 with axes
  and a marker at the current time.
- ``raw``: what a log holds before processing (``beambench replay``): the camera, the events,
  the rocker angle and the measured strains, no empty panel.
- ``live``: a capture as it is recorded (``beambench capture --spawn``): the raw layout and
  the tip deflection measured on the frames shown.
- ``campaign``: a campaign's frequency response (``beambench campaign --rrd``): tip
  amplitude (mm) and phase lag (deg) of the crank fundamental against the crank frequency,
  each run's image, strain and simulation values with their 2-sd bounds and a sweep's
  curves over them, beside the campaign's table and the selected run's card
  (:func:`build_campaign_blueprint`; entities in ``pipelines.review.campaign_view``).

Series are shown in degrees, millimetres and microstrain; results files keep SI.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun as rr
import rerun.blueprint as rrb

N_GAUGES_IN_LAYOUT = 4  # the bench has four gauges; the blueprint shows one panel each
LAYOUTS = ("processed", "raw", "live")

COLOUR_MEASURED = (31, 119, 180)
COLOUR_STRAIN = (255, 127, 14)
COLOUR_SIM = (44, 160, 44)
COLOUR_HUB = (214, 39, 40)
COLOUR_RIGID = (148, 103, 189)
COLOUR_CENTRELINE = (23, 190, 207)
COLOUR_TIP = (255, 221, 0)
COLOUR_DIFFERENCE = (227, 119, 194)
COLOUR_RESIDUAL = (127, 127, 127)
COLOUR_AXES = (160, 160, 160)

# display scale of each SI unit: value_display = scale * value_si
DEG_PER_RAD = 57.29577951308232
MM_PER_M = 1e3
MICROSTRAIN = 1e6


def gauge_entity(prefix: str, j: int) -> str:
    """Entity path of gauge ``j`` (0-based): ``/daq/strain``, 0 -> ``/daq/strain/g1``."""
    return f"{prefix}/g{j + 1}"


def _gauge_panel(j: int, raw: bool) -> rrb.View | rrb.Container:
    strain = rrb.TimeSeriesView(
        name=f"strain g{j + 1} (µε)",
        origin="/",
        contents=[gauge_entity("/daq/strain", j)]
        if raw
        else [gauge_entity("/daq/strain", j), gauge_entity("/sim/strain", j)],
    )
    if raw:
        return strain
    residual = rrb.TimeSeriesView(
        name=f"g{j + 1} measured - sim (µε)",
        origin="/",
        contents=[gauge_entity("/residual/strain", j)],
    )
    return rrb.Vertical(strain, residual, row_shares=[3, 2])


def build_blueprint(
    kind: str = "processed",
    n_gauges: int = N_GAUGES_IN_LAYOUT,
    fig11_bounds: Sequence[float] | None = None,
) -> rrb.Blueprint:
    """The layout of a ``kind`` recording (``processed`` or ``raw``).

    ``fig11_bounds`` = (x_min, x_max, y_min, y_max) of the Fig. 11 view in its own units
    (hub angle in degrees across, -mm up), so the loop fills the view.
    """
    if kind not in LAYOUTS:
        raise ValueError(f"kind must be one of {', '.join(LAYOUTS)}, got {kind!r}")
    raw = kind in ("raw", "live")
    rocker = rrb.TimeSeriesView(
        name="rocker angle (deg)", origin="/", contents=["/daq/rocker_angle"]
    )
    strains = rrb.Grid(*(_gauge_panel(j, raw) for j in range(n_gauges)))
    camera = rrb.Spatial2DView(name="camera", origin="/camera")
    events = rrb.TextLogView(name="events", origin="/events")
    if kind == "live":
        live_tip = rrb.TimeSeriesView(
            name="tip lateral, frames shown (mm)", origin="/", contents=["/tip_lateral/image"]
        )
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Vertical(camera, events, row_shares=[3, 1]),
                rrb.Vertical(rocker, strains, live_tip, row_shares=[1, 3, 1]),
                column_shares=[1, 1],
            ),
            collapse_panels=True,
        )
    if raw:
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Vertical(camera, events, row_shares=[3, 1]),
                rrb.Vertical(rocker, strains, row_shares=[1, 3]),
                column_shares=[1, 1],
            ),
            collapse_panels=True,
        )
    tip = rrb.Vertical(
        rrb.TimeSeriesView(
            name="tip lateral (mm)",
            origin="/",
            contents=["/tip_lateral/**", "/sim/tip_lateral"],
        ),
        rrb.TimeSeriesView(
            name="tip lateral residual (mm)", origin="/", contents=["/residual/tip_lateral/**"]
        ),
        row_shares=[3, 2],
    )
    bounds = None
    if fig11_bounds is not None:
        x0, x1, y0, y1 = (float(v) for v in fig11_bounds)
        bounds = rrb.VisualBounds2D(x_range=[x0, x1], y_range=[y0, y1])
    fig11 = rrb.Spatial2DView(
        name="Fig. 11: tip lateral (mm) vs hub angle (deg)",
        origin="/fig11",
        visual_bounds=bounds,
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                camera,
                rrb.Tabs(rrb.TextDocumentView(name="error summary", origin="/summary"), events),
                row_shares=[4, 3],
            ),
            rrb.Vertical(rocker, strains, row_shares=[2, 7]),
            rrb.Vertical(tip, fig11, row_shares=[4, 3]),
            column_shares=[2, 2, 1.5],
        ),
        collapse_panels=True,
    )


# The campaign recording's x axis: Rerun plots series against a timeline, so the crank
# frequency is one, a sequence in millihertz (integers, shown as e.g. 1450 for 1.45 Hz).
CAMPAIGN_TIMELINE = "crank_frequency_mHz"
CAMPAIGN_SOURCES = ("image", "strain", "sim")
COLOUR_BY_SOURCE = {"image": COLOUR_MEASURED, "strain": COLOUR_STRAIN, "sim": COLOUR_SIM}


def run_entity(run: str) -> str:
    """``/runs/<run>``, the run's name escaped as one path part."""
    return f"/runs/{rr.escape_entity_path_part(run)}"


def campaign_entity(run: str, quantity: str, source: str) -> str:
    """``/runs/<run>/<quantity>/<source>``."""
    return f"{run_entity(run)}/{quantity}/{source}"


def build_campaign_blueprint(runs: Sequence[str], with_sweep: bool) -> rrb.Blueprint:
    """The layout of a campaign recording of ``runs`` (names), a sweep's curves if given."""

    def response(quantity: str, title: str) -> rrb.TimeSeriesView:
        contents = [f"{run_entity(r)}/{quantity}/**" for r in runs]
        if with_sweep:
            contents.append(f"/sweep/{quantity}/**")
        return rrb.TimeSeriesView(name=title, origin="/", contents=contents)

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                response("amplitude", "tip amplitude (mm) vs crank frequency (mHz)"),
                response("phase_lag", "tip phase lag behind rocker (deg) vs crank frequency (mHz)"),
                row_shares=[1, 1],
            ),
            rrb.Vertical(
                rrb.TextDocumentView(name="campaign", origin="/summary"),
                rrb.Tabs(*(rrb.TextDocumentView(name=r, origin=run_entity(r)) for r in runs)),
                row_shares=[3, 2],
            ),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=CAMPAIGN_TIMELINE),
        collapse_panels=True,
    )
