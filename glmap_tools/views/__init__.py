"""Images and files of a GLMap: rendered units, selected views, situated views, top-down, PLY.

Pure functions that take a `GLMap` and return dataclasses (images as uint8 arrays with
their cameras); see design.md.
"""

from glmap_tools.views.common import (
    DEFAULT_HFOV_DEG,
    MAX_VIEW_SIDE,
    RenderedView,
    encode_png,
    view_intrinsics,
)
from glmap_tools.views.export import ExportResult, export_ply, write_bytes_atomic, write_png
from glmap_tools.views.selection import (
    Candidate,
    NoFreeViewpointError,
    SelectionConfig,
    ViewChoice,
    render_selected_view,
    select_view,
)
from glmap_tools.views.situated import SituatedViews, situated_poses, situated_views
from glmap_tools.views.targets import (
    map_gaussians,
    overview_pose,
    render_gaussians,
    render_map,
    render_subset,
    render_unit,
    unit_gaussians,
)
from glmap_tools.views.topdown import HeatMap, TopDownImage, draw_topdown
from glmap_tools.views.visibility import Visibility, visibility

__all__ = [
    "DEFAULT_HFOV_DEG",
    "MAX_VIEW_SIDE",
    "Candidate",
    "ExportResult",
    "HeatMap",
    "NoFreeViewpointError",
    "RenderedView",
    "SelectionConfig",
    "SituatedViews",
    "TopDownImage",
    "ViewChoice",
    "Visibility",
    "draw_topdown",
    "encode_png",
    "export_ply",
    "map_gaussians",
    "overview_pose",
    "render_gaussians",
    "render_map",
    "render_selected_view",
    "render_subset",
    "render_unit",
    "select_view",
    "situated_poses",
    "situated_views",
    "unit_gaussians",
    "view_intrinsics",
    "visibility",
    "write_bytes_atomic",
    "write_png",
]
