"""Images and files of a GLMap: rendered units, selected views, situated views, top-down, PLY.

Pure functions that take a `GLMap` and return dataclasses (images as uint8 arrays with
their cameras); see design.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.lazy import lazy_getattr

if TYPE_CHECKING:
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

# Names load their submodule on first use, so importing one light part (say the report
# models) does not import them all (scipy, numba): the MCP server answers its handshake
# before the heavy parts load.
_LAZY = {
    "DEFAULT_HFOV_DEG": "glmap_tools.views.common",
    "MAX_VIEW_SIDE": "glmap_tools.views.common",
    "RenderedView": "glmap_tools.views.common",
    "encode_png": "glmap_tools.views.common",
    "view_intrinsics": "glmap_tools.views.common",
    "ExportResult": "glmap_tools.views.export",
    "export_ply": "glmap_tools.views.export",
    "write_bytes_atomic": "glmap_tools.views.export",
    "write_png": "glmap_tools.views.export",
    "Candidate": "glmap_tools.views.selection",
    "NoFreeViewpointError": "glmap_tools.views.selection",
    "SelectionConfig": "glmap_tools.views.selection",
    "ViewChoice": "glmap_tools.views.selection",
    "render_selected_view": "glmap_tools.views.selection",
    "select_view": "glmap_tools.views.selection",
    "SituatedViews": "glmap_tools.views.situated",
    "situated_poses": "glmap_tools.views.situated",
    "situated_views": "glmap_tools.views.situated",
    "map_gaussians": "glmap_tools.views.targets",
    "overview_pose": "glmap_tools.views.targets",
    "render_gaussians": "glmap_tools.views.targets",
    "render_map": "glmap_tools.views.targets",
    "render_subset": "glmap_tools.views.targets",
    "render_unit": "glmap_tools.views.targets",
    "unit_gaussians": "glmap_tools.views.targets",
    "HeatMap": "glmap_tools.views.topdown",
    "TopDownImage": "glmap_tools.views.topdown",
    "draw_topdown": "glmap_tools.views.topdown",
    "Visibility": "glmap_tools.views.visibility",
    "visibility": "glmap_tools.views.visibility",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


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
