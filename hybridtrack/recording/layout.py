"""The layout (blueprint) embedded in a recording, built from the entities the run logged (docs/recording.md).

:func:`content_blueprint` makes the views — the 3-D world (east, north, up), the
space-time view, one time-series panel per quantity, the events, a map for
geographic entities — and :func:`default_blueprint` the layout of a file whose
run never closed it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

#: the corner of a panel's legend where its quantity seldom has data (default ``RightTop``): ℓ ≤ 0 is dense just
#: below 0 with spikes down; a growing bank ramps from the bottom left
LEGEND_CORNERS = {"loglik": "RightBottom", "bank_size": "LeftTop", "association_loglik": "RightBottom"}

#: the title of the panel of the identified mode / followed hypothesis: one named lane per mode (``mode_lanes``)
MODE_PANEL_TITLE = "Identified mode / followed hypothesis, a lane each"

#: the name of the map view: its background needs the internet (rerun fetches OpenStreetMap tiles), the tracks do not
MAP_VIEW_NAME = "Map (latitude, longitude) · OpenStreetMap tiles load from the internet; offline the tracks are drawn on black"

#: how many steps of points (truth, measurements, estimates, ellipses) the world view shows behind the time cursor
TRAIL_STEPS = 25


#: the view class that shows each archetype (a component ``Archetype:field`` needs a view of this class)
VIEW_CLASSES = {
    "Scalars": "TimeSeries",
    "SeriesLines": "TimeSeries",
    "SeriesPoints": "TimeSeries",
    "Points3D": "3D",
    "LineStrips3D": "3D",
    "ViewCoordinates": "3D",
    "Ellipsoids3D": "3D",
    "Boxes3D": "3D",
    "Arrows3D": "3D",
    "Transform3D": "3D",
    "Points2D": "2D",
    "LineStrips2D": "2D",
    "TextLog": "TextLog",
    "GeoPoints": "Map",
    "GeoLineStrings": "Map",
}

#: time-series panels of ``estimator/<filter>/<quantity>``: quantity → (panel, title), in display order
_ESTIMATOR_PANELS = {
    "bank_size": ("bank_size", "Bank size (filters running)"),
    "mode": ("mode", MODE_PANEL_TITLE),
    "followed": ("mode", MODE_PANEL_TITLE),
    "segment": ("segment", "Segments (summary.json: the turn rate and speed decide), a lane each"),
    "mode_probability": ("mode_probability", "Mode probabilities μ"),
    "nis": ("nis", "NIS (normalized innovation squared) with the χ² 95 % bounds"),
    "nis_bounds": ("nis", "NIS (normalized innovation squared) with the χ² 95 % bounds"),
    "innovation": ("innovation", "Innovations ν"),
    "loglik": ("loglik", "Log-likelihood ℓ"),
    "beta": ("beta", "Association weights β"),
    "gated": ("gated", "Candidates in the gate"),
    "association_loglik": ("association_loglik", "Association ln Λ"),
}
_PANEL_ORDER = list(dict.fromkeys(panel for panel, _ in _ESTIMATOR_PANELS.values()))


def _panel(entity: str, content: Mapping[str, str]) -> tuple[tuple, str, str]:
    """(sort key, title, contents rule) of the time-series panel that shows a scalar entity: one panel per quantity."""
    parts = entity.split("/")
    if parts[0] == "detector" and len(parts) >= 2:
        rule = f"+ /detector/{parts[1]}/**"
        if "signal" in parts[1]:
            return (0, parts[1]), f"Signal function with its bounds ({parts[1]})", rule
        if any(p.startswith(f"detector/{parts[1]}/log_ratio") for p in content):
            return (0, parts[1]), f"ln λ per hypothesis with A and B ({parts[1]})", rule
        return (0, parts[1]), f"Detector {parts[1]}: statistics and thresholds", rule
    if parts[0] == "estimator" and (len(parts) >= 3 or (len(parts) == 2 and parts[1] in _ESTIMATOR_PANELS)):
        quantity = parts[min(2, len(parts) - 1)]  # estimator/<filter>/<quantity>[/…], or estimator/nis_bounds
        key, title = _ESTIMATOR_PANELS.get(quantity, (quantity, quantity.replace("_", " ")))
        order = _PANEL_ORDER.index(key) if key in _PANEL_ORDER else len(_PANEL_ORDER)
        return (1, order, key), title, "+ /" + "/".join(parts[:3]) + "/**"
    if parts[0] == "solver" and len(parts) >= 3:
        title = "Bearing residuals (degrees)" if parts[-1] == "residual" else parts[-1].replace("_", " ")
        return (2, parts[-1]), title, f"+ /{entity}/**"
    if parts[:2] == ["world", "measurements"]:
        return (3, "measurements"), "Scalar measurements", f"+ /{entity}"
    parent = "/".join(parts[:-1]) or parts[0]
    return (4, parent), parent, f"+ /{entity}"


def content_blueprint(
    content: Mapping[str, str] | None = None,
    *,
    time_step: float | None = None,
    eyes: Mapping[str, tuple] | None = None,
    map_zoom: float | None = None,
    timeline: str | None = None,
):
    """The layout embedded in a file, built from what the run logged (the views: docs/recording.md, "Views").

    ``content`` maps every logged entity path to the view class that shows it (:data:`VIEW_CLASSES`); a 3-D
    view of ``/world`` (points of the last :data:`TRAIL_STEPS` steps, ``time_step`` s each on the ``time`` and
    ``utc`` timelines), of ``/spacetime``, one time-series panel per quantity (each listing its entities, so each
    fits its own range; its legend always shown, in the corner of :data:`LEGEND_CORNERS`), the events, and a view
    of the right class for any other root (the map: :data:`MAP_VIEW_NAME`).  ``eyes`` (origin → (position,
    look_target)) places the 3-D cameras; ``map_zoom`` the map view's zoom level (:func:`map_zoom`); ``timeline``
    the timeline the file opens on (``utc`` for real time stamps; None: the viewer's choice, ``step``).
    """
    import rerun.blueprint as rrb

    content = {p.strip("/"): c for p, c in (content or {"world": "3D", "events/decisions": "TextLog"}).items()}
    behind = {"step": ("seq", TRAIL_STEPS)}  # timeline → (unit, the trail's length)
    if time_step is not None and np.isfinite(time_step) and time_step > 0:
        behind["time"] = ("seconds", TRAIL_STEPS * float(time_step))
        if timeline == "utc":
            behind["utc"] = behind["time"]
    cursor = rrb.TimeRangeBoundary.cursor_relative
    trail = [rrb.VisibleTimeRange(line, start=cursor(**{unit: -n}), end=cursor(**{unit: 0 * n})) for line, (unit, n) in behind.items()]

    eye = {  # origin → its camera
        origin: rrb.EyeControls3D(position=at, look_target=target, eye_up=(0.0, 0.0, 1.0)) for origin, (at, target) in (eyes or {}).items()
    }.get

    spatial, other = [], []
    roots = dict.fromkeys((path.split("/")[0], c) for path, c in content.items() if c not in ("TimeSeries", "TextLog"))
    for root, view_class in roots:
        if view_class == "3D" and root == "world":
            spatial.insert(
                0, rrb.Spatial3DView(origin="/world", name="World (east, north, up)", time_ranges=trail, eye_controls=eye("/world"))
            )
        elif view_class == "3D" and root == "spacetime":
            spatial.append(rrb.Spatial3DView(origin="/spacetime", name="Space-time (x, y, scaled time)", eye_controls=eye("/spacetime")))
        elif view_class == "3D":
            spatial.append(rrb.Spatial3DView(origin=f"/{root}", name=root))
        elif view_class == "2D":
            other.append(rrb.Spatial2DView(origin=f"/{root}", name=root))
        elif view_class == "Map":
            other.append(rrb.MapView(origin=f"/{root}", name=MAP_VIEW_NAME if root == "map" else root, zoom=map_zoom))
        else:
            other.append(rrb.View(class_identifier=view_class, origin=f"/{root}", name=root))

    panels: dict[tuple, tuple[str, list[str]]] = {}  # key → (title, the rule of each of its entities)
    for path in (path for path, view_class in content.items() if view_class == "TimeSeries"):
        key, title, rule = _panel(path, content)
        panels.setdefault(key, (title, []))[1].append(rule)

    def legend(key):  # every panel names its series (a long legend is cut at the panel's edge; hover names any line)
        return rrb.PlotLegend(corner=getattr(rrb.Corner2D, LEGEND_CORNERS.get(str(key[-1]), "RightTop")), visible=True)

    whole = rrb.TimeRangeBoundary.infinite()  # the x axis spans all the data (on a clock timeline, not a window at the cursor)
    series = [
        rrb.TimeSeriesView(
            origin="/",
            contents=list(dict.fromkeys(rules)),
            name=title,
            plot_legend=legend(key),
            axis_x=rrb.TimeAxis(view_range=rrb.TimeRange(start=whole, end=whole)),
        )
        for key, (title, rules) in sorted(panels.items(), key=lambda item: tuple(str(k) for k in item[0]))
    ]
    texts = sorted({path.split("/")[0] for path, c in content.items() if c == "TextLog"})
    logs = [rrb.TextLogView(origin=f"/{root}", name="Events" if root == "events" else root) for root in texts]

    left = spatial + other + logs
    shares = [3.0] * len(spatial) + [2.0] * len(other) + [1.0] * len(logs)
    columns = []
    if left:
        columns.append(rrb.Vertical(*left, row_shares=shares) if len(left) > 1 else left[0])
    if series:
        columns.append(rrb.Grid(*series, grid_columns=2 if len(series) > 4 else 1, name="Time series"))
    if not columns:
        columns = [rrb.TextLogView(origin="/events", name="Events")]
    root = rrb.Horizontal(*columns, column_shares=[1, 1]) if len(columns) == 2 else columns[0]
    return rrb.Blueprint(root, *_time_panel(timeline), collapse_panels=True)


def _time_panel(timeline: str | None) -> list:
    """The collapsed time panel on ``timeline`` (none: the viewer picks, ``step``), as parts of a Blueprint."""
    import rerun.blueprint as rrb

    return [] if timeline is None else [rrb.TimePanel(state="collapsed", timeline=timeline)]


def map_zoom(lat_lon: np.ndarray, width: float = 700.0, height: float = 220.0) -> float:
    """The web-map zoom level that shows every (latitude°, longitude°) row in a ``width`` × ``height`` pixel view.

    At zoom z a 256-pixel tile spans 360°/2ᶻ of longitude (web Mercator), and a degree of latitude is
    1/cos φ times as long as a degree of longitude:  z = log₂(360 · min(w / Δλ, h cos φ / Δφ) / 256), less
    half a level of margin, clipped to 1 … 18.
    """
    lat_lon = np.asarray(lat_lon, dtype=np.float64)
    low, high = np.nanmin(lat_lon, axis=0), np.nanmax(lat_lon, axis=0)
    span_lat, span_lon = max(high[0] - low[0], 1e-4), max(high[1] - low[1], 1e-4)
    fit = min(width / span_lon, height * np.cos(np.radians((low[0] + high[0]) / 2)) / span_lat)
    return float(np.clip(np.log2(360.0 * fit / 256.0) - 0.5, 1.0, 18.0))


def default_blueprint(timeline: str | None = None):
    """The layout written at the start of every file, for a file whose run never closed it (killed): the world
    view, the events and one time-series view per root, on ``timeline`` (as :func:`content_blueprint`);
    :meth:`RerunRecorder.close` replaces it by :func:`content_blueprint`."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin="/world", name="World (east, north, up)"),
                rrb.TextLogView(origin="/events", name="Events"),
                row_shares=[3, 1],
            ),
            rrb.Vertical(*[rrb.TimeSeriesView(origin=f"/{root}", name=root) for root in ("detector", "estimator", "solver")]),
            column_shares=[3, 2],
        ),
        *_time_panel(timeline),
        collapse_panels=True,
    )
