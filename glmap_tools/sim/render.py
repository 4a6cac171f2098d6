"""Offscreen (EGL) rendering of a layout: RGB, metric depth and an exact instance-id mask.

Lighting is baked into per-vertex colours (`face_shade`) and drawn with pyrender's FLAT
pass: software (llvmpipe) rendering stays fast and colours do not depend on the view.
`SceneRenderer`s share one pyrender `OffscreenRenderer` per image size (creating one is
slow; deleting one breaks the others, see `shared_offscreen_renderer`).
Each pass draws one merged mesh in one draw call (a draw call costs pyrender ~0.1 ms of
Python): the colour pass its per-vertex colours, the id pass each object's id colour per
vertex (walls, floors and ceilings 0), through pyrender's SEG pass (multisampling off) with
this package's segmentation shaders (`shaders/`), so every pixel is exactly one object id
or 0; depth is read from the same pass so depth and mask agree pixel for pixel. Both meshes
hold the objects in layout order, then the architecture, and triangles draw in that order,
so where two surfaces tie in depth the same one wins in every process.
"""

from __future__ import annotations

import numbers
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pyrender  # noqa: E402
from pyrender.shader_program import ShaderProgramCache  # noqa: E402

from glmap_tools.errors import InvalidInputError  # noqa: E402
from glmap_tools.geometry import Intrinsics, Pose  # noqa: E402
from glmap_tools.geometry.adapters import to_opengl  # noqa: E402
from glmap_tools.sim.architecture import floor_and_ceiling, room_walls  # noqa: E402
from glmap_tools.sim.layout import Layout  # noqa: E402
from glmap_tools.sim.meshes import PlacedPart, object_parts  # noqa: E402

# Imports inside functions stay there: openGL load on first use; an import that may fail is caught
# where it is used.

Z_NEAR = 0.05  # metres
Z_FAR = 40.0  # metres
SHADER_DIR = Path(__file__).with_name("shaders")  # the id pass's segmentation shaders
MAX_IMAGE_SIDE = 4096  # pixels per side of a rendered view
MAX_CAMERA_HEIGHT = 2.5  # metres above the floor; generated rooms are 2.6 m high


@dataclass(frozen=True)
class CameraSpec:
    """The agent camera: image size, horizontal field of view and height above the floor."""

    width: int = 640
    height: int = 480
    hfov_deg: float = 79.0
    camera_height: float = 0.88

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            side = getattr(self, name)
            if not isinstance(side, numbers.Integral) or not 1 <= int(side) <= MAX_IMAGE_SIDE:
                raise InvalidInputError(
                    f"CameraSpec {name}={side!r} must be a whole number of pixels in "
                    f"1..{MAX_IMAGE_SIDE}, e.g. 640 x 480."
                )
        h = self.camera_height
        if not (isinstance(h, numbers.Real) and 0.0 < h <= MAX_CAMERA_HEIGHT):
            raise InvalidInputError(
                f"CameraSpec camera_height={h!r} m must lie above the floor and below the "
                f"rooms' ceiling: in (0, {MAX_CAMERA_HEIGHT:g}] m, e.g. 0.88 (the agent's)."
            )
        Intrinsics.from_fov(self.width, self.height, self.hfov_deg)  # checks the field of view

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics.from_fov(self.width, self.height, self.hfov_deg)


@dataclass(frozen=True)
class RenderedView:
    """One rendered view.

    Attributes:
        rgb: [H, W, 3] uint8.
        depth: [H, W] float32 metres along the optical axis, 0 where nothing was hit.
        instance_mask: [H, W] int32 layout object ids, 0 for walls, floors, ceilings.
    """

    rgb: np.ndarray  # [H, W, 3]
    depth: np.ndarray  # [H, W]
    instance_mask: np.ndarray  # [H, W]


_OFFSCREEN: dict[tuple[int, int], pyrender.OffscreenRenderer] = {}


class _ColourPassRenderer(pyrender.Renderer):
    """pyrender's renderer, whose pass reads back only its colour image while `colour_only`
    is set (pyrender always resolves and reads depth too, a quarter of the colour pass here;
    the colour image is read exactly as pyrender reads it: RGB bytes, rows flipped), and
    whose SEG pass draws with `id_programs` (this package's segmentation shaders: each
    vertex's `color_0` times the node's colour, the clip position as pyrender's)."""

    colour_only = False
    id_programs: ShaderProgramCache
    _program_cache: ShaderProgramCache  # pyrender's own

    def _get_primitive_program(self, primitive: object, flags: int, program_flags: int) -> object:
        if not flags & pyrender.RenderFlags.SEG:
            return super()._get_primitive_program(primitive, flags, program_flags)
        own, self._program_cache = self._program_cache, self.id_programs
        try:
            return super()._get_primitive_program(primitive, flags, program_flags)
        finally:
            self._program_cache = own

    def _read_main_framebuffer(self, scene: pyrender.Scene, flags: int) -> tuple:
        if not self.colour_only:
            return super()._read_main_framebuffer(scene, flags)
        from OpenGL import GL

        width, height = self._main_fb_dims
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
        GL.glBlitFramebuffer(
            0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_LINEAR
        )
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
        data = GL.glReadPixels(0, 0, width, height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
        rgb = np.frombuffer(data, dtype=np.uint8).reshape((height, width, 3))
        return np.flip(rgb, axis=0), None


def shared_offscreen_renderer(width: int, height: int) -> pyrender.OffscreenRenderer:
    """One process-wide `OffscreenRenderer` per image size.

    Creating one is slow, and deleting one terminates the EGL display under every other
    one, so they are created once and kept for the life of the process.
    """
    key = (int(width), int(height))
    if key not in _OFFSCREEN:
        renderer = pyrender.OffscreenRenderer(key[0], key[1])
        if type(renderer._renderer) is not pyrender.Renderer:
            raise RuntimeError(
                f"pyrender made a {type(renderer._renderer).__name__}, not its Renderer; "
                "install the pyrender version pyproject.toml names."
            )
        renderer._renderer.__class__ = _ColourPassRenderer  # add colour_only and id_programs
        renderer._renderer.id_programs = ShaderProgramCache(str(SHADER_DIR))
        _OFFSCREEN[key] = renderer
    return _OFFSCREEN[key]


def id_color(object_id: int) -> tuple[int, int, int]:
    """Segmentation colour of an object id (low byte red, high byte green)."""
    return (object_id & 255, (object_id >> 8) & 255, 0)


def ids_from_color(seg: np.ndarray) -> np.ndarray:
    """[H, W] int32 ids from an [H, W, 3] uint8 segmentation image."""
    return seg[..., 0].astype(np.int32) | (seg[..., 1].astype(np.int32) << 8)


# Baked lighting: a key light from above and a fill light from the side, per face.
_KEY = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])
_FILL = np.array([1.0, -0.6, 0.3]) / np.linalg.norm([1.0, -0.6, 0.3])
AMBIENT, KEY, FILL = 0.5, 0.35, 0.25


def face_shade(normals: np.ndarray) -> np.ndarray:
    """[M] brightness factors of faces with unit [M, 3] normals (view independent)."""
    return (
        AMBIENT
        + KEY * np.clip(normals @ _KEY, 0.0, None)
        + FILL * np.clip(normals @ _FILL, 0.0, None)
    )


def _shaded_colours(part: PlacedPart) -> np.ndarray:
    """[M, 4] RGBA of a part's faces: its colour with the lighting baked per face."""
    tri = part.vertices[part.faces]  # [M, 3, 3]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    rgb = np.clip(np.asarray(part.color)[None, :] * face_shade(n)[:, None], 0.0, 1.0)
    return np.concatenate([rgb, np.ones((len(rgb), 1))], axis=1)


def _primitive(parts: list[PlacedPart]) -> pyrender.Primitive:
    """One primitive with per-vertex colours (lighting baked per face) from coloured parts."""
    return _coloured_primitive(parts, [_shaded_colours(part) for part in parts])


def _coloured_primitive(
    parts: list[PlacedPart], face_colours: list[np.ndarray]
) -> pyrender.Primitive:
    """One primitive of the parts' triangles, in order, each vertex coloured with its face's
    RGBA (`face_colours[k]`: [M_k, 4] for part k's M_k faces)."""
    positions = [part.vertices[part.faces].reshape(-1, 3) for part in parts]
    colors = [np.repeat(rgba, 3, axis=0) for rgba in face_colours]
    return pyrender.Primitive(
        positions=np.concatenate(positions).astype(np.float32),
        color_0=np.concatenate(colors).astype(np.float32),
        material=pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0)),
    )


class SceneRenderer:
    """Renders a layout from world_from_camera poses (OpenCV camera, z-up world).

    Args:
        layout: the scene.
        camera: image size, field of view (the camera height is the caller's business).
    """

    def __init__(self, layout: Layout, camera: CameraSpec | None = None) -> None:
        self.camera = camera or CameraSpec()
        self.intrinsics = self.camera.intrinsics
        self.scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 1.0), ambient_light=(1.0,) * 3)
        self.seg_node_map: dict[pyrender.Node, tuple[int, int, int]] = {}
        # One merged mesh per pass, the same triangles in the same order; each pass shows only
        # its own.
        object_parts_all = [object_parts(obj) for obj in layout.objects]
        shell = list(room_walls(layout).values())
        for room in layout.rooms:
            shell.extend(floor_and_ceiling(room))
        merged = [part for parts in object_parts_all for part in parts] + shell
        ids = [obj.id for obj, parts in zip(layout.objects, object_parts_all, strict=True)
               for _ in parts] + [0] * len(shell)  # fmt: skip
        self._color_mesh = pyrender.Mesh([_primitive(merged)])
        self.scene.add(self._color_mesh, name="color")
        id_rgba = [
            np.broadcast_to(np.array([*id_color(i), 255]) / 255.0, (len(part.faces), 4))
            for part, i in zip(merged, ids, strict=True)
        ]  # each part's faces in its object's id colour
        self._id_mesh = pyrender.Mesh([_coloured_primitive(merged, id_rgba)])
        self.seg_node_map[self.scene.add(self._id_mesh, name="ids")] = (255, 255, 255)
        k = self.intrinsics
        # pyrender puts pixel centres at +0.5 where OpenCV intrinsics put them at integers.
        cam = pyrender.IntrinsicsCamera(
            k.fx, k.fy, k.cx + 0.5, k.cy + 0.5, znear=Z_NEAR, zfar=Z_FAR
        )
        self.camera_node = self.scene.add(cam, pose=np.eye(4))
        self._renderer: pyrender.OffscreenRenderer | None = shared_offscreen_renderer(
            self.camera.width, self.camera.height
        )

    def render(self, pose: Pose) -> RenderedView:
        """Render RGB, depth and the instance mask seen from `pose` (world_from_camera)."""
        if self._renderer is None:
            raise InvalidInputError("this SceneRenderer was closed; make a new one to render.")
        if not isinstance(pose, Pose):
            raise InvalidInputError(
                f"pose must be a glmap_tools.geometry.Pose, got {type(pose).__name__}."
            )
        self.scene.set_pose(self.camera_node, to_opengl(pose))
        self._show(color=True)
        passes = self._renderer._renderer
        passes.colour_only = isinstance(passes, _ColourPassRenderer)
        try:
            rgb, _ = self._renderer.render(self.scene, flags=pyrender.RenderFlags.FLAT)
        finally:
            passes.colour_only = False
        self._show(color=False)
        seg, depth = self._renderer.render(
            self.scene, flags=pyrender.RenderFlags.SEG, seg_node_map=self.seg_node_map
        )
        # Free the shared context for other threads at once: an env left open on one thread
        # (a caller that never closes it) must not lock the size out for the simulator thread.
        release_current_context()
        mask = ids_from_color(seg)
        return RenderedView(
            np.ascontiguousarray(rgb), np.ascontiguousarray(depth, dtype=np.float32), mask
        )

    def _show(self, color: bool) -> None:
        """Show the colour mesh, or the id mesh."""
        self._color_mesh.is_visible = color
        self._id_mesh.is_visible = not color

    def close(self) -> None:
        """Stop using the shared OpenGL context (it stays alive for other renderers).

        The context is also released from this thread: an EGL context is current on one
        thread at a time, and another thread (the server's simulator thread, say) may
        render at the same size next.
        """
        self._renderer = None
        release_current_context()

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def release_current_context() -> None:
    """Make no EGL context current on the calling thread (a no-op off EGL)."""

    if os.environ.get("PYOPENGL_PLATFORM") != "egl":
        return
    try:
        from OpenGL import EGL

        display = EGL.eglGetCurrentDisplay()
        if display != EGL.EGL_NO_DISPLAY:
            EGL.eglMakeCurrent(display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
    except Exception:  # best effort: the next render reports any real trouble
        pass
