"""The Rerun layout of a run review: colours, gauge entity names and the blueprint.

See ``pipelines.review.viewer`` for what is logged where.
"""

from __future__ import annotations

import rerun.blueprint as rrb

N_GAUGES_IN_LAYOUT = 4  # the bench has four gauges; the blueprint shows one panel each

COLOUR_MEASURED = (31, 119, 180)
COLOUR_STRAIN = (255, 127, 14)
COLOUR_SIM = (44, 160, 44)
COLOUR_HUB = (214, 39, 40)
COLOUR_RIGID = (148, 103, 189)
COLOUR_CENTRELINE = (23, 190, 207)
COLOUR_TIP = (255, 221, 0)


def gauge_entity(prefix: str, j: int) -> str:
    """Entity path of gauge ``j`` (0-based): ``/daq/strain``, 0 -> ``/daq/strain/g1``."""
    return f"{prefix}/g{j + 1}"


def build_blueprint(n_gauges: int = N_GAUGES_IN_LAYOUT) -> rrb.Blueprint:
    """The layout: camera with overlays and the event log on the left; rocker angle,
    one strain panel per gauge (measured and simulated) and tip deflection in the
    middle; the Fig. 11 view on the right."""
    strain_views = [
        rrb.TimeSeriesView(
            name=f"strain g{j + 1}",
            origin="/",
            contents=[gauge_entity("/daq/strain", j), gauge_entity("/sim/strain", j)],
        )
        for j in range(n_gauges)
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial2DView(name="camera", origin="/camera"),
                rrb.Tabs(
                    rrb.TextLogView(name="events", origin="/events"),
                    rrb.TextDocumentView(name="error summary", origin="/summary"),
                ),
                row_shares=[3, 1],
            ),
            rrb.Vertical(
                rrb.TimeSeriesView(
                    name="rocker angle (rad)", origin="/", contents=["/daq/rocker_angle"]
                ),
                rrb.Grid(*strain_views),
                rrb.TimeSeriesView(
                    name="tip lateral (m)",
                    origin="/",
                    contents=["/tip_lateral/**", "/sim/tip_lateral"],
                ),
                row_shares=[1, 2, 1],
            ),
            rrb.Spatial2DView(
                name="Fig. 11: tip lateral (mm, up +) vs hub angle (deg)", origin="/fig11"
            ),
            column_shares=[2, 2, 1],
        ),
        collapse_panels=True,
    )
